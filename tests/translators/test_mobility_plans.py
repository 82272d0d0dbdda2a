"""The plan a vehicle holds, read back (VehiclePlan), path segment plans and PlanQuery: the
list-reading part of the mobility translator, table-driven per message."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES

from edge_vis.dds.convert import converter_for
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Command, Publish, SendMessage
from translators.mobility import (
    GLOBAL_LIST_DRIVER,
    GLOBAL_SEGMENT_DRIVER,
    LOCAL_SEGMENT_DRIVER,
    PLAN_QUERIES_IN_FLIGHT,
    MobilityTranslator,
)

LISTER = JausAddress(150, 1, 2)


def ctx_for(*services: str, source: JausAddress | None = LISTER) -> Any:
    pairs = tuple((s, "1.0") for s in services)
    vehicle = replace(CTX.vehicle, services=pairs, components={LISTER: pairs})
    return replace(CTX, vehicle=vehicle, source=source)


LIST_CTX = ctx_for(GLOBAL_LIST_DRIVER)


def deliver(tr: MobilityTranslator, name: str, fields: dict[str, Any],
            ctx: Any = LIST_CTX) -> list[Any]:
    """``fields`` encoded to real bytes and decoded, as a vehicle's message arrives."""
    return tr.on_message(name, CAT.decode(CAT.encode(name, fields)).fields, ctx)


def plans(actions: list[Any]) -> list[dict[str, Any]]:
    out = [dict(a.sample) for a in actions if isinstance(a, Publish)
           and a.topic == "VehiclePlan"]
    for sample in out:
        converter_for(TYPES["VehiclePlan"]).to_struct(sample, "VehiclePlan")
    return out


def asked(actions: list[Any], name: str = "QueryElement") -> list[Any]:
    return [a.fields.get("element_uid") for a in actions
            if isinstance(a, SendMessage) and a.name == name]


def element(uid: int, previous: int, following: int, message: str,
            fields: dict[str, Any]) -> dict[str, Any]:
    return {"element_uid": uid, "previous_uid": previous, "next_uid": following,
            "element_data": {"format": 0, "data": CAT.encode(message, fields)}}


#: element message, its fields, the PlanElement members expected
ELEMENTS = [
    ("SetGlobalWaypoint", {"latitude": 28.5, "longitude": -81.25, "altitude": 3.0,
                           "waypoint_tolerance": 1.5},
     {"latitude": 28.5, "longitude": -81.25, "altitude": 3.0, "tolerance": 1.5,
      "x": math.nan, "weighting_factor": math.nan}),
    ("SetGlobalWaypoint", {"latitude": -10.0, "longitude": 120.0},
     {"latitude": -10.0, "longitude": 120.0, "altitude": math.nan, "tolerance": math.nan}),
    ("SetLocalWaypoint", {"x": 12.5, "y": -4.0, "z": 1.0, "waypoint_tolerance": 0.5},
     {"x": 12.5, "y": -4.0, "z": 1.0, "tolerance": 0.5, "latitude": math.nan}),
    ("SetGlobalPathSegment", {"p1_latitude": 28.51, "p1_longitude": -81.26,
                              "p2_latitude": 28.52, "p2_longitude": -81.27,
                              "p2_altitude": 5.0, "weighting_factor": 1.5,
                              "path_tolerance": 3.0},
     {"latitude": 28.52, "longitude": -81.27, "altitude": 5.0, "control_latitude": 28.51,
      "control_longitude": -81.26, "control_altitude": math.nan, "weighting_factor": 1.5,
      "tolerance": 3.0}),
    ("SetLocalPathSegment", {"p1_x": 1.0, "p1_y": 2.0, "p2_x": 3.0, "p2_y": 4.0,
                             "p2_z": -1.0, "weighting_factor": 0.0},
     {"x": 3.0, "y": 4.0, "z": -1.0, "control_x": 1.0, "control_y": 2.0,
      "control_z": math.nan, "weighting_factor": 0.0, "tolerance": math.nan}),
]


def close(actual: dict[str, Any], expected: dict[str, Any]) -> None:
    for member, value in expected.items():
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(actual[member]), member
        else:
            assert actual[member] == pytest.approx(value, abs=1e-2), member


@pytest.mark.parametrize(("message", "fields", "expected"), ELEMENTS,
                         ids=[f"{m}-{i}" for i, (m, _, _) in enumerate(ELEMENTS)])
def test_each_element_kind_is_read_back(message: str, fields: dict[str, Any],
                                        expected: dict[str, Any]) -> None:
    tr = MobilityTranslator()
    out = deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 7}]})
    assert asked(out) == [7]
    (held,) = plans(out)
    assert held["complete"] is False and held["element_count"] == 1
    assert held["component"] == "150.1.2" and held["elements"] == []
    (held,) = plans(deliver(tr, "ReportElement", element(7, 0, 0, message, fields)))
    assert held["complete"] is True
    (got,) = held["elements"]
    assert (got["uid"], got["message"]) == (7, message)
    close(got, expected)


#: driver report, its fields, the ``current`` members expected
TARGETS = [
    ("ReportGlobalWaypoint", {"latitude": 28.5, "longitude": -81.25, "waypoint_tolerance": 2.0},
     {"latitude": 28.5, "longitude": -81.25, "altitude": math.nan, "tolerance": 2.0}),
    ("ReportLocalWaypoint", {"x": 3.0, "y": 4.0}, {"x": 3.0, "y": 4.0, "z": math.nan}),
    ("ReportGlobalPathSegment", {"p1_latitude": 1.0, "p1_longitude": 2.0, "p2_latitude": 3.0,
                                 "p2_longitude": 4.0, "weighting_factor": 2.0},
     {"latitude": 3.0, "longitude": 4.0, "control_latitude": 1.0, "control_longitude": 2.0,
      "weighting_factor": 2.0}),
    ("ReportLocalPathSegment", {"p1_x": 1.0, "p1_y": 2.0, "p2_x": 3.0, "p2_y": 4.0,
                                "weighting_factor": 0.5, "path_tolerance": 1.0},
     {"x": 3.0, "y": 4.0, "control_x": 1.0, "control_y": 2.0, "weighting_factor": 0.5,
      "tolerance": 1.0}),
]


@pytest.mark.parametrize(("report", "fields", "expected"), TARGETS,
                         ids=[t[0] for t in TARGETS])
def test_a_drivers_current_target_is_shown(report: str, fields: dict[str, Any],
                                           expected: dict[str, Any]) -> None:
    tr = MobilityTranslator()
    (held,) = plans(deliver(tr, report, fields))
    assert held["current"]["message"] == report.replace("Report", "Set")
    close(held["current"], expected)
    assert held["elements"] == [] and held["element_count"] == -1


def test_elements_follow_the_list_order_and_changes() -> None:
    tr = MobilityTranslator()
    wp = {"latitude": 1.0, "longitude": 2.0}
    deliver(tr, "ReportElementList", {"element_list": [{"element_uid": u} for u in (3, 1, 2)]})
    for uid in (1, 2, 3):
        out = deliver(tr, "ReportElement", element(uid, 0, 0, "SetGlobalWaypoint", wp))
    assert [e["uid"] for e in plans(out)[0]["elements"]] == [3, 1, 2]
    # an element removed from the list goes; one added is asked for, nothing else
    out = deliver(tr, "ReportElementList", {"element_list": [{"element_uid": u}
                                                             for u in (3, 2, 9)]})
    assert asked(out) == [9]
    (held,) = plans(out)
    assert [e["uid"] for e in held["elements"]] == [3, 2] and not held["complete"]
    # a late answer for the removed element changes nothing
    assert deliver(tr, "ReportElement", element(1, 0, 0, "SetGlobalWaypoint", wp)) == []
    # a count that differs from the list read makes the relay read the list again
    out = deliver(tr, "ReportElementCount", {"element_count": 5})
    assert len([a for a in out if isinstance(a, SendMessage)
                and a.name == "QueryElementList" and a.destination == LISTER]) == 1
    assert plans(out)[0]["element_count"] == 5


def test_a_long_list_is_read_a_few_elements_at_a_time() -> None:
    tr = MobilityTranslator()
    uids = list(range(1, 21))
    out = deliver(tr, "ReportElementList", {"element_list": [{"element_uid": u}
                                                             for u in uids]})
    first = asked(out)
    assert first == uids[:PLAN_QUERIES_IN_FLIGHT]
    assert all(a.traffic_class == "telemetry" and a.destination == LISTER
               for a in out if isinstance(a, SendMessage))
    seen = list(first)
    for uid in uids:
        out = deliver(tr, "ReportElement", element(uid, 0, 0, "SetLocalWaypoint",
                                                   {"x": float(uid), "y": 0.0}))
        seen += asked(out)
    assert seen == uids  # each asked for once, in order
    held = plans(out)[0]
    assert held["complete"]
    assert [e["x"] for e in held["elements"]] == pytest.approx([float(u) for u in uids],
                                                                abs=1e-3)


def test_an_element_that_is_not_a_known_message_is_listed_without_content() -> None:
    tr = MobilityTranslator()
    deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 4}]})
    raw = {"element_uid": 4, "previous_uid": 0, "next_uid": 0,
           "element_data": {"format": 1, "data": b"\x01\x02"}}
    (held,) = plans(deliver(tr, "ReportElement", raw))
    (got,) = held["elements"]
    assert got["message"] == "" and math.isnan(got["latitude"]) and held["complete"]


def test_plan_query_reads_everything_again_through_the_engine() -> None:
    tr = MobilityTranslator()
    wp = {"latitude": 1.0, "longitude": 2.0}
    deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 1}]})
    deliver(tr, "ReportElement", element(1, 0, 0, "SetGlobalWaypoint", wp))
    # the same list again: nothing to ask
    assert asked(deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 1}]})) \
        == []
    out = tr.on_sample("PlanQuery", {"vehicle_id": "veh1", "operator_id": "op1"}, LIST_CTX)
    assert all(isinstance(c, Command) for c in out)
    assert sorted(c.name for c in out) == ["QueryElementCount", "QueryElementList"]
    assert {(c.service, c.component, c.operator_id) for c in out} == {
        (GLOBAL_LIST_DRIVER, LISTER, "op1")}
    # now the same list is read again, element by element
    assert asked(deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 1}]})) \
        == [1]


def segments_plan(frame: str = "GLOBAL") -> dict[str, Any]:
    return {"vehicle_id": "veh1", "operator_id": "op1", "plan_id": "s1", "frame": frame,
            "speed": 1.5, "segments": [
                {"latitude": 28.5, "longitude": -81.25, "control_latitude": 28.49,
                 "control_longitude": -81.24, "weighting_factor": 1.0, "tolerance": 2.0},
                {"x": 10.0, "y": 5.0, "control_x": 5.0, "control_y": 5.0}]}


@pytest.mark.parametrize(("frame", "service", "message", "checks"), [
    ("GLOBAL", GLOBAL_SEGMENT_DRIVER, "SetGlobalPathSegment",
     {"p2_latitude": 28.5, "p2_longitude": -81.25, "p1_latitude": 28.49,
      "p1_longitude": -81.24, "weighting_factor": 1.0, "path_tolerance": 2.0}),
    ("LOCAL", LOCAL_SEGMENT_DRIVER, "SetLocalPathSegment",
     {"p2_x": 0.0, "p1_x": 0.0, "weighting_factor": 1.0, "path_tolerance": 2.0}),
])
def test_path_segments_go_out_through_the_list_manager(
        frame: str, service: str, message: str, checks: dict[str, float]) -> None:
    tr = MobilityTranslator()
    ctx = ctx_for(service)
    out = tr.on_sample("PathSegmentPlan", segments_plan(frame), ctx)
    (delete,) = [a for a in out if isinstance(a, Command)]
    assert delete.name == "DeleteElement" and delete.service == service
    rid = delete.fields["request_id_rec"]["request_id"]
    (set_element,) = [a for a in deliver(tr, "ConfirmElementRequest", {"request_id": rid}, ctx)
                      if isinstance(a, Command)]
    assert set_element.name == "SetElement"
    CAT.encode("SetElement", set_element.fields)
    first, second = (CAT.decode(e["element_data"]["data"])
                     for e in set_element.fields["element_list"])
    assert first.name == second.name == message
    close(first.fields, checks)
    assert "path_tolerance" not in second.fields
    rid = set_element.fields["request_id_rec"]["request_id"]
    out = deliver(tr, "ConfirmElementRequest", {"request_id": rid}, ctx)
    (execute,) = [a for a in out if isinstance(a, Command)]
    assert execute.name == "ExecuteList" and execute.fields["speed"] == pytest.approx(1.5)
    assert execute.service == service
    # the plan now on the vehicle is read back
    assert [a.name for a in out if isinstance(a, SendMessage)] == ["QueryElementList"]
    (status,) = [a.sample for a in out if isinstance(a, Publish) and a.topic == "MissionStatus"]
    assert status["state"] == "EXECUTING" and status["plan_id"] == "s1"


def test_path_segments_to_a_vehicle_without_the_driver_fail() -> None:
    tr = MobilityTranslator()
    out = tr.on_sample("PathSegmentPlan", segments_plan(), LIST_CTX)
    assert not [a for a in out if isinstance(a, Command)]
    (status,) = [a.sample for a in out if isinstance(a, Publish)]
    assert status["state"] == "FAILED"
