"""Waypoint plans through the List Manager (or single waypoints), MissionStatus back, and
AccelerationState: the mission part of the mobility translator."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES

from edge_vis.dds.convert import converter_for
from edge_vis.jaus.transport import JTS_MAX_PAYLOAD
from edge_vis.kit.actions import Command, Publish
from translators.mobility import (
    DEFAULT_SPEED,
    ELEMENTS_PER_SET,
    GLOBAL_LIST_DRIVER,
    LOCAL_WAYPOINT_DRIVER,
    MobilityTranslator,
)


def ctx_with(*services: str) -> Any:
    return replace(CTX, vehicle=replace(CTX.vehicle, services=tuple((s, "1.0")
                                                                      for s in services)))


LIST_CTX = ctx_with(GLOBAL_LIST_DRIVER)


def plan(n: int, **extra: Any) -> dict[str, Any]:
    return {"vehicle_id": "veh1", "operator_id": "op1", "plan_id": "p1", "frame": "GLOBAL",
            "speed": 2.0, **extra,
            "waypoints": [{"latitude": 28.5 + i * 1e-4, "longitude": -81.25, "altitude": 3.0,
                           "tolerance": 1.5 if i == 0 else 0.0} for i in range(n)]}


def commands(actions: list[Any]) -> list[Command]:
    return [a for a in actions if isinstance(a, Command)]


def statuses(actions: list[Any]) -> list[dict[str, Any]]:
    return [dict(a.sample) for a in actions if isinstance(a, Publish)
            and a.topic == "MissionStatus"]


def answer(tr: MobilityTranslator, command: Command, name: str = "ConfirmElementRequest",
           **extra: Any) -> list[Any]:
    rid = command.fields["request_id_rec"]["request_id"]
    fields = CAT.decode(CAT.encode(name, {"request_id": rid, **extra})).fields
    return tr.on_message(name, fields, LIST_CTX)


def test_plan_goes_out_as_list_manager_sequence() -> None:
    tr = MobilityTranslator()
    out = tr.on_sample("WaypointPlan", plan(3), LIST_CTX)
    (delete,) = commands(out)
    assert delete.name == "DeleteElement" and delete.service == GLOBAL_LIST_DRIVER
    assert delete.fields["delete_element_list"] == [{"element_uid": 0xFFFF}]
    assert delete.stop is None and delete.kind == "waypoint"
    assert statuses(out)[0]["state"] == "PENDING"
    # nothing more until the vehicle confirms
    (set_element,) = commands(answer(tr, delete))
    assert set_element.name == "SetElement"
    elements = set_element.fields["element_list"]
    assert [(e["element_uid"], e["previous_uid"], e["next_uid"]) for e in elements] == [
        (1, 0, 2), (2, 1, 3), (3, 2, 0)]
    first = CAT.decode(elements[0]["element_data"]["data"])
    assert first.name == "SetGlobalWaypoint" and elements[0]["element_data"]["format"] == 0
    assert first.fields["latitude"] == pytest.approx(28.5, abs=1e-6)
    assert first.fields["waypoint_tolerance"] == pytest.approx(1.5, abs=0.01)
    assert "waypoint_tolerance" not in CAT.decode(elements[1]["element_data"]["data"]).fields
    CAT.encode("SetElement", set_element.fields)
    # a confirm for another request changes nothing
    assert answer(tr, replace(set_element, fields={"request_id_rec": {"request_id": 99}})) \
        == []
    out = answer(tr, set_element)
    (execute,) = commands(out)
    assert execute.name == "ExecuteList" and dict(execute.fields) == {"speed": 2.0,
                                                                       "element_uid": 1}
    # executing from element 1, as commanded: the driver's every-change event need not
    # come (a driver already at element 1 of the list this one replaced sends none)
    assert (statuses(out)[-1]["state"], statuses(out)[-1]["active_waypoint"]) == (
        "EXECUTING", 0)

    def report(name: str, **fields: Any) -> dict[str, Any]:
        decoded = CAT.decode(CAT.encode(name, fields)).fields
        (status,) = statuses(tr.on_message(name, decoded, LIST_CTX))
        converter_for(TYPES["MissionStatus"]).to_struct(status, "MissionStatus")
        return status

    assert report("ReportActiveElement", element_uid=2)["active_waypoint"] == 1
    speed = report("ReportTravelSpeed", speed=1.75)
    assert speed["travel_speed"] == pytest.approx(1.75, abs=0.01) and speed["plan_id"] == "p1"
    done = report("ReportActiveElement", element_uid=0)
    assert (done["state"], done["active_waypoint"]) == ("COMPLETED", -1)


def test_long_plans_are_split_and_linked_across_set_elements() -> None:
    tr = MobilityTranslator()
    (step,) = commands(tr.on_sample("WaypointPlan", plan(120), LIST_CTX))
    sets = []
    while True:
        (step,) = commands(answer(tr, step))
        if step.name != "SetElement":
            break
        sets.append(step)
        assert len(CAT.encode("SetElement", step.fields)) <= JTS_MAX_PAYLOAD
    assert step.name == "ExecuteList"
    assert [len(s.fields["element_list"]) for s in sets] == [ELEMENTS_PER_SET,
                                                             ELEMENTS_PER_SET, 20]
    links = [(e["element_uid"], e["previous_uid"], e["next_uid"])
             for s in sets for e in s.fields["element_list"]]
    assert [uid for uid, _, _ in links] == list(range(1, 121))
    assert links[49] == (50, 49, 0) and links[50] == (51, 50, 52)  # appended at the tail


def test_rejected_elements_fail_the_mission_but_a_refused_delete_does_not() -> None:
    tr = MobilityTranslator()
    (delete,) = commands(tr.on_sample("WaypointPlan", plan(2), LIST_CTX))
    (set_element,) = commands(answer(tr, delete, "RejectElementRequest", response_code=5))
    assert set_element.name == "SetElement"
    out = answer(tr, set_element, "RejectElementRequest", response_code=6)
    assert commands(out) == [] and statuses(out)[-1]["state"] == "FAILED"


def test_speed_zero_uses_the_reported_travel_speed_or_the_default() -> None:
    tr = MobilityTranslator()
    (delete,) = commands(tr.on_sample("WaypointPlan", plan(1, speed=0.0), LIST_CTX))
    (set_element,) = commands(answer(tr, delete))
    (execute,) = commands(answer(tr, set_element))
    assert execute.fields["speed"] == DEFAULT_SPEED
    tr.on_message("ReportTravelSpeed", {"speed": 3.5}, LIST_CTX)
    (delete,) = commands(tr.on_sample("WaypointPlan", plan(1, speed=0.0), LIST_CTX))
    (set_element,) = commands(answer(tr, delete))
    (execute,) = commands(answer(tr, set_element))
    assert execute.fields["speed"] == 3.5


def test_single_waypoint_driver_gets_one_waypoint_at_a_time() -> None:
    ctx = ctx_with(LOCAL_WAYPOINT_DRIVER)
    tr = MobilityTranslator()
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "plan_id": "sq", "frame": "LOCAL",
              "waypoints": [{"x": 10.0, "y": 0.0, "tolerance": 1.0},
                            {"x": 10.0, "y": 200_000.0}]}  # beyond the JSIDL limit
    out = tr.on_sample("WaypointPlan", sample, ctx)
    speed, first = commands(out)
    assert (speed.name, dict(speed.fields), speed.kind) == ("SetTravelSpeed",
                                                            {"speed": DEFAULT_SPEED},
                                                            "waypoint_speed")
    assert (first.name, first.service) == ("SetLocalWaypoint", LOCAL_WAYPOINT_DRIVER)
    assert dict(first.fields) == {"x": 10.0, "y": 0.0, "z": 0.0, "waypoint_tolerance": 1.0}
    assert statuses(out)[-1]["active_waypoint"] == 0

    def pose(x: float, y: float) -> list[Any]:
        return tr.on_message("ReportLocalPose", {"x": x, "y": y}, ctx)

    assert commands(pose(5.0, 0.0)) == []  # 5 m away: not there yet
    out = pose(9.5, 0.5)  # within the 1 m tolerance
    (second,) = commands(out)
    assert second.fields["y"] == 100_000.0  # clamped to the JSIDL limit
    assert statuses(out)[-1]["active_waypoint"] == 1
    out = pose(10.0, 100_000.0 - 1.0)  # default tolerance: 2 m
    assert commands(out) == [] and statuses(out)[-1]["state"] == "COMPLETED"


def test_plan_without_a_driver_or_waypoints_fails_visibly() -> None:
    out = MobilityTranslator().on_sample("WaypointPlan", plan(2), ctx_with())
    assert commands(out) == [] and statuses(out)[-1]["state"] == "FAILED"
    out = MobilityTranslator().on_sample("WaypointPlan", plan(0), LIST_CTX)
    assert commands(out) == [] and statuses(out)[-1]["state"] == "FAILED"


def test_acceleration_state() -> None:
    fields = CAT.decode(CAT.encode("ReportAccelerationState", {
        "acceleration_x": -1310.68, "yaw_acceleration": 2.5})).fields
    (action,) = MobilityTranslator().on_message("ReportAccelerationState", fields, CTX)
    assert action.topic == "AccelerationState"
    sample = action.sample
    assert sample["ax"] == pytest.approx(-1310.68, abs=1e-3)  # the JSIDL lower limit
    assert sample["yaw_acceleration"] == pytest.approx(2.5, abs=1e-3)
    assert math.isnan(sample["ay"])
    converter_for(TYPES["AccelerationState"]).to_struct(sample, "AccelerationState")
