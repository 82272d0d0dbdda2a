"""A simulated manipulator arm and pan-tilt, in manipulator v2.0 or v1.0. No I/O.

A vehicle with ``[vehicles.manipulator]`` in its sim profile gets two more components: an
arm (component 5: three joints - a turret and a shoulder that turn, a slide that extends -
with a gripper) and a pan-tilt (component 6). ``version = "1.0"`` makes both offer the
v1.0 services, speak the v1.0 definitions on the wire (dialect ``manipulator-1.0``: plural
names, ``motion_profile_list``, no joint names in the specifications) and answer the
queries v1.0 services answered (specifications from the sensors and drivers, motion
profiles from the drivers, the tool offset from the end-effector pose sensor).

As the JSIDL says: commands of services derived from Management (the joint and pan-tilt
drivers, the primitive services, the gripper) are obeyed only from the controller in READY;
the motion profile and tool offset services derive from AccessControl only, so their Set
messages need control, not READY. A component that leaves READY stops its joints.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from edge_vis.schema import setting
from edge_vis.tools.sim import components as svc
from edge_vis.tools.sim.components import ComponentSpec
from edge_vis.tools.sim.outputs import Action

if TYPE_CHECKING:
    from edge_vis.jaus.address import JausAddress
    from edge_vis.tools.sim.subsystem import Component, SimVehicle

M = "urn:jaus:jss:manipulator:"
V1_DIALECT = "manipulator-1.0"
ARM_COMPONENT, PAN_TILT_COMPONENT = 5, 6
_BASE = (svc.TRANSPORT, svc.EVENTS, svc.ACCESS_CONTROL, svc.MANAGEMENT, svc.LIVENESS)

#: version -> (arm services, pan-tilt services) as the vehicle reports them
SERVICES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "2.0": (tuple(M + s for s in (
        "PrimitiveManipulator", "ManipulatorJointPositionSensor",
        "ManipulatorJointVelocitySensor", "ManipulatorJointPositionDriver",
        "ManipulatorJointVelocityDriver", "ManipulatorSpecificationService",
        "ManipulatorJointMotionProfile", "ManipulatorEndEffectorPoseSensor",
        "ManipulatorToolOffsetService", "PrimitiveEndEffector")),
        tuple(M + s for s in (
            "PrimitivePanTilt", "PanTiltJointPositionSensor", "PanTiltJointPositionDriver",
            "PanTiltJointVelocitySensor", "PanTiltJointVelocityDriver",
            "PanTiltSpecificationService", "PanTiltMotionProfileService"))),
    "1.0": (tuple(M + s for s in (
        "PrimitiveManipulator", "ManipulatorJointPositionSensor",
        "ManipulatorJointVelocitySensor", "ManipulatorJointPositionDriver",
        "ManipulatorJointVelocitiesDriver", "ManipulatorEndEffectorPoseSensor",
        "PrimitiveEndEffector")),
        tuple(M + s for s in (
            "PrimitivePanTilt", "PanTiltJointPositionSensor", "PanTiltJointPositionDriver",
            "PanTiltJointVelocitySensor", "PanTiltJointVelocitiesDriver"))),
}
#: v1.0 answers these v2.0 services' messages from the services above (v1.0 JSIDL)
V1_ANSWERS = (tuple(M + s for s in (
    "ManipulatorJointVelocityDriver", "ManipulatorSpecificationService",
    "ManipulatorJointMotionProfile", "ManipulatorToolOffsetService")),
    tuple(M + s for s in ("PanTiltJointVelocityDriver", "PanTiltSpecificationService",
                          "PanTiltMotionProfileService")))


@dataclass(frozen=True, slots=True)
class ArmSpec:
    """A manipulator and a pan-tilt on the vehicle (``[vehicles.manipulator]``)."""

    version: str = setting("2.0", choices=("2.0", "1.0"))


def layout(spec: ArmSpec) -> tuple[ComponentSpec, ComponentSpec]:
    """The arm's and the pan-tilt's components."""
    arm, pan_tilt = SERVICES[spec.version]
    v1 = spec.version == "1.0"
    version = (1, 0) if v1 else (2, 0)
    return (ComponentSpec(ARM_COMPONENT, "Manipulator", _BASE + arm, version,
                          V1_ANSWERS[0] if v1 else ()),
            ComponentSpec(PAN_TILT_COMPONENT, "PanTilt", _BASE + pan_tilt, version,
                          V1_ANSWERS[1] if v1 else ()))


@dataclass(frozen=True, slots=True)
class Joint:
    name: str
    prismatic: bool
    low: float
    high: float
    max_speed: float


JOINTS = (Joint("turret", False, -math.pi, math.pi, 1.0),
          Joint("shoulder", False, -0.5, 1.5, 0.8),
          Joint("slide", True, 0.0, 0.4, 0.1))
PAN_TILT = (Joint("pan", False, -3.0, 3.0, 1.5), Joint("tilt", False, -1.0, 1.0, 1.0))
#: link length (m) of the shoulder to the slide, height of the turret
LINK, HEIGHT = 0.6, 0.3


@dataclass
class Axes:
    """Joints moved to position targets or at commanded velocities, within their limits."""

    joints: tuple[Joint, ...]
    positions: list[float] = field(default_factory=list)
    targets: list[float] | None = None
    velocities: list[float] | None = None
    efforts: list[float] = field(default_factory=list)
    #: per joint: max speed, acceleration, deceleration
    profile: list[tuple[float, float, float]] = field(default_factory=list)

    def __post_init__(self) -> None:
        """At rest within its limits, each joint's profile its top speed."""
        self.positions = [min(max(0.0, j.low), j.high) for j in self.joints]
        self.efforts = [0.0] * len(self.joints)
        self.profile = [(j.max_speed, 2 * j.max_speed, 2 * j.max_speed) for j in self.joints]

    def step(self, dt: float) -> None:
        for i, joint in enumerate(self.joints):
            speed = min(joint.max_speed, self.profile[i][0])
            if self.velocities is not None:
                move = max(-speed, min(speed, self.velocities[i])) * dt
            elif self.targets is not None:
                move = max(-speed * dt, min(speed * dt, self.targets[i] - self.positions[i]))
            else:
                continue
            self.positions[i] = max(joint.low, min(joint.high, self.positions[i] + move))

    def stop(self) -> None:
        self.targets = self.velocities = None
        self.efforts = [0.0] * len(self.joints)

    def fit(self, values: list[float]) -> list[float]:
        """``values`` for every joint (missing ones: where the joint is), within limits."""
        return [max(j.low, min(j.high, values[i] if i < len(values) else self.positions[i]))
                for i, j in enumerate(self.joints)]


class Arm:
    """The state of the simulated manipulator, gripper and pan-tilt."""

    def __init__(self, spec: ArmSpec) -> None:
        self.v1 = spec.version == "1.0"
        self.arm = Axes(JOINTS)
        self.pan_tilt = Axes(PAN_TILT)
        self.tool_offset = (0.0, 0.0, 0.15)
        self.gripper = 0.0

    @property
    def dialects(self) -> tuple[str, ...]:
        """The message dialects it speaks on the wire."""
        return (V1_DIALECT,) if self.v1 else ()

    def step(self, dt: float, arm_ready: bool, pan_tilt_ready: bool) -> None:
        for axes, ready in ((self.arm, arm_ready), (self.pan_tilt, pan_tilt_ready)):
            if not ready:
                axes.stop()
            axes.step(dt)

    def tool_point(self) -> tuple[float, float, float, float, float]:
        """Tool point (x, y, z in the manipulator frame) and its yaw and pitch."""
        yaw, pitch, slide = self.arm.positions
        reach = LINK + slide + self.tool_offset[2]
        return (reach * math.cos(pitch) * math.cos(yaw), reach * math.cos(pitch) * math.sin(yaw),
                HEIGHT + reach * math.sin(pitch), yaw, pitch)


# -- reports --------------------------------------------------------------------------------


def _arm(vehicle: SimVehicle) -> Arm:
    assert vehicle.arm is not None
    return vehicle.arm


def _position(joint: Joint, value: float) -> dict[str, Any]:
    return {"joint_position": {"meter" if joint.prismatic else "radian": value}}


def _positions(axes: Axes, values: list[float]) -> dict[str, Any]:
    return {"joint_position_list": [_position(j, v) for j, v in zip(axes.joints, values,
                                                                       strict=True)]}


def _velocities(axes: Axes, values: list[float] | None) -> dict[str, Any]:
    values = values or [0.0] * len(axes.joints)
    return {"joint_velocity_list": [
        {"joint_velocity": {"meter_per_second" if j.prismatic else "radian_per_second": v}}
        for j, v in zip(axes.joints, values, strict=True)]}


def _specifications(vehicle: SimVehicle, comp: Component,
                    fields: dict[str, Any]) -> dict[str, Any]:
    arm = _arm(vehicle)
    first, *rest = JOINTS
    body: dict[str, Any] = {
        "manipulator_coordinate_system_rec": {
            "manipulator_coordinate_sys_x": 0.2, "manipulator_coordinate_sys_y": 0.0,
            "manipulator_coordinate_sys_z": 0.4, "d_component_of_unit_quaternion_q": 1.0,
            "a_component_of_unit_quaternion_q": 0.0, "b_component_of_unit_quaternion_q": 0.0,
            "c_component_of_unit_quaternion_q": 0.0},
        "first_joint_parameters": {"revolute_joint1_offset_rec": {
            "joint1_offset": HEIGHT, "joint1_min_value": first.low,
            "joint1_max_value": first.high, "joint1_max_speed": first.max_speed}},
        "joint_specification_list": [
            {"prismatic_joint_specification_rec": {
                "link_length": LINK, "twist_angle": 0.0, "joint_angle": 0.0,
                "min_value": j.low, "max_value": j.high, "max_speed": j.max_speed}}
            if j.prismatic else
            {"revolute_joint_specification_rec": {
                "link_length": 0.0, "twist_angle": math.pi / 2, "joint_offset": 0.0,
                "min_value": j.low, "max_value": j.high, "max_speed": j.max_speed}}
            for j in rest],
    }
    if not arm.v1:  # v2.0 names its joints; v1.0 has no such list
        body["joint_names_list"] = [{"description": j.name} for j in JOINTS]
    return body


def _motion_profile(vehicle: SimVehicle, comp: Component,
                    fields: dict[str, Any]) -> dict[str, Any]:
    arm = _arm(vehicle)
    prefix = "" if arm.v1 else "joint_"
    items = [{(f"prismatic_{prefix}motion_profile_rec" if j.prismatic
               else f"revolute_{prefix}motion_profile_rec"): {
        "joint_max_speed": p[0], "joint_max_acceleration_rate": p[1],
        "joint_max_deceleration_rate": p[2]}} for j, p in zip(JOINTS, arm.arm.profile,
                                                                   strict=True)]
    return {"motion_profile_list" if arm.v1 else "joint_motion_profile_list": items}


def _end_effector_pose(vehicle: SimVehicle, comp: Component,
                       fields: dict[str, Any]) -> dict[str, Any]:
    x, y, z, yaw, pitch = _arm(vehicle).tool_point()
    cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(-pitch / 2), \
        math.sin(-pitch / 2)
    return {"tool_point_coordinate_x": x, "tool_point_coordinate_y": y,
            "tool_point_coordinate_z": z, "d_component_of_unit_quaternion_q": cy * cp,
            "a_component_of_unit_quaternion_q": -sy * sp,
            "b_component_of_unit_quaternion_q": cy * sp,
            "c_component_of_unit_quaternion_q": sy * cp}


def _pan_tilt_specifications(vehicle: SimVehicle, comp: Component,
                             fields: dict[str, Any]) -> dict[str, Any]:
    pan, tilt = PAN_TILT
    return {"pan_tilt_coordinate_sys_x": 0.3, "pan_tilt_coordinate_sys_y": 0.0,
            "pan_tilt_coordinate_sys_z": 0.8, "d_component_of_unit_quaternion_q": 1.0,
            "a_component_of_unit_quaternion_q": 0.0, "b_component_of_unit_quaternion_q": 0.0,
            "c_component_of_unit_quaternion_q": 0.0,
            "joint1_min_value": pan.low, "joint1_max_value": pan.high,
            "joint1_max_speed": pan.max_speed, "joint2_min_value": tilt.low,
            "joint2_max_value": tilt.high, "joint2_max_speed": tilt.max_speed}


def _pan_tilt_profile(vehicle: SimVehicle, comp: Component,
                      fields: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for n, p in enumerate(_arm(vehicle).pan_tilt.profile, 1):
        out |= {f"joint{n}_max_speed": p[0], f"joint{n}_max_acceleration_rate": p[1],
                f"joint{n}_max_deceleration_rate": p[2]}
    return out


def _pair(values: list[float], what: str) -> dict[str, Any]:
    return {f"joint1_{what}": values[0], f"joint2_{what}": values[1]}


Builder = Callable[["SimVehicle", "Component", dict[str, Any]], "dict[str, Any] | None"]

#: query name (base definition's) -> (v2.0 service answering it, report name, builder)
QUERIES: dict[str, tuple[str, str, Builder]] = {
    "QueryManipulatorSpecifications": (M + "ManipulatorSpecificationService",
                                       "ReportManipulatorSpecifications", _specifications),
    "QueryJointPositions": (M + "ManipulatorJointPositionSensor", "ReportJointPositions",
                            lambda v, c, f: _positions(_arm(v).arm, _arm(v).arm.positions)),
    "QueryJointVelocity": (M + "ManipulatorJointVelocitySensor", "ReportJointVelocity",
                           lambda v, c, f: _velocities(_arm(v).arm, _arm(v).arm.velocities)),
    "QueryJointEffort": (M + "PrimitiveManipulator", "ReportJointEffort",
                         lambda v, c, f: {"joint_effort_list": [
                             {"joint_effort": e} for e in _arm(v).arm.efforts]}),
    "QueryCommandedJointPositions": (
        M + "ManipulatorJointPositionDriver", "ReportCommandedJointPositions",
        lambda v, c, f: _positions(_arm(v).arm, _arm(v).arm.targets or _arm(v).arm.positions)),
    "QueryCommandedJointVelocity": (
        M + "ManipulatorJointVelocityDriver", "ReportCommandedJointVelocity",
        lambda v, c, f: _velocities(_arm(v).arm, _arm(v).arm.velocities)),
    "QueryJointMotionProfile": (M + "ManipulatorJointMotionProfile",
                                "ReportJointMotionProfile", _motion_profile),
    "QueryEndEffectorPose": (M + "ManipulatorEndEffectorPoseSensor", "ReportEndEffectorPose",
                             _end_effector_pose),
    "QueryToolOffset": (M + "ManipulatorToolOffsetService", "ReportToolOffset",
                        lambda v, c, f: dict(zip(("tool_point_coordinate_x",
                                                  "tool_point_coordinate_y",
                                                  "tool_point_coordinate_z"),
                                                 _arm(v).tool_offset, strict=True))),
    "QueryEndEffectorSpecification": (M + "PrimitiveEndEffector",
                                      "ReportEndEffectorSpecification",
                                      lambda v, c, f: {"parent_id": ARM_COMPONENT}),
    "QueryEndEffectorEffort": (M + "PrimitiveEndEffector", "ReportEndEffectorEffort",
                               lambda v, c, f: {"end_effector_effort": _arm(v).gripper}),
    "QueryPanTiltSpecifications": (M + "PanTiltSpecificationService",
                                   "ReportPanTiltSpecifications", _pan_tilt_specifications),
    "QueryPanTiltJointPositions": (M + "PanTiltJointPositionSensor",
                                   "ReportPanTiltJointPositions",
                                   lambda v, c, f: _pair(_arm(v).pan_tilt.positions,
                                                         "position")),
    "QueryCommandedPanTiltJointPositions": (
        M + "PanTiltJointPositionDriver", "ReportCommandedPanTiltJointPositions",
        lambda v, c, f: _pair(_arm(v).pan_tilt.targets or _arm(v).pan_tilt.positions,
                              "position")),
    "QueryPanTiltJointVelocity": (M + "PanTiltJointVelocitySensor",
                                  "ReportPanTiltJointVelocity",
                                  lambda v, c, f: _pair(_arm(v).pan_tilt.velocities or [0.0, 0.0],
                                                        "velocity")),
    "QueryCommandedPanTiltJointVelocity": (
        M + "PanTiltJointVelocityDriver", "ReportCommandedPanTiltJointVelocity",
        lambda v, c, f: _pair(_arm(v).pan_tilt.velocities or [0.0, 0.0], "velocity")),
    "QueryPanTiltJointEffort": (M + "PrimitivePanTilt", "ReportPanTiltJointEffort",
                                lambda v, c, f: _pair(_arm(v).pan_tilt.efforts, "effort")),
    "QueryPanTiltMotionProfile": (M + "PanTiltMotionProfileService",
                                  "ReportPanTiltMotionProfile", _pan_tilt_profile),
}

# -- commands -------------------------------------------------------------------------------

Handler = Callable[["SimVehicle", "Component", "JausAddress", dict[str, Any], float],
                   list[Action]]


def _value(item: dict[str, Any], name: str) -> float:
    value = item[name]
    return float(next(iter(value.values())) if isinstance(value, dict) else value)


def _driver(name: str, apply: Callable[[Arm, dict[str, Any]], None]) -> Handler:
    """A command of a Management-derived service: controller and READY only."""
    def handle(vehicle: SimVehicle, comp: Component, source: JausAddress,
               fields: dict[str, Any], now: float) -> list[Action]:
        if vehicle._commanding(comp, source, name):
            apply(_arm(vehicle), fields)
            vehicle.counters["commands_obeyed"] += 1
        return []
    return handle


def _configure(name: str, apply: Callable[[Arm, dict[str, Any]], None]) -> Handler:
    """A Set of an AccessControl-derived service: the controlling client only."""
    def handle(vehicle: SimVehicle, comp: Component, source: JausAddress,
               fields: dict[str, Any], now: float) -> list[Action]:
        if comp.controller != source:
            vehicle.counters["commands_ignored"] += 1
            return []
        apply(_arm(vehicle), fields)
        vehicle.counters["commands_obeyed"] += 1
        return []
    return handle


def _set_positions(arm: Arm, fields: dict[str, Any]) -> None:
    arm.arm.velocities = None
    arm.arm.targets = arm.arm.fit([_value(i, "joint_position")
                                   for i in fields["joint_position_list"]])


def _set_velocities(arm: Arm, fields: dict[str, Any]) -> None:
    arm.arm.targets = None
    values = [_value(i, "joint_velocity") for i in fields["joint_velocity_list"]]
    arm.arm.velocities = [values[i] if i < len(values) else 0.0 for i in range(len(JOINTS))]


def _set_efforts(arm: Arm, fields: dict[str, Any]) -> None:
    values = [float(i["joint_effort"]) for i in fields["joint_effort_list"]]
    arm.arm.efforts = [values[i] if i < len(values) else 0.0 for i in range(len(JOINTS))]


def _set_motion_profile(arm: Arm, fields: dict[str, Any]) -> None:
    items = fields.get("joint_motion_profile_list", fields.get("motion_profile_list")) or []
    for i, item in enumerate(items[:len(JOINTS)]):
        rec = next(iter(item.values()))
        arm.arm.profile[i] = (rec["joint_max_speed"], rec["joint_max_acceleration_rate"],
                              rec["joint_max_deceleration_rate"])


def _set_tool_offset(arm: Arm, fields: dict[str, Any]) -> None:
    arm.tool_offset = (fields["tool_point_coordinate_x"], fields["tool_point_coordinate_y"],
                       fields["tool_point_coordinate_z"])


def _set_pan_tilt_positions(arm: Arm, fields: dict[str, Any]) -> None:
    arm.pan_tilt.velocities = None
    arm.pan_tilt.targets = arm.pan_tilt.fit([fields["joint1_position"],
                                             fields["joint2_position"]])


def _set_pan_tilt_velocities(arm: Arm, fields: dict[str, Any]) -> None:
    arm.pan_tilt.targets = None
    arm.pan_tilt.velocities = [fields["joint1_velocity"], fields["joint2_velocity"]]


def _set_pan_tilt_profile(arm: Arm, fields: dict[str, Any]) -> None:
    arm.pan_tilt.profile = [tuple(fields[f"joint{n}_{m}"] for m in (  # type: ignore[misc]
        "max_speed", "max_acceleration_rate", "max_deceleration_rate")) for n in (1, 2)]


def _set_gripper(arm: Arm, fields: dict[str, Any]) -> None:
    arm.gripper = fields["end_effector_effort"]


def _set_pan_tilt_efforts(arm: Arm, fields: dict[str, Any]) -> None:
    arm.pan_tilt.efforts = [fields["joint1_effort"], fields["joint2_effort"]]


#: command name (base definition's) -> (v2.0 service obeying it, handler)
HANDLERS: dict[str, tuple[str, Handler]] = {
    "SetJointPositions": (M + "ManipulatorJointPositionDriver",
                          _driver("SetJointPositions", _set_positions)),
    "SetJointVelocity": (M + "ManipulatorJointVelocityDriver",
                         _driver("SetJointVelocity", _set_velocities)),
    "SetJointEffort": (M + "PrimitiveManipulator", _driver("SetJointEffort", _set_efforts)),
    "SetEndEffectorEffort": (M + "PrimitiveEndEffector",
                             _driver("SetEndEffectorEffort", _set_gripper)),
    "SetPanTiltJointPositions": (M + "PanTiltJointPositionDriver",
                                 _driver("SetPanTiltJointPositions", _set_pan_tilt_positions)),
    "SetPanTiltJointVelocity": (M + "PanTiltJointVelocityDriver",
                                _driver("SetPanTiltJointVelocity", _set_pan_tilt_velocities)),
    "SetPanTiltJointEffort": (M + "PrimitivePanTilt",
                              _driver("SetPanTiltJointEffort", _set_pan_tilt_efforts)),
    "SetJointMotionProfile": (M + "ManipulatorJointMotionProfile",
                              _configure("SetJointMotionProfile", _set_motion_profile)),
    "SetToolOffset": (M + "ManipulatorToolOffsetService",
                      _configure("SetToolOffset", _set_tool_offset)),
    "SetPanTiltMotionProfile": (M + "PanTiltMotionProfileService",
                                _configure("SetPanTiltMotionProfile", _set_pan_tilt_profile)),
}

