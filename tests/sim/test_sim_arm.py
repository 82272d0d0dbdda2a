"""The simulated manipulator and pan-tilt (sans-I/O, fake clock), in v2.0 and v1.0: what each
version reports, the wire layouts each speaks, and the JSIDL's rules on who may command."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pytest
from conftest import OCU, OTHER, Wire, spec

from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.tools.sim.arm import ArmSpec
from edge_vis.tools.sim.outputs import Send
from edge_vis.tools.sim.profile import parse_profile

ARM, PAN_TILT, NODE_MANAGER = JausAddress(101, 1, 5), JausAddress(101, 1, 6), \
    JausAddress(101, 1, 1)
M = "urn:jaus:jss:manipulator:"
V1 = ("manipulator-1.0",)


class ArmWire(Wire):
    """The sim's wire in the dialect the vehicle speaks (what a peer of that version sends)."""

    def __init__(self, version: str) -> None:
        super().__init__(spec(manipulator=ArmSpec(version)))
        self.dialects = V1 if version == "1.0" else ()

    def talk(self, name: str, fields: Mapping[str, Any] | None = None, *,
             to: JausAddress = ARM, source: JausAddress = OCU) -> list[tuple[str, Any]]:
        payload = self.catalogue.encode(name, fields or {}, self.dialects)
        msg = self.catalogue.decode(payload, self.dialects)
        out = []
        for action in self.vehicle.receive(source, to, msg, self.now):
            assert isinstance(action, Send)
            wire = self.catalogue.encode(action.name, action.fields, self.dialects)
            back = self.catalogue.decode(wire, self.dialects)
            out.append((back.name, back.fields))
        return out

    def ask(self, name: str, fields: Mapping[str, Any] | None = None, **kw: Any) -> Any:
        ((_name, fields_back),) = self.talk(name, fields, **kw)
        return fields_back

    def control(self, to: JausAddress = ARM, resume: bool = True) -> None:
        assert self.talk("RequestControl", {"authority_code": 100}, to=to) == [
            ("ConfirmControl", {"response_code": 0})]
        if resume:
            self.talk("Resume", to=to)


def services(wire: ArmWire, component: int) -> dict[str, tuple[int, int]]:
    nodes = wire.ask("QueryServices", {"node_list": []}, to=NODE_MANAGER)["node_list"]
    (comp,) = [c for c in nodes[0]["component_list"]
               if c["component_rec"]["component_id"] == component]
    return {s["uri"]: (s["major_version_number"], s["minor_version_number"])
            for s in comp["service_list"]}


def velocity(value: float) -> dict[str, Any]:
    return {"joint_velocity_list": [{"joint_velocity": {"radian_per_second": value}}]}


def test_v2_reports_the_v2_services_and_names_its_joints() -> None:
    wire = ArmWire("2.0")
    wire.advance(1.0)
    arm = services(wire, 5)
    assert arm[M + "ManipulatorSpecificationService"] == (2, 0)
    assert arm[M + "ManipulatorJointMotionProfile"] == (2, 0)
    assert arm["urn:jaus:jss:core:AccessControl"] == (1, 1)
    assert services(wire, 6)[M + "PanTiltSpecificationService"] == (2, 0)
    spec_fields = wire.ask("QueryManipulatorSpecifications", {"presence_vector": 0xFF})
    assert [n["description"] for n in spec_fields["joint_names_list"]] == [
        "turret", "shoulder", "slide"]
    profile = wire.ask("QueryJointMotionProfile")
    assert list(profile) == ["joint_motion_profile_list"]
    assert list(profile["joint_motion_profile_list"][2]) == ["prismatic_joint_motion_profile_rec"]


def test_v1_reports_v1_services_and_answers_in_the_v1_layouts() -> None:
    wire = ArmWire("1.0")
    wire.advance(1.0)
    arm = services(wire, 5)
    assert arm[M + "ManipulatorJointVelocitiesDriver"] == (1, 0)
    assert M + "ManipulatorSpecificationService" not in arm  # v1.0 has no such service
    assert M + "ManipulatorJointVelocityDriver" not in arm
    assert M + "PanTiltMotionProfileService" not in services(wire, 6)
    # ... yet its v1.0 services answer what v2.0 gave services of their own
    spec_fields = wire.ask("QueryManipulatorSpecifications", {"presence_vector": 0xFF})
    assert "joint_names_list" not in spec_fields
    assert len(spec_fields["joint_specification_list"]) == 2
    profile = wire.ask("QueryJointMotionProfile")
    assert list(profile) == ["motion_profile_list"]
    assert list(profile["motion_profile_list"][0]) == ["revolute_motion_profile_rec"]
    assert wire.ask("QueryPanTiltMotionProfile", to=PAN_TILT)["joint1_max_speed"] == \
        pytest.approx(1.5, abs=1e-6)


@pytest.mark.parametrize("version", ["2.0", "1.0"])
def test_joint_commands_need_control_and_ready(version: str) -> None:
    wire = ArmWire(version)
    wire.advance(1.0)
    assert wire.talk("SetJointVelocity", velocity(0.5)) == []
    wire.control(resume=False)  # controlled but STANDBY: still ignored
    wire.talk("SetJointVelocity", velocity(0.5))
    wire.advance(1.0)
    assert wire.vehicle.arm is not None
    assert wire.vehicle.arm.arm.positions[0] == 0.0
    assert wire.vehicle.counters["commands_ignored"] == 2
    wire.talk("Resume")
    wire.talk("SetJointVelocity", velocity(0.5))
    wire.advance(1.0)
    position = wire.ask("QueryJointPositions")["joint_position_list"][0]
    assert position["joint_position"]["radian"] == pytest.approx(0.5, abs=0.06)
    # another client cannot command it
    wire.talk("SetJointVelocity", velocity(-0.5), source=OTHER)
    assert wire.vehicle.counters["commands_ignored"] == 3


def test_losing_control_stops_the_joints() -> None:
    wire = ArmWire("2.0")
    wire.advance(1.0)
    wire.control()
    wire.talk("SetJointVelocity", velocity(0.5))
    wire.advance(0.5)
    wire.talk("ReleaseControl")
    wire.advance(0.1)
    assert wire.vehicle.arm is not None
    stopped = wire.vehicle.arm.arm.positions[0]
    wire.advance(1.0)
    assert wire.vehicle.arm.arm.positions[0] == stopped
    commanded = wire.ask("QueryCommandedJointVelocity")["joint_velocity_list"][0]
    assert commanded["joint_velocity"]["radian_per_second"] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("version", ["2.0", "1.0"])
def test_motion_profile_needs_control_not_ready_and_slows_the_joint(version: str) -> None:
    wire = ArmWire(version)
    wire.advance(1.0)
    v1 = version == "1.0"
    key, rec = (("motion_profile_list", "revolute_motion_profile_rec") if v1 else
                ("joint_motion_profile_list", "revolute_joint_motion_profile_rec"))
    new = {key: [{rec: {"joint_max_speed": 0.1, "joint_max_acceleration_rate": 0.2,
                        "joint_max_deceleration_rate": 0.2}}]}
    wire.talk("SetJointMotionProfile", new)  # not in control: ignored
    assert wire.ask("QueryJointMotionProfile")[key][0][rec]["joint_max_speed"] == \
        pytest.approx(1.0, abs=1e-6)
    wire.control(resume=False)
    wire.talk("SetJointMotionProfile", new)
    assert wire.ask("QueryJointMotionProfile")[key][0][rec]["joint_max_speed"] == \
        pytest.approx(0.1, abs=1e-6)
    wire.talk("Resume")
    wire.talk("SetJointPositions", {"joint_position_list": [
        {"joint_position": {"radian": 1.0}}]})
    wire.advance(1.0)
    position = wire.ask("QueryJointPositions")["joint_position_list"][0]
    assert position["joint_position"]["radian"] == pytest.approx(0.1, abs=0.02)


def test_pan_tilt_tool_offset_and_gripper() -> None:
    wire = ArmWire("2.0")
    wire.advance(1.0)
    wire.control(PAN_TILT)
    wire.talk("SetPanTiltJointPositions", {"joint1_position": 0.3, "joint2_position": -2.0},
              to=PAN_TILT)
    wire.advance(2.0)
    pose = wire.ask("QueryPanTiltJointPositions", to=PAN_TILT)
    assert (pose["joint1_position"], pose["joint2_position"]) == pytest.approx((0.3, -1.0),
                                                                             abs=1e-3)
    before = wire.ask("QueryEndEffectorPose")["tool_point_coordinate_x"]
    wire.control()
    wire.talk("SetToolOffset", {"tool_point_coordinate_x": 0.0, "tool_point_coordinate_y": 0.0,
                                "tool_point_coordinate_z": 0.35})
    assert wire.ask("QueryToolOffset")["tool_point_coordinate_z"] == pytest.approx(0.35,
                                                                                   abs=1e-3)
    assert wire.ask("QueryEndEffectorPose")["tool_point_coordinate_x"] == \
        pytest.approx(before + 0.2, abs=1e-3)
    wire.talk("SetEndEffectorEffort", {"end_effector_effort": 40.0})
    assert wire.ask("QueryEndEffectorEffort")["end_effector_effort"] == pytest.approx(40.0,
                                                                                      abs=0.5)


@pytest.mark.parametrize("version", ["2.0", "1.0"])
def test_pan_tilt_turns_at_a_commanded_velocity(version: str) -> None:
    wire = ArmWire(version)
    wire.advance(1.0)
    assert M + ("PanTiltJointVelocityDriver" if version == "2.0"
                else "PanTiltJointVelocitiesDriver") in services(wire, 6)
    wire.control(PAN_TILT)
    wire.talk("SetPanTiltJointVelocity", {"joint1_velocity": 0.5, "joint2_velocity": -0.25},
              to=PAN_TILT)
    wire.advance(1.0)
    sensed = wire.ask("QueryPanTiltJointVelocity", to=PAN_TILT)
    assert (sensed["joint1_velocity"], sensed["joint2_velocity"]) == pytest.approx(
        (0.5, -0.25), abs=1e-3)
    pose = wire.ask("QueryPanTiltJointPositions", to=PAN_TILT)
    assert (pose["joint1_position"], pose["joint2_position"]) == pytest.approx(
        (0.5, -0.25), abs=0.06)
    wire.talk("Standby", to=PAN_TILT)  # out of READY: it stops
    wire.advance(0.5)
    commanded = wire.ask("QueryCommandedPanTiltJointVelocity", to=PAN_TILT)
    assert commanded["joint1_velocity"] == pytest.approx(0.0, abs=1e-3)


def test_profile_option_is_checked() -> None:
    base = {"name": "a", "subsystem": 3, "link": "udp://127.0.0.9:3794"}
    profile = parse_profile({"vehicles": [{**base, "manipulator": {}}]})
    assert profile.vehicles[0].manipulator == ArmSpec("2.0")
    with pytest.raises(ConfigError) as err:
        parse_profile({"vehicles": [{**base, "kind": "uuv",
                                     "manipulator": {"version": "3.0"}}]})
    assert "manipulator.version" in str(err.value) and "kind = \"ugv\"" in str(err.value)


def test_check_names_each_vehicles_manipulator(capsys: pytest.CaptureFixture[str]) -> None:
    from pathlib import Path

    from edge_vis.cli import main

    shipped = Path(__file__).resolve().parents[2] / "profiles" / "sim" / "arm.toml"
    assert main(["check", str(shipped)]) == 0
    out = capsys.readouterr().out
    assert "eod-v2 (ugv + manipulator v2.0" in out and "eod-v1 (ugv + manipulator v1.0" in out


def test_a_vehicle_with_iop_services_and_a_manipulator_has_all_its_components() -> None:
    from dataclasses import replace

    wire = ArmWire("2.0")
    wire.vehicle = type(wire.vehicle)(replace(wire.vehicle.spec, iop=True), wire.catalogue)
    wire.advance(1.0)
    components = {c.component for c in wire.vehicle.layout}
    assert components == {1, 2, 3, 4, 5, 6}
    assert M + "PrimitiveManipulator" in services(wire, 5)
    assert "urn:jaus:jss:iop:EnhancedAccessControl" in services(wire, 4)
