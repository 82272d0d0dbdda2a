"""The ``manipulator`` translator (AS6057): joints, end effector and pan-tilt. No I/O.

JAUS -> DDS:

* Report{,Commanded}JointPositions / JointVelocity, ReportJointEffort,
  ReportJointForceTorques -> ``JointState`` (device ``manipulator``; ``quantity`` says
  which, ``units`` per joint because a joint is revolute (rad) or prismatic (m));
* ReportPanTilt{,Commanded}Joint{Positions,Velocity}, ReportPanTiltJointEffort ->
  ``JointState`` (device ``pan_tilt``);
* ReportManipulatorSpecifications, ReportPanTiltSpecifications,
  ReportEndEffectorSpecification -> ``JointSpecification`` (joint names, types, limits:
  what an operator labels the joints of ``JointState`` with);
* ReportJointMotionProfile, ReportPanTiltMotionProfile -> ``JointState`` (quantity
  ``max_speed``, ``max_acceleration``, ``max_deceleration``);
* Report{,Commanded}EndEffectorPose, ReportToolOffset -> ``EndEffectorPose``;
  Report{,Commanded}EndEffectorVelocityState -> ``EndEffectorVelocity``;
  ReportEndEffectorEffort -> ``JointState`` (device ``end_effector``).

DDS -> JAUS (behind control, throttled by the engine):

* ``JointCommand`` -> SetJointPositions / SetJointVelocity / SetJointEffort /
  SetActuatorForceTorques, or the
  SetPanTilt* equivalents for device ``pan_tilt`` (values clamped to the JSIDL limits);
  velocity and effort are motion commands (dead-man stop = zero);
* ``EndEffectorCommand`` -> SetEndEffectorPose / SetEndEffectorVelocityState /
  SetEndEffectorEffort by ``mode``;
* ``JointCommand`` with quantity ``motion_profile`` -> SetJointMotionProfile /
  SetPanTiltMotionProfile (``values``: speed, acceleration, deceleration per joint);
  ``EndEffectorCommand`` mode ``tool_offset`` -> SetToolOffset;
* ``JointCommand`` with quantity ``execute_list`` -> ExecuteList (the manipulator's, code
  0x061E, not mobility's of the same name) to the joint-positions list driver, starting
  at element ``values[0]``;
* ``ManipulatorPlan`` -> the List Manager sequence (DeleteElement, SetElement with
  SetJointPositions or SetEndEffectorPose elements, ExecuteList) to the joint-position or
  end-effector-pose list driver (see :class:`ManipulatorLists`); its progress
  (ConfirmElementRequest, RejectElementRequest, the manipulator's ReportActiveElement) ->
  ``ManipulatorPlanStatus``, and what each list driver holds (ReportElementList,
  ReportElement, ReportElementCount) -> ``ManipulatorList``.

Manipulator v1.0 and v2.0 both: the engine matches v1.0 services to the v2.0 ones that
took over their messages and decodes a v1.0 vehicle's messages with the v1.0 definitions
(dialect ``manipulator-1.0``), under the v2.0 names; the v1.0 motion profile's field names
are read and written here. A vehicle reporting both 1.x and 2.x manipulator services reads
each message as the service carrying it defines it: a 2.0 ManipulatorJointMotionProfile or
ManipulatorSpecificationService speaks 2.0 beside 1.0 drivers. The IOP copy of the v1.0
set reads ReportManipulatorSpecifications as v1.0 does (the same bytes; it labels a
prismatic joint's maximum force newton metre where v1.0 and v2.0 say newton).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from edge_vis.kit import (
    ELEMENTS_PER_SET,
    LIST_REPLIES,
    LIST_REPORTS,
    Action,
    Build,
    Command,
    Computed,
    Const,
    Each,
    From,
    HeldList,
    JausAddress,
    ListDriver,
    ListLoader,
    ListReadBack,
    Publish,
    Put,
    PutEach,
    ReportRule,
    RuleTranslator,
    TranslatorContext,
    list_bindings,
)
from edge_vis.kit import CommandRule as Cmd

MANIP = "urn:jaus:jss:manipulator:"
REVOLUTE_LIMIT = 8 * math.pi        # joint position, rad (JSIDL: +-25.13)
PRISMATIC_LIMIT = 10.0              # joint position, m
REVOLUTE_RATE = 10 * math.pi        # joint velocity, rad/s
PRISMATIC_RATE = 5.0                # joint velocity, m/s (JSIDL: +-5 m/s)


def _units(list_name: str, variant: str, names: Mapping[str, str]) -> Each:
    return Each(list_name, From(variant, convert=lambda v: names.get(next(iter(v)), "")
                                if isinstance(v, Mapping) and v else "", default=""),
                note=", ".join(f"{k}={u}" for k, u in names.items()))


_POS_UNITS = {"radian": "rad", "meter": "m"}
_VEL_UNITS = {"radian_per_second": "rad/s", "meter_per_second": "m/s"}
_FT_UNITS = {"newton_meter": "N m", "newton": "N"}


def _joints(message: str, quantity: str, list_name: str, variant: str | None,
            units: Mapping[str, str] | str, query: str, service: str,
            rate: float = 5.0) -> ReportRule:
    if variant is None:
        values = Each(list_name, From(f"{_single(list_name)}"))
        unit_spec: Any = Each(list_name, Const(units)) if isinstance(units, str) else None
    else:
        values = Each(list_name, From(f"{variant}.*"))
        unit_spec = _units(list_name, variant, units)  # type: ignore[arg-type]
    return ReportRule(message, "JointState",
                      {"device": Const("manipulator"), "quantity": Const(quantity),
                       "values": values, "units": unit_spec},
                      query=query, service=service, rate=rate)


def _single(list_name: str) -> str:
    return {"joint_effort_list": "joint_effort"}[list_name]


def _pan_tilt(message: str, quantity: str, prefix: str, unit: str, query: str,
              service: str, device: str = "pan_tilt") -> ReportRule:
    return ReportRule(message, "JointState",
                      {"device": Const(device), "quantity": Const(quantity),
                       "values": _pair(f"joint1_{prefix}", f"joint2_{prefix}"),
                       "units": Const([unit, unit])},
                      query=query, service=service, rate=5.0)


def _pair(a: str, b: str) -> Any:
    return Computed(lambda f: [float(f.get(a, math.nan)), float(f.get(b, math.nan))],
                    f"[{a}, {b}]")


_POSE = {"x": From("tool_point_coordinate_x", note="m"),
         "y": From("tool_point_coordinate_y", note="m"),
         "z": From("tool_point_coordinate_z", note="m"),
         "qw": From("d_component_of_unit_quaternion_q"),
         "qx": From("a_component_of_unit_quaternion_q"),
         "qy": From("b_component_of_unit_quaternion_q"),
         "qz": From("c_component_of_unit_quaternion_q")}
_TWIST = {"vx": From("linear_velocity_component_x", note="m/s"),
          "vy": From("linear_velocity_component_y", note="m/s"),
          "vz": From("linear_velocity_component_z", note="m/s"),
          "wx": From("angular_velocity_component_x", note="rad/s"),
          "wy": From("angular_velocity_component_y", note="rad/s"),
          "wz": From("angular_velocity_component_z", note="rad/s")}


def _position(value: Any, index: int, sample: Mapping[str, Any]) -> dict[str, Any]:
    units = sample.get("units") or ()
    if index < len(units) and str(units[index]).strip().lower() in ("m", "meter", "metre"):
        return {"joint_position": {"meter": _lim(value, PRISMATIC_LIMIT)}}
    return {"joint_position": {"radian": _lim(value, REVOLUTE_LIMIT)}}


def _velocity(value: Any, index: int, sample: Mapping[str, Any]) -> dict[str, Any]:
    units = sample.get("units") or ()
    if index < len(units) and str(units[index]).strip().lower() in ("m/s", "meter_per_second"):
        return {"joint_velocity": {"meter_per_second": _lim(value, PRISMATIC_RATE)}}
    return {"joint_velocity": {"radian_per_second": _lim(value, REVOLUTE_RATE)}}


def _force(value: Any, index: int, sample: Mapping[str, Any]) -> dict[str, Any]:
    units = sample.get("units") or ()
    if index < len(units) and str(units[index]).strip().lower() in ("n", "newton"):
        return {"joint_force_torque": {"newton": _lim(value, 500.0)}}
    return {"joint_force_torque": {"newton_meter": _lim(value, 1000.0)}}


def _effort(value: Any, index: int, sample: Mapping[str, Any]) -> dict[str, Any]:
    return {"joint_effort": _lim(value, 100.0)}


def _lim(value: Any, limit: float) -> float:
    number = float(value) if value is not None else 0.0
    if math.isnan(number):
        return 0.0
    return max(-limit, min(limit, number))


def _zeros(list_name: str, element: str, alternative: str | None) -> Any:
    """Dead-man stop of a joint list command: the same joints, all at zero."""

    def stop(fields: Mapping[str, Any]) -> dict[str, Any]:
        out = []
        for item in fields.get(list_name, ()):
            value = item[element]
            if alternative is not None and isinstance(value, Mapping):
                out.append({element: dict.fromkeys(value, 0.0)})
            else:
                out.append({element: 0.0})
        return {list_name: out}

    return stop


def _pair_one(name: str) -> Any:
    return Computed(lambda f: [float(f.get(name, math.nan))], f"[{name}]")


def _element_uid(sample: Mapping[str, Any]) -> int:
    """ExecuteList's first element: ``values[0]``, a list element UID (1..65535)."""
    value = float((sample.get("values") or [math.nan])[0])
    if math.isnan(value) or not 1 <= value <= 0xFFFF or value != int(value):
        raise ValueError(f"ExecuteList: element UID {value!r} is not 1..65535")
    return int(value)


V1 = "manipulator-1.0"
SET_MOTION_PROFILE = 0x0607
#: v2.0 field name -> the v1.0 one, where v1.0 named the same field otherwise
_V1_NAMES = {"joint_motion_profile_list": "motion_profile_list",
             "revolute_joint_motion_profile_rec": "revolute_motion_profile_rec",
             "prismatic_joint_motion_profile_rec": "prismatic_motion_profile_rec"}
_V2_NAMES = {v1: v2 for v2, v1 in _V1_NAMES.items()}


def _renamed(value: Any, names: Mapping[str, str]) -> Any:
    """``value`` with its field names renamed by ``names``, at every depth."""
    if isinstance(value, Mapping):
        return {names.get(k, k): _renamed(v, names) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_renamed(v, names) for v in value]
    return value


def _profiles(fields: Mapping[str, Any]) -> list[tuple[str, Mapping[str, Any]]]:
    """(alternative, record) per joint of a joint motion profile, v1.0 or v2.0 names."""
    items = fields.get("joint_motion_profile_list", fields.get("motion_profile_list")) or ()
    out = []
    for item in items:
        if isinstance(item, Mapping) and item:
            name, rec = next(iter(item.items()))
            out.append((_V2_NAMES.get(name, name), rec))
    return out


def _profile_values(member: str) -> Computed:
    return Computed(lambda f: [float(rec.get(member, math.nan)) for _a, rec in _profiles(f)],
                    f"joint_motion_profile_list[] (v1.0: motion_profile_list[]).*.{member}")


def _profile_units(suffix: str) -> Computed:
    return Computed(lambda f: [("m" if alt.startswith("prismatic") else "rad") + suffix
                               for alt, _rec in _profiles(f)],
                    "rad or m by the joint type")


def _pan_tilt_profile(member: str) -> Computed:
    return _pair(f"joint1_{member}", f"joint2_{member}")


def _joint_specs(fields: Mapping[str, Any]) -> dict[str, list[Any]]:
    """Names, types and limits per joint of a ReportManipulatorSpecifications: joint 1 from
    ``first_joint_parameters``, the others from ``joint_specification_list``, names from
    ``joint_names_list`` (v2.0; v1.0 has none)."""
    joints: list[tuple[str, Mapping[str, Any], str, str, str]] = []
    first = fields.get("first_joint_parameters") or {}
    for alt, rec in first.items():
        kind = "prismatic" if alt.startswith("prismatic") else "revolute"
        joints.append((kind, rec, "joint1_min_value", "joint1_max_value", "joint1_max_speed"))
    for item in fields.get("joint_specification_list") or ():
        for alt, rec in item.items():
            kind = "prismatic" if alt.startswith("prismatic") else "revolute"
            joints.append((kind, rec, "min_value", "max_value", "max_speed"))
    names = [str(n.get("description", "")) if isinstance(n, Mapping) else str(n)
             for n in fields.get("joint_names_list") or ()]
    return {
        "names": [names[i] if i < len(names) else "" for i in range(len(joints))],
        "types": [kind for kind, *_rest in joints],
        "min_values": [float(rec.get(lo, math.nan)) for _k, rec, lo, _h, _s in joints],
        "max_values": [float(rec.get(hi, math.nan)) for _k, rec, _l, hi, _s in joints],
        "max_speeds": [float(rec.get(sp, math.nan)) for _k, rec, _l, _h, sp in joints],
        "units": ["m" if kind == "prismatic" else "rad" for kind, *_rest in joints],
    }


def _spec(member: str) -> Computed:
    return Computed(lambda f: _joint_specs(f)[member],
                    "first_joint_parameters, joint_specification_list[]"
                    + (", joint_names_list[].description" if member == "names" else ""))


def _profile_list(sample: Mapping[str, Any]) -> list[dict[str, Any]]:
    """SetJointMotionProfile's list from ``values`` (speed, acceleration, deceleration per
    joint; ``units[i]`` m or m/s makes joint i prismatic)."""
    values = [float(v) for v in sample.get("values") or ()]
    units = list(sample.get("units") or ())
    if not values or len(values) % 3 or any(math.isnan(v) or v < 0 for v in values):
        raise ValueError(f"motion profile: {len(values)} values; 3 per joint, none negative")
    out = []
    for i in range(0, len(values), 3):
        prismatic = i // 3 < len(units) and str(units[i // 3]).strip().lower().startswith("m")
        speed, acc = (5.0, 20.0) if prismatic else (10 * math.pi, 10 * math.pi)
        alt = "prismatic_joint_motion_profile_rec" if prismatic \
            else "revolute_joint_motion_profile_rec"
        out.append({alt: {"joint_max_speed": min(values[i], speed),
                          "joint_max_acceleration_rate": min(values[i + 1], acc),
                          "joint_max_deceleration_rate": min(values[i + 2], acc)}})
    return out


def _pan_tilt_profile_value(index: int, limit: float) -> Build:
    def get(sample: Mapping[str, Any]) -> float:
        values = list(sample.get("values") or ())
        if len(values) != 6:
            raise ValueError(f"pan-tilt motion profile: {len(values)} values, 6 expected")
        return max(0.0, min(float(values[index]), limit))

    return Build(f"values[{index}]", get, f"clamped to [0, {limit:g}]")


_PT_PROFILE = ("joint1_max_speed", "joint1_max_acceleration_rate",
               "joint1_max_deceleration_rate", "joint2_max_speed",
               "joint2_max_acceleration_rate", "joint2_max_deceleration_rate")


# -- the manipulator's List Manager (ManipulatorPlan -> list driver -> status, read-back) ---

JOINT_LIST_DRIVER = MANIP + "ManipulatorJointPositionListDriver"
#: the v1.0 name of the joint-position list driver
JOINT_LIST_DRIVER_V1 = MANIP + "ManipulatorJointPositionsListDriver"
POSE_LIST_DRIVER = MANIP + "ManipulatorEndEffectorPoseListDriver"
#: the list drivers a plan is loaded into (the kit's list mechanism; ExecuteList and
#: ReportActiveElement of the manipulator set, 0x061E / 0x461E)
LIST_DRIVERS = (
    ListDriver(JOINT_LIST_DRIVER, "manipulator", ("SetJointPositions",), "manipulator_list"),
    ListDriver(JOINT_LIST_DRIVER_V1, "manipulator", ("SetJointPositions",), "manipulator_list"),
    ListDriver(POSE_LIST_DRIVER, "manipulator", ("SetEndEffectorPose",), "manipulator_list"),
)
#: ManipulatorPlan mode -> the drivers that take it, preferred first
PLAN_MODES = {"joint_positions": LIST_DRIVERS[:2], "end_effector_pose": LIST_DRIVERS[2:]}
LIST_MESSAGES = (*LIST_REPLIES, *LIST_REPORTS, "ReportActiveElement")
_POSE_FIELDS = (("x", "tool_point_coordinate_x", 30.0), ("y", "tool_point_coordinate_y", 30.0),
                ("z", "tool_point_coordinate_z", 30.0),
                ("qw", "d_component_of_unit_quaternion_q", 1.0),
                ("qx", "a_component_of_unit_quaternion_q", 1.0),
                ("qy", "b_component_of_unit_quaternion_q", 1.0),
                ("qz", "c_component_of_unit_quaternion_q", 1.0))


def target_fields(mode: str, target: Mapping[str, Any]) -> dict[str, Any]:
    """The element message's fields of one ``ManipulatorTarget``: SetJointPositions (rad,
    or m where ``units[i]`` is "m", clamped) or SetEndEffectorPose (m, quaternion)."""
    if mode == "joint_positions":
        values = list(target.get("values") or ())
        if not values:
            raise ValueError("a joint_positions target has no values")
        return {"joint_position_list": [_position(v, i, target) for i, v in enumerate(values)]}
    return {jaus: _lim(target.get(dds, 1.0 if dds == "qw" else 0.0), limit)
            for dds, jaus, limit in _POSE_FIELDS}


def _held_target(message: str, fields: Mapping[str, Any], uid: int, previous: int,
                 following: int) -> dict[str, Any]:
    """A ``ManipulatorListElement`` of a list element read back (NaN where unset)."""
    target: dict[str, Any] = {"values": [], "units": [],
                              **{dds: math.nan for dds, _, _ in _POSE_FIELDS}}
    if message == "SetJointPositions":
        for joint in fields.get("joint_position_list") or ():
            (unit, value), = dict(joint.get("joint_position") or {"radian": math.nan}).items()
            target["values"].append(float(value))
            target["units"].append(_POS_UNITS.get(unit, unit))
    elif message == "SetEndEffectorPose":
        target.update({dds: float(fields.get(jaus, math.nan)) for dds, jaus, _ in _POSE_FIELDS})
    return {"uid": uid, "previous_uid": previous, "next_uid": following, "message": message,
            "target": target}


def _held_list(vehicle_id: str, component: JausAddress, held: HeldList,
               ctx: TranslatorContext) -> Publish:
    return Publish("ManipulatorList", {
        "vehicle_id": vehicle_id, "component": str(component), "element_count": held.count,
        "elements": held.listed(), "complete": held.complete(),
        "timestamp_ms": ctx.timestamp_ms})


@dataclass
class _ArmPlan:
    plan_id: str
    mode: str
    count: int
    active: int = -1
    state: str = "PENDING"
    reason: str = ""


class ManipulatorLists:
    """``ManipulatorPlan`` -> the manipulator's List Manager -> ``ManipulatorPlanStatus``;
    what each list driver holds -> ``ManipulatorList``.

    A plan is loaded by the kit's list mechanism (DeleteElement, SetElement batches of
    SetJointPositions or SetEndEffectorPose elements, each after the previous was
    confirmed, then the manipulator's ExecuteList from the first element); its progress
    is the driver's ReportActiveElement (0x461E): target ``uid - 1`` while executing,
    COMPLETED when it reports 0 after it reported one of the plan's targets (a 0 reported
    before then was sent before ExecuteList arrived). The lists are read back as mobility's
    plans are (ReportElementList events, QueryElement), and again after a plan executes.
    """

    def __init__(self) -> None:
        self.loader = ListLoader()
        self.plans: dict[str, _ArmPlan] = {}
        self.held = ListReadBack(LIST_DRIVERS, _held_target, _held_list)

    def on_plan(self, sample: Mapping[str, Any], ctx: TranslatorContext) -> list[Action]:
        vehicle = ctx.vehicle
        if vehicle is None:
            return []
        vid = vehicle.vehicle_id
        mode = str(sample.get("mode") or "joint_positions").strip().lower()
        targets = [dict(t) for t in sample.get("targets") or ()]
        plan = self.plans[vid] = _ArmPlan(str(sample.get("plan_id", "")), mode, len(targets))
        self.loader.loads.pop(vid, None)  # a new plan replaces any load
        offered = {uri for uri, _ in vehicle.services}
        drivers = [d for d in PLAN_MODES.get(mode, ()) if d.service in offered]
        try:
            if mode not in PLAN_MODES:
                raise ValueError(f"mode {mode!r} is not one of {', '.join(PLAN_MODES)}")
            if not targets:
                raise ValueError("the plan has no targets")
            if not drivers:
                raise ValueError(f"the vehicle offers no {mode} list driver")
            elements = [target_fields(mode, t) for t in targets]
        except ValueError as exc:
            plan.state, plan.reason = "FAILED", str(exc)
            return [self._status(vid, ctx)]
        driver = drivers[0]
        first = self.loader.load(vid, vid, str(sample.get("operator_id", "")), driver,
                                 driver.elements[0], elements, ctx.catalogue,
                                 lambda: {"element_uid": 1})
        return [first, self._status(vid, ctx)]

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        if ctx.vehicle is None:
            return []
        if name in LIST_REPORTS:
            return self.held.on_report(name, fields, ctx)
        vid = ctx.vehicle.vehicle_id
        plan = self.plans.get(vid)
        if plan is None:
            return []
        if name in LIST_REPLIES:
            steps = self.loader.on_reply(vid, name, fields)
            if steps is None:
                return []
            load = self.loader.loads[vid]
            if load.state == "FAILED":
                plan.state, plan.reason = "FAILED", load.reason
                return [self._status(vid, ctx)]
            actions: list[Action] = list(steps)
            if load.state == "EXECUTING":
                plan.state = "EXECUTING"
                actions.append(self._status(vid, ctx))
                if ctx.source is not None:  # read back what the driver now holds
                    actions += self.held.refresh(vid, ctx.source)
            return actions
        if name == "ReportActiveElement" and plan.state == "EXECUTING":
            uid = int(fields.get("element_uid", 0))
            if 1 <= uid <= plan.count:
                plan.active = uid - 1
            elif uid == 0 and plan.active >= 0:
                plan.active, plan.state = -1, "COMPLETED"
            else:
                # not an element of this plan, or none active yet: a report from before
                # ExecuteList reached the arm, not the end of the plan
                return []
            return [self._status(vid, ctx)]
        return []

    def _status(self, vehicle_id: str, ctx: TranslatorContext) -> Publish:
        plan = self.plans[vehicle_id]
        return Publish("ManipulatorPlanStatus", {
            "vehicle_id": vehicle_id, "plan_id": plan.plan_id, "mode": plan.mode,
            "active_target": plan.active, "target_count": plan.count, "state": plan.state,
            "reason": plan.reason, "timestamp_ms": ctx.timestamp_ms})


def _list_rows() -> list[dict[str, Any]]:
    """Mapping-table rows of the manipulator's List Manager."""
    def row(direction: str, message: str, topic: str, fields: list[tuple[str, str, str]],
            query: str = "", doc: str = "", service_set: str = "") -> dict[str, Any]:
        out = {"translator": "manipulator", "direction": direction, "message": message,
               "topic": topic, "query": query, "service": "", "rate": None,
               "fields": [{"jaus": j, "dds": d, "note": n} for j, d, n in fields], "doc": doc}
        if service_set:
            out["service_set"] = service_set
        return out

    joints = [("joint_position_list[].joint_position", "targets[].values, units",
               "rad, or m where units[i] is m; clamped")]
    pose = [(jaus, f"targets[].{dds}", "m" if dds in "xyz" else "unit quaternion")
            for dds, jaus, _ in _POSE_FIELDS]
    element = [("element_uid / previous_uid / next_uid",
                "elements[].uid / previous_uid / next_uid", ""),
               ("element_data (SetJointPositions | SetEndEffectorPose)",
                "elements[].message, target", "decoded")]
    return [
        row("dds->jaus", "DeleteElement", "ManipulatorPlan",
            [("delete_element_list[].element_uid", "= 65535", "")],
            doc="every element, before a new plan"),
        row("dds->jaus", "SetElement", "ManipulatorPlan",
            [("element_list[].element_data", "targets[]", "UIDs 1..n, linked")],
            doc=f"<= {ELEMENTS_PER_SET} targets each, after the previous was confirmed"),
        row("dds->jaus", "SetJointPositions", "ManipulatorPlan", joints,
            doc="list element data, mode joint_positions"),
        row("dds->jaus", "SetEndEffectorPose", "ManipulatorPlan", pose,
            doc="list element data, mode end_effector_pose"),
        row("dds->jaus", "ExecuteList", "ManipulatorPlan",
            [("element_uid", "= 1", "the first target")],
            doc="after the last ConfirmElementRequest", service_set="manipulator"),
        row("jaus->dds", "ConfirmElementRequest", "ManipulatorPlanStatus",
            [("request_id", "state", "next step")],
            doc="from a manipulator list driver"),
        row("jaus->dds", "RejectElementRequest", "ManipulatorPlanStatus",
            [("response_code", "state, reason", "FAILED")],
            doc="from a manipulator list driver"),
        row("jaus->dds", "ReportActiveElement", "ManipulatorPlanStatus",
            [("element_uid", "active_target", "uid - 1; 0 after executing = COMPLETED")],
            "QueryActiveElement", "every-change event", service_set="manipulator"),
        row("jaus->dds", "ReportElementList", "ManipulatorList",
            [("element_list[].element_uid", "elements (order), element_count", "")],
            "QueryElementList", "every-change event; a changed list is read with "
            "QueryElement"),
        row("jaus->dds", "ReportElement", "ManipulatorList", element, "QueryElement",
            "asked for each listed element"),
        row("jaus->dds", "ReportElementCount", "ManipulatorList",
            [("element_count", "element_count", "a different count re-reads the list")],
            "QueryElementCount"),
    ]


class ManipulatorTranslator(RuleTranslator):
    """Manipulator service set <-> JointState, EndEffector* topics and their commands."""

    name = "manipulator"
    report_rules = (
        _joints("ReportJointPositions", "position", "joint_position_list", "joint_position",
                _POS_UNITS, "QueryJointPositions", MANIP + "ManipulatorJointPositionSensor"),
        _joints("ReportJointVelocity", "velocity", "joint_velocity_list", "joint_velocity",
                _VEL_UNITS, "QueryJointVelocity", MANIP + "ManipulatorJointVelocitySensor"),
        _joints("ReportJointEffort", "effort", "joint_effort_list", None, "%",
                "QueryJointEffort", MANIP + "PrimitiveManipulator"),
        _joints("ReportJointForceTorques", "force_torque", "actuator_force_torque_list",
                "joint_force_torque", _FT_UNITS, "QueryJointForceTorques",
                MANIP + "ManipulatorJointForceTorqueSensor"),
        _joints("ReportCommandedJointPositions", "commanded_position", "joint_position_list",
                "joint_position", _POS_UNITS, "QueryCommandedJointPositions",
                MANIP + "ManipulatorJointPositionDriver", rate=1.0),
        _joints("ReportCommandedJointVelocity", "commanded_velocity", "joint_velocity_list",
                "joint_velocity", _VEL_UNITS, "QueryCommandedJointVelocity",
                MANIP + "ManipulatorJointVelocityDriver", rate=1.0),
        _joints("ReportCommandedActuatorForceTorques", "commanded_force_torque",
                "actuator_force_torque_list", "joint_force_torque", _FT_UNITS,
                "QueryCommandedActuatorForceTorques",
                MANIP + "ManipulatorActuatorForceTorqueDriver", rate=1.0),
        _pan_tilt("ReportPanTiltJointPositions", "position", "position", "rad",
                  "QueryPanTiltJointPositions", MANIP + "PanTiltJointPositionSensor"),
        _pan_tilt("ReportPanTiltJointVelocity", "velocity", "velocity", "rad/s",
                  "QueryPanTiltJointVelocity", MANIP + "PanTiltJointVelocitySensor"),
        _pan_tilt("ReportPanTiltJointEffort", "effort", "effort", "%",
                  "QueryPanTiltJointEffort", MANIP + "PrimitivePanTilt"),
        _pan_tilt("ReportCommandedPanTiltJointPositions", "commanded_position", "position",
                  "rad", "QueryCommandedPanTiltJointPositions",
                  MANIP + "PanTiltJointPositionDriver"),
        _pan_tilt("ReportCommandedPanTiltJointVelocity", "commanded_velocity", "velocity",
                  "rad/s", "QueryCommandedPanTiltJointVelocity",
                  MANIP + "PanTiltJointVelocityDriver"),
        ReportRule("ReportEndEffectorEffort", "JointState",
                   {"device": Const("end_effector"), "quantity": Const("effort"),
                    "values": _pair_one("end_effector_effort"), "units": Const(["%"])},
                   query="QueryEndEffectorEffort", service=MANIP + "PrimitiveEndEffector"),
        ReportRule("ReportEndEffectorPose", "EndEffectorPose", {"kind": Const("actual"), **_POSE},
                   query="QueryEndEffectorPose",
                   service=MANIP + "ManipulatorEndEffectorPoseSensor", rate=5.0),
        ReportRule("ReportCommandedEndEffectorPose", "EndEffectorPose",
                   {"kind": Const("commanded"), **_POSE},
                   query="QueryCommandedEndEffectorPose",
                   service=MANIP + "ManipulatorEndEffectorPoseDriver"),
        ReportRule("ReportToolOffset", "EndEffectorPose",
                   {"kind": Const("tool_offset"), "x": _POSE["x"], "y": _POSE["y"],
                    "z": _POSE["z"]},
                   query="QueryToolOffset", service=MANIP + "ManipulatorToolOffsetService",
                   rate=0.2, on_change=True),
        ReportRule("ReportEndEffectorVelocityState", "EndEffectorVelocity",
                   {"kind": Const("actual"), **_TWIST}, query="QueryEndEffectorVelocityState",
                   service=MANIP + "ManipulatorEndEffectorVelocityStateSensor", rate=5.0),
        ReportRule("ReportCommandedEndEffectorVelocityState", "EndEffectorVelocity",
                   {"kind": Const("commanded"), **_TWIST},
                   query="QueryCommandedEndEffectorVelocityState",
                   service=MANIP + "ManipulatorEndEffectorVelocityStateDriver"),
        ReportRule("ReportManipulatorSpecifications", "JointSpecification",
                   {"device": Const("manipulator"), **{m: _spec(m) for m in (
                       "names", "types", "min_values", "max_values", "max_speeds", "units")}},
                   query="QueryManipulatorSpecifications", query_fields={"presence_vector": 0xFF},
                   service=MANIP + "ManipulatorSpecificationService", rate=0.2, on_change=True,
                   doc="v1.0 reports no joint names: names are empty"),
        ReportRule("ReportPanTiltSpecifications", "JointSpecification",
                   {"device": Const("pan_tilt"), "names": Const(["pan", "tilt"]),
                    "types": Const(["revolute", "revolute"]),
                    "min_values": _pair("joint1_min_value", "joint2_min_value"),
                    "max_values": _pair("joint1_max_value", "joint2_max_value"),
                    "max_speeds": _pair("joint1_max_speed", "joint2_max_speed"),
                    "units": Const(["rad", "rad"])},
                   query="QueryPanTiltSpecifications", query_fields={"presence_vector": 0xFF},
                   service=MANIP + "PanTiltSpecificationService", rate=0.2, on_change=True),
        ReportRule("ReportEndEffectorSpecification", "JointSpecification",
                   {"device": Const("end_effector"), "names": Const(["effort"]),
                    "types": Const(["end_effector"]), "parent_id": From("parent_id", default=-1)},
                   query="QueryEndEffectorSpecification",
                   service=MANIP + "PrimitiveEndEffector", rate=0.2, on_change=True),
        *(ReportRule("ReportJointMotionProfile", "JointState",
                     {"device": Const("manipulator"), "quantity": Const(quantity),
                      "values": _profile_values(member), "units": _profile_units(suffix)},
                     query="QueryJointMotionProfile",
                     service=MANIP + "ManipulatorJointMotionProfile", rate=0.2, on_change=True)
          for quantity, member, suffix in (
              ("max_speed", "joint_max_speed", "/s"),
              ("max_acceleration", "joint_max_acceleration_rate", "/s^2"),
              ("max_deceleration", "joint_max_deceleration_rate", "/s^2"))),
        *(ReportRule("ReportPanTiltMotionProfile", "JointState",
                     {"device": Const("pan_tilt"), "quantity": Const(quantity),
                      "values": _pan_tilt_profile(member), "units": Const([unit, unit])},
                     query="QueryPanTiltMotionProfile",
                     service=MANIP + "PanTiltMotionProfileService", rate=0.2, on_change=True)
          for quantity, member, unit in (
              ("max_speed", "max_speed", "rad/s"),
              ("max_acceleration", "max_acceleration_rate", "rad/s^2"),
              ("max_deceleration", "max_deceleration_rate", "rad/s^2"))),
    )
    command_rules = (
        Cmd("JointCommand", "SetJointPositions", MANIP + "ManipulatorJointPositionDriver",
            "joint_position", {"joint_position_list": PutEach(
                "values", _position, "radian, or meter where units[i] is m; clamped")},
            when={"device": ("manipulator", ""), "quantity": "position"}),
        Cmd("JointCommand", "SetJointVelocity", MANIP + "ManipulatorJointVelocityDriver",
            "joint_velocity", {"joint_velocity_list": PutEach(
                "values", _velocity, "rad/s, or m/s where units[i] is m/s; clamped")},
            when={"device": ("manipulator", ""), "quantity": "velocity"},
            stop=_zeros("joint_velocity_list", "joint_velocity", "variant"),
            doc="motion: dead-man stop"),
        Cmd("JointCommand", "SetJointEffort", MANIP + "PrimitiveManipulator", "joint_effort",
            {"joint_effort_list": PutEach("values", _effort, "percent, clamped to +-100")},
            when={"device": ("manipulator", ""), "quantity": "effort"},
            stop=_zeros("joint_effort_list", "joint_effort", None), doc="motion: dead-man stop"),
        Cmd("JointCommand", "SetActuatorForceTorques",
            MANIP + "ManipulatorActuatorForceTorqueDriver", "joint_force_torque",
            {"actuator_force_torque_list": PutEach(
                "values", _force, "N m, or N where units[i] is N; clamped")},
            when={"device": ("manipulator", ""), "quantity": "force_torque"},
            stop=_zeros("actuator_force_torque_list", "joint_force_torque", "variant"),
            doc="motion: dead-man stop"),
        Cmd("JointCommand", "SetPanTiltJointPositions", MANIP + "PanTiltJointPositionDriver",
            "pan_tilt_position",
            {"joint1_position": Put("values[0]", -REVOLUTE_LIMIT, REVOLUTE_LIMIT),
             "joint2_position": Put("values[1]", -REVOLUTE_LIMIT, REVOLUTE_LIMIT)},
            when={"device": "pan_tilt", "quantity": "position"}),
        Cmd("JointCommand", "SetPanTiltJointVelocity", MANIP + "PanTiltJointVelocityDriver",
            "pan_tilt_velocity",
            {"joint1_velocity": Put("values[0]", -REVOLUTE_RATE, REVOLUTE_RATE),
             "joint2_velocity": Put("values[1]", -REVOLUTE_RATE, REVOLUTE_RATE)},
            when={"device": "pan_tilt", "quantity": "velocity"},
            stop={"joint1_velocity": 0.0, "joint2_velocity": 0.0}, doc="motion: dead-man stop"),
        Cmd("JointCommand", "SetPanTiltJointEffort", MANIP + "PrimitivePanTilt",
            "pan_tilt_effort",
            {"joint1_effort": Put("values[0]", -100.0, 100.0),
             "joint2_effort": Put("values[1]", -100.0, 100.0)},
            when={"device": "pan_tilt", "quantity": "effort"},
            stop={"joint1_effort": 0.0, "joint2_effort": 0.0}, doc="motion: dead-man stop"),
        Cmd("EndEffectorCommand", "SetEndEffectorPose", MANIP + "ManipulatorEndEffectorPoseDriver",
            "end_effector_pose",
            {"tool_point_coordinate_x": Put("x", -30.0, 30.0),
             "tool_point_coordinate_y": Put("y", -30.0, 30.0),
             "tool_point_coordinate_z": Put("z", -30.0, 30.0),
             "d_component_of_unit_quaternion_q": Put("qw", -1.0, 1.0, default=1.0),
             "a_component_of_unit_quaternion_q": Put("qx", -1.0, 1.0),
             "b_component_of_unit_quaternion_q": Put("qy", -1.0, 1.0),
             "c_component_of_unit_quaternion_q": Put("qz", -1.0, 1.0)},
            when={"mode": "pose"}),
        Cmd("EndEffectorCommand", "SetEndEffectorVelocityState",
            MANIP + "ManipulatorEndEffectorVelocityStateDriver", "end_effector_velocity",
            {"linear_velocity_component_x": Put("vx", -10.0, 10.0),
             "linear_velocity_component_y": Put("vy", -10.0, 10.0),
             "linear_velocity_component_z": Put("vz", -10.0, 10.0),
             "angular_velocity_component_x": Put("wx", -20 * math.pi, 20 * math.pi),
             "angular_velocity_component_y": Put("wy", -20 * math.pi, 20 * math.pi),
             "angular_velocity_component_z": Put("wz", -20 * math.pi, 20 * math.pi)},
            when={"mode": "velocity"},
            stop=dict.fromkeys(("linear_velocity_component_x", "linear_velocity_component_y",
                                "linear_velocity_component_z", "angular_velocity_component_x",
                                "angular_velocity_component_y", "angular_velocity_component_z"),
                               0.0), doc="motion: dead-man stop"),
        Cmd("JointCommand", "ExecuteList", MANIP + "ManipulatorListDriver",
            "joint_list", {"element_uid": Build("values", _element_uid,
                                                "values[0]: the list element to start at")},
            when={"device": ("manipulator", ""), "quantity": "execute_list"},
            doc="runs the joint-position list loaded on the vehicle",
            service_set="manipulator"),
        Cmd("EndEffectorCommand", "SetEndEffectorEffort", MANIP + "PrimitiveEndEffector",
            "end_effector_effort", {"end_effector_effort": Put("effort", -100.0, 100.0)},
            when={"mode": "effort"}),
        Cmd("JointCommand", "SetJointMotionProfile", MANIP + "ManipulatorJointMotionProfile",
            "joint_motion_profile",
            {"joint_motion_profile_list": Build(
                "values, units", _profile_list,
                "speed, acceleration, deceleration per joint (rad or m by units[i])")},
            when={"device": ("manipulator", ""), "quantity": "motion_profile"},
            doc="v1.0: SetMotionProfile, motion_profile_list"),
        Cmd("JointCommand", "SetPanTiltMotionProfile", MANIP + "PanTiltMotionProfileService",
            "pan_tilt_motion_profile",
            {name: _pan_tilt_profile_value(i, 10 * math.pi) for i, name in enumerate(_PT_PROFILE)},
            when={"device": "pan_tilt", "quantity": "motion_profile"}),
        Cmd("EndEffectorCommand", "SetToolOffset", MANIP + "ManipulatorToolOffsetService",
            "tool_offset",
            {"tool_point_coordinate_x": Put("x", -15.0, 15.0),
             "tool_point_coordinate_y": Put("y", -15.0, 15.0),
             "tool_point_coordinate_z": Put("z", -15.0, 15.0)},
            when={"mode": "tool_offset"}),
    )
    not_translated = ()
    extra_messages = LIST_MESSAGES
    extra_publishes = ("ManipulatorPlanStatus", "ManipulatorList")

    @classmethod
    def _derive(cls) -> None:
        super()._derive()
        # the List Manager's plans: its list drivers' lists and progress, ManipulatorPlan
        cls.reports = (*cls.reports, *(d.read_back() for d in LIST_DRIVERS),
                       *(d.progress() for d in LIST_DRIVERS))
        cls.subscribes = (*cls.subscribes, "ManipulatorPlan")
        cls.controlled_services = tuple(dict.fromkeys(
            (*cls.controlled_services, *(d.service for d in LIST_DRIVERS))))
        cls.bindings = {**cls.bindings, **list_bindings(LIST_DRIVERS)}

    def __init__(self) -> None:
        super().__init__()
        self.lists = ManipulatorLists()

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        if name in LIST_MESSAGES:
            return self.lists.on_message(name, fields, ctx)
        return super().on_message(name, fields, ctx)

    def describe(self) -> list[dict[str, Any]]:
        """The rule tables' rows, then the List Manager's."""
        return [*super().describe(), *_list_rows()]

    def on_sample(self, topic: str, sample: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        """A v1.0 manipulator gets the v1.0 field names where v1.0 named them otherwise."""
        if topic == "ManipulatorPlan":
            return self.lists.on_plan(sample, ctx)
        actions = super().on_sample(topic, sample, ctx)
        if ctx.vehicle is None or not ctx.vehicle.speaks(V1, SET_MOTION_PROFILE):
            return actions
        return [replace(a, fields=_renamed(a.fields, _V1_NAMES))
                if isinstance(a, Command) and a.name == "SetJointMotionProfile" else a
                for a in actions]

    def command(self, rule, sample):  # type: ignore[no-untyped-def]
        """Pan-tilt rules read ``values[0]``/``values[1]``: expose them as members first."""
        values = list(sample.get("values") or ())
        if any(isinstance(s, Put) and s.dds.startswith("values[") for s in rule.fields.values()):
            if len(values) < 2:
                return None
            sample = {**sample, "values[0]": values[0], "values[1]": values[1]}
        elif isinstance(sample.get("values"), list | tuple) and not values:
            return None
        return super().command(rule, sample)

