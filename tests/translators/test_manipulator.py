"""The manipulator translator: joint and end-effector reports out, set-points in."""

from __future__ import annotations

import math
from typing import Any

import pytest
from rulekit import CAT, CTX, check_command_rule, check_report_rule, command_sample, encode

from edge_vis.kit import CommandRule
from edge_vis.kit.actions import Command
from translators.manipulator import REVOLUTE_LIMIT, ManipulatorTranslator

TR = ManipulatorTranslator
REPORTS = TR.report_rules
COMMANDS = TR.command_rules


@pytest.mark.parametrize("rule", REPORTS, ids=[r.message for r in REPORTS])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


#: sample values per command message, with the JAUS fields they must give
COMMAND_CASES: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "SetJointPositions": (
        {"values": [1.0, 0.3, 100.0, -math.inf], "units": ["rad", "m"]},
        {"joint_position_list": [{"joint_position": {"radian": 1.0}},
                                 {"joint_position": {"meter": 0.3}},
                                 {"joint_position": {"radian": REVOLUTE_LIMIT}},
                                 {"joint_position": {"radian": -REVOLUTE_LIMIT}}]}),
    "SetJointVelocity": (
        {"values": [-0.5, 0.2], "units": ["", "m/s"]},
        {"joint_velocity_list": [{"joint_velocity": {"radian_per_second": -0.5}},
                                 {"joint_velocity": {"meter_per_second": 0.2}}]}),
    "SetJointEffort": (
        {"values": [50.0, -150.0, math.nan]},
        {"joint_effort_list": [{"joint_effort": 50.0}, {"joint_effort": -100.0},
                               {"joint_effort": 0.0}]}),
    "SetActuatorForceTorques": (
        {"values": [12.5, -600.0], "units": ["N m", "N"]},
        {"actuator_force_torque_list": [{"joint_force_torque": {"newton_meter": 12.5}},
                                        {"joint_force_torque": {"newton": -500.0}}]}),
    "SetPanTiltJointPositions": (
        {"values": [0.5, -0.25]}, {"joint1_position": 0.5, "joint2_position": -0.25}),
    "SetPanTiltJointVelocity": (
        {"values": [0.1, -99.0]}, {"joint1_velocity": 0.1, "joint2_velocity": -10 * math.pi}),
    "SetPanTiltJointEffort": (
        {"values": [10.0, 200.0]}, {"joint1_effort": 10.0, "joint2_effort": 100.0}),
    "SetEndEffectorPose": (
        {"x": 0.5, "y": -40.0, "z": 1.0, "qw": 1.0},
        {"tool_point_coordinate_x": 0.5, "tool_point_coordinate_y": -30.0,
         "tool_point_coordinate_z": 1.0, "d_component_of_unit_quaternion_q": 1.0,
         "a_component_of_unit_quaternion_q": 0.0, "b_component_of_unit_quaternion_q": 0.0,
         "c_component_of_unit_quaternion_q": 0.0}),
    "SetEndEffectorVelocityState": (
        {"vx": 0.25, "wz": -0.5},
        {"linear_velocity_component_x": 0.25, "linear_velocity_component_y": 0.0,
         "linear_velocity_component_z": 0.0, "angular_velocity_component_x": 0.0,
         "angular_velocity_component_y": 0.0, "angular_velocity_component_z": -0.5}),
    "SetEndEffectorEffort": ({"effort": 150.0}, {"end_effector_effort": 100.0}),
    "ExecuteList": ({"values": [3.0]}, {"element_uid": 3}),
    "SetJointMotionProfile": (
        {"values": [1.0, 2.0, 3.0, 9.0, 30.0, 0.5], "units": ["rad", "m"]},
        {"joint_motion_profile_list": [
            {"revolute_joint_motion_profile_rec": {
                "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
                "joint_max_deceleration_rate": 3.0}},
            {"prismatic_joint_motion_profile_rec": {
                "joint_max_speed": 5.0, "joint_max_acceleration_rate": 20.0,
                "joint_max_deceleration_rate": 0.5}}]}),
    "SetPanTiltMotionProfile": (
        {"values": [1.0, 2.0, 3.0, 4.0, 5.0, 99.0]},
        {"joint1_max_speed": 1.0, "joint1_max_acceleration_rate": 2.0,
         "joint1_max_deceleration_rate": 3.0, "joint2_max_speed": 4.0,
         "joint2_max_acceleration_rate": 5.0, "joint2_max_deceleration_rate": 10 * math.pi}),
    "SetToolOffset": ({"x": 0.1, "y": -0.2, "z": 40.0},
                      {"tool_point_coordinate_x": 0.1, "tool_point_coordinate_y": -0.2,
                       "tool_point_coordinate_z": 15.0}),
}


def test_every_command_rule_has_a_case() -> None:
    assert {r.message for r in COMMANDS} == set(COMMAND_CASES)


@pytest.mark.parametrize("rule", COMMANDS, ids=[r.message for r in COMMANDS])
def test_every_declared_command(rule: CommandRule) -> None:
    values, expected = COMMAND_CASES[rule.message]
    command = check_command_rule(TR(), rule, command_sample(rule, **values))
    assert _close(dict(command.fields), expected)
    # and through real bytes the values survive, within the JSIDL resolution
    decoded = CAT.decode(encode(command)).fields
    assert _close(decoded, expected, tol=5e-3)  # 16-bit efforts: 0.003 % steps


def _close(a: Any, b: Any, tol: float = 1e-9) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], tol) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, tol) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(a, b, abs_tol=tol)
    return bool(a == b)


def test_motion_commands_stop_every_joint_they_drive() -> None:
    rule = next(r for r in COMMANDS if r.message == "SetJointVelocity")
    sample = command_sample(rule, values=[0.3, -0.2, 0.1], units=["", "m/s", ""])
    (command,) = TR().on_sample("JointCommand", sample, CTX)
    assert isinstance(command, Command)
    assert command.stop == {"joint_velocity_list": [
        {"joint_velocity": {"radian_per_second": 0.0}},
        {"joint_velocity": {"meter_per_second": 0.0}},
        {"joint_velocity": {"radian_per_second": 0.0}}]}
    positions = next(r for r in COMMANDS if r.message == "SetJointPositions")
    (command,) = TR().on_sample("JointCommand", command_sample(positions, values=[1.0]), CTX)
    assert command.stop is None  # a position is a goal, not a motion to stop


def test_unusable_joint_commands_are_not_sent() -> None:
    tr = TR()
    base = {"vehicle_id": "veh1", "operator_id": "op1"}
    assert tr.on_sample("JointCommand", {**base, "device": "pan_tilt",
                                         "quantity": "position", "values": [0.1]}, CTX) == []
    assert tr.on_sample("JointCommand", {**base, "quantity": "position", "values": []},
                        CTX) == []
    assert tr.on_sample("JointCommand", {**base, "quantity": "torque", "values": [1]},
                        CTX) == []
    assert tr.on_sample("EndEffectorCommand", {**base, "mode": "dance"}, CTX) == []


def test_joint_positions_report_keeps_units_per_joint() -> None:
    payload = CAT.encode("ReportJointPositions", {"joint_position_list": [
        {"joint_position": {"radian": -1.25}}, {"joint_position": {"meter": 0.75}}]})
    message = CAT.decode(payload)
    (action,) = TR().on_message(message.name, message.fields, CTX)
    assert action.topic == "JointState"
    sample = action.sample
    assert (sample["device"], sample["quantity"]) == ("manipulator", "position")
    assert sample["values"] == pytest.approx([-1.25, 0.75], abs=1e-6)
    assert sample["units"] == ["rad", "m"]


def test_pan_tilt_and_end_effector_reports() -> None:
    message = CAT.decode(CAT.encode("ReportPanTiltJointPositions",
                                    {"joint1_position": 1.5, "joint2_position": -0.5}))
    (action,) = TR().on_message(message.name, message.fields, CTX)
    assert action.sample["device"] == "pan_tilt"
    assert action.sample["values"] == pytest.approx([1.5, -0.5], abs=1e-6)
    pose = CAT.decode(CAT.encode("ReportEndEffectorPose", {
        "tool_point_coordinate_x": -30.0, "tool_point_coordinate_y": 30.0,
        "tool_point_coordinate_z": 0.0, "d_component_of_unit_quaternion_q": 1.0,
        "a_component_of_unit_quaternion_q": 0.0, "b_component_of_unit_quaternion_q": 0.0,
        "c_component_of_unit_quaternion_q": -1.0}))
    (action,) = TR().on_message(pose.name, pose.fields, CTX)
    assert action.topic == "EndEffectorPose" and action.sample["kind"] == "actual"
    assert action.sample["x"] == pytest.approx(-30.0, abs=1e-6)
    assert action.sample["qz"] == pytest.approx(-1.0, abs=1e-6)


def test_declarations() -> None:
    tr = TR()
    assert set(tr.subscribes) == {"JointCommand", "EndEffectorCommand", "ManipulatorPlan"}
    assert {"JointState", "JointSpecification", "EndEffectorPose", "EndEffectorVelocity",
            "ManipulatorPlanStatus", "ManipulatorList"} == set(tr.publishes)
    assert all(s.startswith("urn:jaus:jss:manipulator:") for s in tr.controlled_services)
