"""The manipulator's List Manager: ManipulatorPlan loaded into a joint-position or
end-effector-pose list driver and executed, its progress (ManipulatorPlanStatus), what the
driver holds (ManipulatorList), and the routing that lets mobility and the manipulator
both use the List Manager's messages and each its own ReportActiveElement."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES

from edge_vis.dds.convert import converter_for
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import PluginConflictError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit import Binding, Translator
from edge_vis.kit.actions import Command, Publish, SendMessage
from translators.manipulator import (
    JOINT_LIST_DRIVER,
    JOINT_LIST_DRIVER_V1,
    POSE_LIST_DRIVER,
    ManipulatorTranslator,
)
from translators.mobility import GLOBAL_LIST_DRIVER, MobilityTranslator

ARM = JausAddress(150, 1, 4)
BASE = JausAddress(150, 1, 2)


def ctx_for(*services: str, source: JausAddress | None = ARM, base: tuple[str, ...] = (),
            service_set: str = "") -> Any:
    pairs = tuple((s, "2.0") for s in services)
    base_pairs = tuple((s, "1.0") for s in base)
    vehicle = replace(CTX.vehicle, services=pairs + base_pairs,
                      components={ARM: pairs, BASE: base_pairs})
    return replace(CTX, vehicle=vehicle, source=source, service_set=service_set)


JOINT_CTX = ctx_for(JOINT_LIST_DRIVER)


def decoded(name: str, fields: dict[str, Any], service_set: str | None = None) -> Any:
    """``fields`` as they arrive: encoded as the set's message, decoded by code."""
    code = CAT.by_name(name, service_set).code if service_set else name
    return CAT.decode(CAT.encode(code, fields))


def deliver(tr: ManipulatorTranslator, name: str, fields: dict[str, Any],
            ctx: Any = JOINT_CTX) -> list[Any]:
    return tr.on_message(name, decoded(name, fields, "manipulator" if "Active" in name
                                       else None).fields, ctx)


def commands(actions: list[Any]) -> list[Command]:
    return [a for a in actions if isinstance(a, Command)]


def published(actions: list[Any], topic: str) -> list[dict[str, Any]]:
    out = [dict(a.sample) for a in actions if isinstance(a, Publish) and a.topic == topic]
    for sample in out:  # each is a valid sample of the topic's type
        converter_for(TYPES[topic]).to_struct(sample, topic)
    return out


def joints(*values: float, units: tuple[str, ...] = ()) -> dict[str, Any]:
    return {"values": list(values), "units": list(units)}


def plan(targets: list[dict[str, Any]], mode: str = "joint_positions") -> dict[str, Any]:
    return {"vehicle_id": "veh1", "operator_id": "op1", "plan_id": "arm1", "mode": mode,
            "targets": targets}


def confirm(tr: ManipulatorTranslator, command: Command,
            name: str = "ConfirmElementRequest", **extra: Any) -> list[Any]:
    rid = command.fields["request_id_rec"]["request_id"]
    return deliver(tr, name, {"request_id": rid, **extra})


def load_all(tr: ManipulatorTranslator, sample: dict[str, Any],
             ctx: Any = JOINT_CTX) -> list[Command]:
    """Send the plan, confirm every request; every command sent, in order."""
    sent = commands(tr.on_sample("ManipulatorPlan", sample, ctx))
    while sent[-1].name != "ExecuteList":
        sent += commands(confirm(tr, sent[-1]))
    return sent


def leaves(value: Any, path: str) -> list[tuple[str, float]]:
    """(path, number) of every number in nested records and lists."""
    if isinstance(value, dict):
        return [leaf for k, v in value.items() for leaf in leaves(v, f"{path}.{k}")]
    if isinstance(value, list):
        return [leaf for i, v in enumerate(value) for leaf in leaves(v, f"{path}[{i}]")]
    return [(path, float(value))]


def elements_of(command: Command) -> list[tuple[str, dict[str, Any]]]:
    """(message, fields) of each element data a SetElement carries."""
    out = []
    for element in command.fields["element_list"]:
        inner = CAT.decode(element["element_data"]["data"])
        out.append((inner.name, inner.fields))
    return out


#: (mode, target, services the vehicle offers) -> the driver and element expected
LOADS = [
    ("joint_positions", joints(0.5, -1.0), (JOINT_LIST_DRIVER,), JOINT_LIST_DRIVER,
     ("SetJointPositions", {"joint_position_list": [{"joint_position": {"radian": 0.5}},
                                                    {"joint_position": {"radian": -1.0}}]})),
    ("joint_positions", joints(0.25, 0.1, units=("rad", "m")), (JOINT_LIST_DRIVER_V1,),
     JOINT_LIST_DRIVER_V1,
     ("SetJointPositions", {"joint_position_list": [{"joint_position": {"radian": 0.25}},
                                                    {"joint_position": {"meter": 0.1}}]})),
    ("joint_positions", joints(100.0), (JOINT_LIST_DRIVER, JOINT_LIST_DRIVER_V1),
     JOINT_LIST_DRIVER,
     ("SetJointPositions", {"joint_position_list": [
         {"joint_position": {"radian": 8 * math.pi}}]})),
    ("end_effector_pose", {"x": 0.5, "y": -0.25, "z": 1.0, "qw": 1.0}, (POSE_LIST_DRIVER,),
     POSE_LIST_DRIVER,
     ("SetEndEffectorPose", {"tool_point_coordinate_x": 0.5, "tool_point_coordinate_y": -0.25,
                             "tool_point_coordinate_z": 1.0,
                             "d_component_of_unit_quaternion_q": 1.0,
                             "a_component_of_unit_quaternion_q": 0.0})),
    ("END_EFFECTOR_POSE", {"x": 99.0, "qx": -3.0}, (POSE_LIST_DRIVER,), POSE_LIST_DRIVER,
     ("SetEndEffectorPose", {"tool_point_coordinate_x": 30.0,
                             "d_component_of_unit_quaternion_q": 1.0,
                             "a_component_of_unit_quaternion_q": -1.0})),
]


@pytest.mark.parametrize(("mode", "target", "services", "driver", "element"), LOADS,
                         ids=[f"{m}-{i}" for i, (m, *_) in enumerate(LOADS)])
def test_a_plan_is_loaded_into_its_driver_and_executed(
        mode: str, target: dict[str, Any], services: tuple[str, ...], driver: str,
        element: tuple[str, dict[str, Any]]) -> None:
    tr = ManipulatorTranslator()
    ctx = ctx_for(*services)
    first = tr.on_sample("ManipulatorPlan", plan([target, target], mode), ctx)
    (status,) = published(first, "ManipulatorPlanStatus")
    assert (status["state"], status["target_count"], status["active_target"]) == \
        ("PENDING", 2, -1)
    sent = load_all(tr, plan([target, target], mode), ctx)
    assert [c.name for c in sent] == ["DeleteElement", "SetElement", "ExecuteList"]
    assert {c.service for c in sent} == {driver}
    assert sent[0].fields["delete_element_list"] == [{"element_uid": 0xFFFF}]
    links = [(e["element_uid"], e["previous_uid"], e["next_uid"])
             for e in sent[1].fields["element_list"]]
    assert links == [(1, 0, 2), (2, 1, 0)]
    message, fields = elements_of(sent[1])[0]
    assert message == element[0]
    for path, value in element[1].items():
        got, want = dict(leaves(fields[path], path)), dict(leaves(value, path))
        assert got.keys() == want.keys()
        assert [got[k] for k in want] == pytest.approx(list(want.values()), abs=1e-3), path
    execute = sent[-1]
    assert execute.fields == {"element_uid": 1} and execute.service_set == "manipulator"
    # encoded as the manipulator's ExecuteList, not mobility's of the same name
    assert CAT.by_name("ExecuteList", execute.service_set).code == 0x061E


def test_long_plans_go_in_batches_and_executing_is_reported() -> None:
    tr = ManipulatorTranslator()
    sent = commands(tr.on_sample("ManipulatorPlan", plan([joints(0.01 * i)
                                                          for i in range(60)]), JOINT_CTX))
    statuses: list[dict[str, Any]] = []
    out: list[Any] = []
    while sent[-1].name != "ExecuteList":
        out = confirm(tr, sent[-1])
        statuses += published(out, "ManipulatorPlanStatus")
        sent += commands(out)
    assert [len(c.fields["element_list"]) for c in sent if c.name == "SetElement"] == [50, 10]
    assert [s["state"] for s in statuses] == ["EXECUTING"]
    # the driver's list is read back once the plan executes
    assert [(a.destination, a.name) for a in out if isinstance(a, SendMessage)] == \
        [(ARM, "QueryElementList")]
    assert confirm(tr, sent[-2]) == []  # a late duplicate confirm changes nothing


#: the reply to each request, the state and reason reached
REPLIES = [
    ("DeleteElement", "RejectElementRequest", "PENDING", ""),  # an empty list may refuse
    ("SetElement", "RejectElementRequest", "FAILED", "SetElement refused (code 6)"),
    ("SetElement", "ConfirmElementRequest", "EXECUTING", ""),
]


@pytest.mark.parametrize(("step", "reply", "state", "reason"), REPLIES)
def test_replies(step: str, reply: str, state: str, reason: str) -> None:
    tr = ManipulatorTranslator()
    (delete,) = commands(tr.on_sample("ManipulatorPlan", plan([joints(0.1)]), JOINT_CTX))
    current = delete
    if step == "SetElement":
        (current,) = commands(confirm(tr, delete))
    out = confirm(tr, current, reply, **({"response_code": 6} if "Reject" in reply else {}))
    statuses = published(out, "ManipulatorPlanStatus")
    if state == "PENDING":
        assert statuses == [] and [c.name for c in commands(out)] == ["SetElement"]
        return
    assert statuses[-1]["state"] == state and statuses[-1]["reason"] == reason
    if state == "FAILED":
        assert commands(out) == []


#: (why, the plan, the vehicle's services) -> FAILED and its reason
REFUSED = [
    ("mode", plan([joints(0.1)], "wiggle"), (JOINT_LIST_DRIVER,), "mode 'wiggle'"),
    ("empty", plan([]), (JOINT_LIST_DRIVER,), "no targets"),
    ("no driver", plan([joints(0.1)]), (POSE_LIST_DRIVER,), "no joint_positions list"),
    ("no values", plan([joints()]), (JOINT_LIST_DRIVER,), "has no values"),
    ("no pose driver", plan([{"x": 1.0}], "end_effector_pose"), (JOINT_LIST_DRIVER,),
     "no end_effector_pose list"),
]


@pytest.mark.parametrize(("why", "sample", "services", "reason"), REFUSED,
                         ids=[r[0] for r in REFUSED])
def test_plans_that_cannot_run_fail_with_a_reason(why: str, sample: dict[str, Any],
                                                  services: tuple[str, ...],
                                                  reason: str) -> None:
    out = ManipulatorTranslator().on_sample("ManipulatorPlan", sample, ctx_for(*services))
    assert commands(out) == []
    (status,) = published(out, "ManipulatorPlanStatus")
    assert status["state"] == "FAILED" and reason in status["reason"]


#: ReportActiveElement UIDs in turn -> (active target, state) after each
PROGRESS = [
    ([1, 2, 3, 0], [(0, "EXECUTING"), (1, "EXECUTING"), (2, "EXECUTING"), (-1, "COMPLETED")]),
    ([2, 9], [(1, "EXECUTING"), None]),  # a UID beyond the plan is not ours
    # none active before the arm reported a target: sent before ExecuteList arrived
    ([0, 1, 0], [None, (0, "EXECUTING"), (-1, "COMPLETED")]),
]


@pytest.mark.parametrize(("uids", "expected"), PROGRESS)
def test_progress_from_the_manipulators_active_element(
        uids: list[int], expected: list[tuple[int, str] | None]) -> None:
    tr = ManipulatorTranslator()
    load_all(tr, plan([joints(0.1), joints(0.2), joints(0.3)]))
    for uid, want in zip(uids, expected, strict=True):
        statuses = published(deliver(tr, "ReportActiveElement", {"element_uid": uid}),
                             "ManipulatorPlanStatus")
        if want is None:
            assert statuses == []
        else:
            (status,) = statuses
            assert (status["active_target"], status["state"]) == want


def test_the_list_a_driver_holds_is_read_back() -> None:
    tr = ManipulatorTranslator()
    out = deliver(tr, "ReportElementList", {"element_list": [{"element_uid": 3},
                                                             {"element_uid": 4}]})
    assert [a.fields["element_uid"] for a in out
            if isinstance(a, SendMessage) and a.name == "QueryElement"] == [3, 4]
    (held,) = published(out, "ManipulatorList")
    assert (held["component"], held["element_count"], held["complete"]) == ("150.1.4", 2,
                                                                            False)
    deliver(tr, "ReportElement", {
        "element_uid": 3, "previous_uid": 0, "next_uid": 4, "element_data": {
            "format": 0, "data": CAT.encode("SetJointPositions", {"joint_position_list": [
                {"joint_position": {"radian": 0.5}}, {"joint_position": {"meter": 0.2}}]})}})
    (held,) = published(deliver(tr, "ReportElement", {
        "element_uid": 4, "previous_uid": 3, "next_uid": 0, "element_data": {
            "format": 0, "data": CAT.encode("SetEndEffectorPose", {
                "tool_point_coordinate_x": 1.0, "tool_point_coordinate_y": 2.0,
                "tool_point_coordinate_z": 3.0, "d_component_of_unit_quaternion_q": 1.0,
                "a_component_of_unit_quaternion_q": 0.0,
                "b_component_of_unit_quaternion_q": 0.0,
                "c_component_of_unit_quaternion_q": 0.0})}}), "ManipulatorList")
    assert held["complete"] is True
    first, second = held["elements"]
    assert (first["uid"], first["next_uid"], first["message"]) == (3, 4, "SetJointPositions")
    assert first["target"]["values"] == pytest.approx([0.5, 0.2], abs=1e-3)
    assert first["target"]["units"] == ["rad", "m"] and math.isnan(first["target"]["x"])
    assert second["message"] == "SetEndEffectorPose" and second["target"]["values"] == []
    assert [second["target"][k] for k in ("x", "y", "z", "qw")] == \
        pytest.approx([1.0, 2.0, 3.0, 1.0], abs=1e-3)


# -- one name, two sets: each ReportActiveElement reaches its own translator ---------------


def test_each_report_active_element_reaches_the_translator_of_its_set() -> None:
    manager = TranslationManager([MobilityTranslator(), ManipulatorTranslator()])
    mobility_ctx = ctx_for(JOINT_LIST_DRIVER, base=(GLOBAL_LIST_DRIVER,), source=BASE)
    arm_ctx = JOINT_CTX
    # both have a plan running
    manager.on_sample("WaypointPlan", {
        "vehicle_id": "veh1", "operator_id": "op1", "plan_id": "p1", "speed": 1.0,
        "waypoints": [{"latitude": 28.5, "longitude": -81.25}] * 3}, mobility_ctx)
    arm = manager.on_sample("ManipulatorPlan", plan([joints(0.1)] * 3), arm_ctx)
    # the List Manager's confirmations go to the translator whose driver sent them
    sent = commands(arm)
    while sent[-1].name != "ExecuteList":
        rid = sent[-1].fields["request_id_rec"]["request_id"]
        reply = manager.on_message("ConfirmElementRequest", {"request_id": rid}, arm_ctx)
        assert {a.topic for a in reply if isinstance(a, Publish)} <= {"ManipulatorPlanStatus"}
        sent += commands(reply)
    for service_set, ctx, topic, member in (
            ("manipulator", arm_ctx, "ManipulatorPlanStatus", "active_target"),
            ("mobility", mobility_ctx, "MissionStatus", "active_waypoint")):
        message = decoded("ReportActiveElement", {"element_uid": 2}, service_set)
        assert message.definition.service_set == service_set  # 0x461E / 0x441E
        out = manager.on_message(message.name, message.fields,
                                 replace(ctx, service_set=message.definition.service_set))
        assert [a.topic for a in out if isinstance(a, Publish)] == [topic]
        assert out[0].sample[member] == 1


class _Lists(Translator):
    name = "lists"
    messages = ("ConfirmElementRequest",)


#: the other translator's binding of ConfirmElementRequest -> may both load?
CLAIMS = [
    (Binding(services=(GLOBAL_LIST_DRIVER,)), False),
    (Binding(), False),
    (Binding(services=("urn:example:OtherListDriver",)), True),
    (Binding(service_set="core", services=(JOINT_LIST_DRIVER,)), False),
]


@pytest.mark.parametrize(("binding", "allowed"), CLAIMS)
def test_overlapping_claims_are_refused_at_start(binding: Binding, allowed: bool) -> None:
    other = type("Other", (_Lists,), {"bindings": {"ConfirmElementRequest": binding}})()
    if allowed:
        TranslationManager([MobilityTranslator(), ManipulatorTranslator(), other])
    else:
        with pytest.raises(PluginConflictError, match="ConfirmElementRequest"):
            TranslationManager([MobilityTranslator(), ManipulatorTranslator(), other])
