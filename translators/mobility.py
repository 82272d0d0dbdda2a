"""The ``mobility`` translator (AS6009): pose, velocity, drivers' state and drive commands.

No I/O. The pose, velocity, effort, vector, limit and pose-reset mappings are rule tables
(:mod:`translators.generic`): what runs is what ``edge-vis mappings`` prints. JAUS -> DDS:

* ReportGlobalPose -> ``GlobalPose`` (degrees, metres, radians)
* ReportLocalPose -> ``LocalPose`` (metres, radians)
* ReportVelocityState -> ``Velocity`` (m/s, rad/s)
* ReportAccelerationState -> ``AccelerationState`` (m/s^2, rad/s^2)
* ReportWrenchEffort -> ``WrenchEffortState`` (percent)
* ReportVelocityCommand -> ``VelocityCommandState`` (the current command, m/s, rad/s)
* ReportGlobalVector / ReportLocalVector -> ``VectorState`` (frame GLOBAL / LOCAL)
* ReportAccelerationLimit -> ``AccelerationLimit`` (MAXIMUM / MINIMUM)
* ReportGeomagneticProperty -> ``GeomagneticProperty`` (magnetic variation, rad)
* ReportActiveElement, ReportTravelSpeed, Confirm/RejectElementRequest and, for
  single-waypoint drivers, the pose reaching a waypoint -> ``MissionStatus``
* ReportElementList, ReportElement, ReportElementCount (each waypoint list and path
  segment driver's List Manager) and Report{Global,Local}{Waypoint,PathSegment} (what a
  driver is going to) -> ``VehiclePlan``, the plan each component actually holds (see
  :func:`plan_read_back`)

DDS -> JAUS (commands, throttled and control-checked by the engine):

* ``WrenchEffortCommand`` -> SetWrenchEffort to the PrimitiveDriver (percent; propulsive
  clamped to [-100, 100], resistive to [0, 100]; an absent field is left out, i.e. left
  unchanged by the vehicle; stop = all propulsive efforts zero)
* ``VelocityCommand`` -> SetVelocityCommand (current command) to the VelocityStateDriver
  (stop = all zero)
* ``VectorCommand`` -> SetGlobalVector / SetLocalVector by ``frame`` (angles wrapped to
  [-pi, pi]; absent = unchanged; stop = speed zero)
* ``AccelerationLimitCommand`` -> SetAccelerationLimit (MAXIMUM / MINIMUM)
* ``PoseCommand`` -> SetGlobalPose / SetLocalPose by ``frame`` (resets a pose sensor's
  estimate; absent = unchanged); its ``magnetic_variation``, when given, ->
  SetGeomagneticProperty
* ``WaypointPlan`` -> the List Manager sequence to the Global/LocalWaypointListDriver
  (DeleteElement, SetElement with Set{Global,Local}Waypoint elements, ExecuteList), or
  SetTravelSpeed and Set{Global,Local}Waypoint one at a time to a vehicle with only a
  waypoint driver (see :class:`WaypointMissions`)
* ``PathSegmentPlan`` -> the same List Manager sequence with Set{Global,Local}PathSegment
  elements to the Global/LocalPathSegmentDriver, then ExecuteList
* ``PlanQuery`` -> QueryElementCount and QueryElementList to every list driver: the plan
  is read back again, every element

A command that would set nothing (every member absent) is not sent. Fields a vehicle does
not report are published as NaN, so "not reported" never reads as zero. ``timestamp_ms``
is the relay's reception time (wall clock, ms since the epoch): the JAUS TimeStamp carries
no date and cannot be converted without guessing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from edge_vis.kit import (
    ELEMENTS_PER_SET,
    LIST_REPLIES,
    LIST_REPORTS,
    NAN,
    QUERIES_IN_FLIGHT,
    Action,
    Build,
    Command,
    Const,
    From,
    HeldList,
    JausAddress,
    ListDriver,
    ListLoader,
    ListReadBack,
    Publish,
    Put,
    ReportRule,
    ReportSpec,
    RuleTranslator,
    TranslatorContext,
    code_of,
    label,
    list_bindings,
    number,
    setting,
)
from edge_vis.kit import CommandRule as Cmd

MOBILITY = "urn:jaus:jss:mobility:"
PRIMITIVE_DRIVER = MOBILITY + "PrimitiveDriver"
VELOCITY_DRIVER = MOBILITY + "VelocityStateDriver"
GLOBAL_POSE_SENSOR = MOBILITY + "GlobalPoseSensor"
LOCAL_POSE_SENSOR = MOBILITY + "LocalPoseSensor"
GLOBAL_VECTOR_DRIVER = MOBILITY + "GlobalVectorDriver"
LOCAL_VECTOR_DRIVER = MOBILITY + "LocalVectorDriver"

#: presence vector asking for every field of the pose and velocity reports
ALL_FIELDS = 0x01FF
#: ... of ReportWrenchEffort (12 efforts)
ALL_EFFORTS = 0x0FFF
#: ... of ReportVelocityCommand and ReportAccelerationLimit (6 values)
ALL_SIX = 0x3F
#: ... of Report{Global,Local}Vector (speed, altitude/z, heading, roll, pitch)
ALL_VECTOR = 0x1F

#: SetVelocityCommand / ReportVelocityCommand CommandType
COMMAND_TYPES = {0: "CURRENT", 1: "MAXIMUM", 2: "MINIMUM", 3: "DEFAULT"}
#: SetAccelerationLimit / ReportAccelerationLimit CommandType
LIMITS = {1: "MAXIMUM", 2: "MINIMUM"}

VELOCITY_LIMIT = 327.67           # m/s, SetVelocityCommand velocity_x/y/z
RATE_LIMIT = 32.767               # rad/s, SetVelocityCommand rates
ACCELERATION_LIMIT = 1310.68      # m/s^2, SetAccelerationLimit linear
ANGULAR_ACCELERATION_LIMIT = 13106.8  # rad/s^2, SetAccelerationLimit angular


def _clamp(value: Any, low: float, high: float) -> float:
    if value is None:  # an optional DDS field the operator left unset
        return 0.0
    number = float(value)
    if math.isnan(number):
        return 0.0
    return max(low, min(high, number))


def wrap_angle(value: Any) -> float:
    """Converter: radians -> the same direction in [-pi, pi] (a heading of 3.5 rad is
    -2.78 rad, not pi)."""
    angle = math.remainder(float(value), math.tau)
    return max(-math.pi, min(math.pi, angle))


def _is_local(value: Any) -> bool:
    """LOCAL"""
    return str(value).strip().upper() in ("LOCAL", "1")


def _is_global(value: Any) -> bool:
    """GLOBAL (the default)"""
    return not _is_local(value)


def _given(value: Any) -> bool:
    """given"""
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def _measured(*pairs: tuple[str, str], note: str = "") -> dict[str, From]:
    """DDS member <- JAUS field, as a float (NaN when the vehicle left it out)."""
    return {dds: From(jaus, convert=number, note=note) for dds, jaus in pairs}


_GLOBAL_POSE = _measured(("latitude", "latitude"), ("longitude", "longitude"),
                         ("altitude", "altitude"), ("roll", "roll"), ("pitch", "pitch"),
                         ("yaw", "yaw"))
_LOCAL_POSE = _measured(("x", "x"), ("y", "y"), ("z", "z"), ("roll", "roll"),
                        ("pitch", "pitch"), ("yaw", "yaw"))
_VELOCITY = _measured(("vx", "velocity_x"), ("vy", "velocity_y"), ("vz", "velocity_z"),
                      ("roll_rate", "roll_rate"), ("pitch_rate", "pitch_rate"),
                      ("yaw_rate", "yaw_rate"))
_ACCELERATION = _measured(("ax", "acceleration_x"), ("ay", "acceleration_y"),
                          ("az", "acceleration_z"), ("roll_acceleration", "roll_acceleration"),
                          ("pitch_acceleration", "pitch_acceleration"),
                          ("yaw_acceleration", "yaw_acceleration"))
#: (DDS member, JAUS field, lowest, highest) of the twelve efforts, percent
_WRENCH = tuple(
    (f"{kind}_{axis}", f"{kind}_effort_{axis}", low, 100.0)
    for kind, low in (("propulsive_linear", -100.0), ("propulsive_rotational", -100.0),
                      ("resistive_linear", 0.0), ("resistive_rotational", 0.0))
    for axis in ("x", "y", "z")
)
_WRENCH_STOP = {jaus: 0.0 for dds, jaus, _, _ in _WRENCH if dds.startswith("propulsive")}
#: (DDS member, SetVelocityCommand field, limit)
_VELOCITY_CMD = (
    ("vx", "velocity_x", VELOCITY_LIMIT), ("vy", "velocity_y", VELOCITY_LIMIT),
    ("vz", "velocity_z", VELOCITY_LIMIT), ("roll_rate", "roll_rate", RATE_LIMIT),
    ("pitch_rate", "pitch_rate", RATE_LIMIT), ("yaw_rate", "yaw_rate", RATE_LIMIT),
)
_LIMIT_CMD = (
    ("ax", "acceleration_x", ACCELERATION_LIMIT), ("ay", "acceleration_y", ACCELERATION_LIMIT),
    ("az", "acceleration_z", ACCELERATION_LIMIT),
    ("roll_acceleration", "roll_acceleration", ANGULAR_ACCELERATION_LIMIT),
    ("pitch_acceleration", "pitch_acceleration", ANGULAR_ACCELERATION_LIMIT),
    ("yaw_acceleration", "yaw_acceleration", ANGULAR_ACCELERATION_LIMIT),
)


def _angle(dds: str) -> Put:
    return Put(dds, convert=wrap_angle, optional=True, note="rad, wrapped to [-pi, pi]")


def _vector(frame: str, height: str) -> dict[str, Any]:
    """VectorState members of Report{Global,Local}Vector (``height``: altitude or z)."""
    return {"frame": Const(frame), "speed": From("speed", convert=number, note="m/s"),
            "heading": From("heading", convert=number, note="rad"),
            "altitude": From(height, convert=number, note="m") if height == "altitude"
            else Const(NAN, "GLOBAL only"),
            "z": From(height, convert=number, note="m") if height == "z"
            else Const(NAN, "LOCAL only"),
            "roll": From("roll", convert=number), "pitch": From("pitch", convert=number)}


def _set_vector(height: str) -> dict[str, Put]:
    """Set{Global,Local}Vector fields from a VectorCommand (``height``: altitude or z)."""
    return {"speed": Put("speed", 0.0, VELOCITY_LIMIT, optional=True, note="m/s"),
            height: Put(height, -10_000.0, 35_000.0, optional=True, note="m"),
            "heading": _angle("heading"), "roll": _angle("roll"), "pitch": _angle("pitch")}


def _set_pose(local: bool) -> dict[str, Put]:
    """Set{Global,Local}Pose fields from a PoseCommand."""
    if local:
        position = {axis: Put(axis, -100_000.0, 100_000.0, optional=True, note="m")
                    for axis in ("x", "y", "z")}
    else:
        position = {"latitude": Put("latitude", -90.0, 90.0, optional=True, note="deg"),
                    "longitude": Put("longitude", -180.0, 180.0, optional=True, note="deg"),
                    "altitude": Put("altitude", -10_000.0, 35_000.0, optional=True,
                                    note="m")}
    return {**position,
            "position_rms": Put("position_rms", 0.0, 100.0, optional=True, note="m"),
            "roll": _angle("roll"), "pitch": _angle("pitch"), "yaw": _angle("yaw"),
            "attitude_rms": Put("attitude_rms", 0.0, math.pi, optional=True, note="rad")}


def _current(sample: Mapping[str, Any]) -> int:
    return 0


def _limit_type(sample: Mapping[str, Any]) -> int:
    value = code_of(LIMITS)(sample.get("limit") or "MAXIMUM")
    if value not in LIMITS:
        raise ValueError(f"limit {value!r} is not one of {', '.join(LIMITS.values())}")
    return value


#: driver and sensor settings: translated when they arrive, asked for (events) only when
#: the profile lists them in ``[translators.mobility] extra_reports`` (radio links are slow)
OPTIONAL_REPORTS = ("ReportWrenchEffort", "ReportVelocityCommand", "ReportGlobalVector",
                    "ReportLocalVector", "ReportAccelerationLimit", "ReportGeomagneticProperty")
_OPT_IN = "asked for when listed in [translators.mobility] extra_reports"


@dataclass(frozen=True, slots=True)
class MobilityOptions:
    """``[translators.mobility]``: ``extra_reports``, the :data:`OPTIONAL_REPORTS` to ask
    for too (``["*"]`` for all of them)."""

    extra_reports: tuple[str, ...] = setting((), choices=("*", *OPTIONAL_REPORTS))

REPORT_RULES = (
    ReportRule("ReportGlobalPose", "GlobalPose", _GLOBAL_POSE, query="QueryGlobalPose",
               service=GLOBAL_POSE_SENSOR, query_fields={"presence_vector": ALL_FIELDS},
               rate=5.0),
    ReportRule("ReportLocalPose", "LocalPose", _LOCAL_POSE, query="QueryLocalPose",
               service=LOCAL_POSE_SENSOR, query_fields={"presence_vector": ALL_FIELDS},
               rate=5.0),
    ReportRule("ReportVelocityState", "Velocity", _VELOCITY, query="QueryVelocityState",
               service=MOBILITY + "VelocityStateSensor",
               query_fields={"presence_vector": ALL_FIELDS}, rate=5.0),
    ReportRule("ReportAccelerationState", "AccelerationState", _ACCELERATION,
               query="QueryAccelerationState", service=MOBILITY + "AccelerationStateSensor",
               query_fields={"presence_vector": ALL_FIELDS}, rate=1.0),
    ReportRule("ReportWrenchEffort", "WrenchEffortState",
               _measured(*((dds, jaus) for dds, jaus, _, _ in _WRENCH), note="percent"),
               query="QueryWrenchEffort", service=PRIMITIVE_DRIVER,
               query_fields={"presence_vector": ALL_EFFORTS}, rate=1.0,
               doc=f"what the primitive driver applies; {_OPT_IN}"),
    ReportRule("ReportVelocityCommand", "VelocityCommandState",
               {"command_type": From("command_type", convert=label(COMMAND_TYPES)),
                **_measured(*((dds, jaus) for dds, jaus, _ in _VELOCITY_CMD))},
               query="QueryVelocityCommand", service=VELOCITY_DRIVER,
               query_fields={"presence_vector": ALL_SIX, "command_type": 0}, rate=1.0,
               doc=f"the velocity the driver is holding; {_OPT_IN}"),
    ReportRule("ReportGlobalVector", "VectorState", _vector("GLOBAL", "altitude"),
               query="QueryGlobalVector", service=GLOBAL_VECTOR_DRIVER,
               query_fields={"presence_vector": ALL_VECTOR}, rate=1.0, doc=_OPT_IN),
    ReportRule("ReportLocalVector", "VectorState", _vector("LOCAL", "z"),
               query="QueryLocalVector", service=LOCAL_VECTOR_DRIVER,
               query_fields={"presence_vector": ALL_VECTOR}, rate=1.0, doc=_OPT_IN),
    ReportRule("ReportAccelerationLimit", "AccelerationLimit",
               {"limit": From("command_type", convert=label(LIMITS)),
                **_measured(*((dds, jaus) for dds, jaus, _ in _LIMIT_CMD))},
               query="QueryAccelerationLimit", service=VELOCITY_DRIVER,
               query_fields={"presence_vector": ALL_SIX, "command_type": 1}, rate=0.2,
               on_change=True,
               doc=f"the maximum is asked for, a minimum is taken if sent; {_OPT_IN}"),
    ReportRule("ReportGeomagneticProperty", "GeomagneticProperty",
               {"magnetic_variation": From("magnetic_variation", convert=number,
                                           note="rad, east positive")},
               query="QueryGeomagneticProperty", service=GLOBAL_POSE_SENSOR, rate=0.1,
               on_change=True, doc=_OPT_IN),
)

COMMAND_RULES = (
    Cmd("VelocityCommand", "SetVelocityCommand", VELOCITY_DRIVER, "velocity",
        {"command_type": Build("(fixed)", _current, "= 0, the current command"),
         **{jaus: Put(dds, -limit, limit) for dds, jaus, limit in _VELOCITY_CMD}},
        stop={"command_type": 0, **{jaus: 0.0 for _, jaus, _ in _VELOCITY_CMD}},
        doc="motion: dead-man stop = all zero"),
    Cmd("WrenchEffortCommand", "SetWrenchEffort", PRIMITIVE_DRIVER, "wrench_effort",
        {jaus: Put(dds, low, high, optional=True, note="percent")
         for dds, jaus, low, high in _WRENCH},
        stop=_WRENCH_STOP, doc="motion: dead-man stop = propulsive efforts zero"),
    Cmd("VectorCommand", "SetGlobalVector", GLOBAL_VECTOR_DRIVER, "vector",
        _set_vector("altitude"), when={"frame": _is_global}, stop={"speed": 0.0},
        doc="motion: dead-man stop = speed zero"),
    Cmd("VectorCommand", "SetLocalVector", LOCAL_VECTOR_DRIVER, "vector",
        _set_vector("z"), when={"frame": _is_local}, stop={"speed": 0.0},
        doc="motion: dead-man stop = speed zero"),
    Cmd("AccelerationLimitCommand", "SetAccelerationLimit", VELOCITY_DRIVER,
        "acceleration_limit",
        {"command_type": Build("limit", _limit_type, "MAXIMUM = 1, MINIMUM = 2"),
         **{jaus: Put(dds, -limit, limit, optional=True)
            for dds, jaus, limit in _LIMIT_CMD}}),
    Cmd("PoseCommand", "SetGlobalPose", GLOBAL_POSE_SENSOR, "pose_reset",
        _set_pose(local=False), when={"frame": _is_global},
        doc="resets the sensor's estimate"),
    Cmd("PoseCommand", "SetLocalPose", LOCAL_POSE_SENSOR, "pose_reset",
        _set_pose(local=True), when={"frame": _is_local}, doc="resets the sensor's estimate"),
    Cmd("PoseCommand", "SetGeomagneticProperty", GLOBAL_POSE_SENSOR, "geomagnetic",
        {"magnetic_variation": Put("magnetic_variation", convert=wrap_angle,
                                   note="rad, east positive, wrapped to [-pi, pi]")},
        when={"magnetic_variation": _given}),
)

# -- waypoint missions (WaypointPlan -> List Manager / waypoint drivers -> MissionStatus) --

GLOBAL_LIST_DRIVER = MOBILITY + "GlobalWaypointListDriver"
LOCAL_LIST_DRIVER = MOBILITY + "LocalWaypointListDriver"
GLOBAL_WAYPOINT_DRIVER = MOBILITY + "GlobalWaypointDriver"
LOCAL_WAYPOINT_DRIVER = MOBILITY + "LocalWaypointDriver"
GLOBAL_SEGMENT_DRIVER = MOBILITY + "GlobalPathSegmentDriver"
LOCAL_SEGMENT_DRIVER = MOBILITY + "LocalPathSegmentDriver"
#: the drivers whose List Manager holds a plan the relay loads and reads back
LIST_DRIVERS = (GLOBAL_LIST_DRIVER, LOCAL_LIST_DRIVER, GLOBAL_SEGMENT_DRIVER,
                LOCAL_SEGMENT_DRIVER)
#: the same, declared for the kit's list mechanism (ExecuteList of the mobility set)
DRIVERS = {
    GLOBAL_LIST_DRIVER: ListDriver(GLOBAL_LIST_DRIVER, "mobility", ("SetGlobalWaypoint",),
                                   "waypoint"),
    LOCAL_LIST_DRIVER: ListDriver(LOCAL_LIST_DRIVER, "mobility", ("SetLocalWaypoint",),
                                  "waypoint"),
    GLOBAL_SEGMENT_DRIVER: ListDriver(GLOBAL_SEGMENT_DRIVER, "mobility",
                                      ("SetGlobalPathSegment",), "waypoint"),
    LOCAL_SEGMENT_DRIVER: ListDriver(LOCAL_SEGMENT_DRIVER, "mobility",
                                     ("SetLocalPathSegment",), "waypoint"),
}
#: metres that count as "reached" for single-waypoint drivers when the plan says 0
DEFAULT_TOLERANCE = 2.0
#: ExecuteList speed when the plan says 0 and the vehicle never reported a travel speed
DEFAULT_SPEED = 1.0
_EARTH_RADIUS = 6_371_000.0
MISSION_MESSAGES = ("ConfirmElementRequest", "RejectElementRequest", "ReportActiveElement",
                    "ReportTravelSpeed")
MISSION_REPORTS = tuple(
    spec for driver in DRIVERS.values()
    for spec in (driver.progress(),
                 ReportSpec("ReportTravelSpeed", "QueryTravelSpeed", driver.service, rate=1.0,
                            on_change=True))
)


@dataclass
class _Mission:
    """One vehicle's plan on its way to, and through, the vehicle."""

    plan_id: str
    operator_id: str
    local: bool
    service: str
    listed: bool
    waypoints: list[dict[str, float]]
    speed: float
    #: the JAUS message each list element carries, and its fields per element
    element: str = ""
    element_fields: list[dict[str, float]] = field(default_factory=list)
    active: int = -1
    state: str = "PENDING"
    travel_speed: float = math.nan


def waypoint_fields(wp: Mapping[str, Any], local: bool) -> dict[str, float]:
    """SetGlobalWaypoint / SetLocalWaypoint fields of one ``Waypoint`` (clamped; tolerance
    only when given)."""
    if local:
        fields = {axis: _clamp(wp.get(axis), -100_000.0, 100_000.0) for axis in ("x", "y", "z")}
    else:
        fields = {"latitude": _clamp(wp.get("latitude"), -90.0, 90.0),
                  "longitude": _clamp(wp.get("longitude"), -180.0, 180.0),
                  "altitude": _clamp(wp.get("altitude"), -10_000.0, 35_000.0)}
    tolerance = _clamp(wp.get("tolerance"), 0.0, 100.0)
    if tolerance > 0:
        fields["waypoint_tolerance"] = tolerance
    return fields


def segment_fields(seg: Mapping[str, Any], local: bool) -> dict[str, float]:
    """SetGlobalPathSegment / SetLocalPathSegment fields of one ``PathSegment``: P2 is the
    end point, P1 the control point (clamped; tolerance only when given)."""
    if local:
        fields = {f"p{n}_{axis}": _clamp(seg.get(prefix + axis), low, high)
                  for n, prefix in ((1, "control_"), (2, ""))
                  for axis, low, high in (("x", -100_000.0, 100_000.0),
                                          ("y", -100_000.0, 100_000.0),
                                          ("z", -10_000.0, 35_000.0))}
    else:
        fields = {f"p{n}_{name}": _clamp(seg.get(prefix + name), low, high)
                  for n, prefix in ((1, "control_"), (2, ""))
                  for name, low, high in (("latitude", -90.0, 90.0),
                                          ("longitude", -180.0, 180.0),
                                          ("altitude", -10_000.0, 35_000.0))}
    fields["weighting_factor"] = _clamp(seg.get("weighting_factor"), 0.0, 500.0)
    tolerance = _clamp(seg.get("tolerance"), 0.0, 100_000.0)
    if tolerance > 0:
        fields["path_tolerance"] = tolerance
    return fields


class WaypointMissions:
    """WaypointPlan -> List Manager sequence (or single waypoints) -> MissionStatus.

    With a waypoint *list* driver the plan is loaded by the kit's list mechanism
    (:class:`~edge_vis.kit.lists.ListLoader`: DeleteElement, SetElement batches of
    Set{Global,Local}Waypoint elements, each after the previous was confirmed, then
    ExecuteList with the speed). With only a waypoint driver the waypoints go out one at
    a time: the next when the reported pose comes within the waypoint's tolerance. Every
    step is a :class:`Command` (control-gated and throttled by the engine, kind
    ``waypoint``).
    """

    def __init__(self) -> None:
        self.missions: dict[str, _Mission] = {}
        self.lists = ListLoader()

    def on_plan(self, sample: Mapping[str, Any], ctx: TranslatorContext) -> list[Action]:
        vehicle = ctx.vehicle
        if vehicle is None:
            return []
        local = str(sample.get("frame", "GLOBAL")).upper() in ("LOCAL", "1")
        services = {uri for uri, _ in vehicle.services}
        list_driver = LOCAL_LIST_DRIVER if local else GLOBAL_LIST_DRIVER
        single_driver = LOCAL_WAYPOINT_DRIVER if local else GLOBAL_WAYPOINT_DRIVER
        waypoints = [dict(w) for w in sample.get("waypoints") or ()]
        old = self.missions.get(vehicle.vehicle_id)
        mission = _Mission(str(sample.get("plan_id", "")), str(sample.get("operator_id", "")),
                           local, list_driver, True, waypoints,
                           float(sample.get("speed") or 0.0),
                           travel_speed=old.travel_speed if old else math.nan)
        mission.element = "SetLocalWaypoint" if local else "SetGlobalWaypoint"
        mission.element_fields = [waypoint_fields(w, local) for w in waypoints]
        if list_driver not in services:
            mission.service, mission.listed = single_driver, False
        self.lists.loads.pop(vehicle.vehicle_id, None)  # a new plan replaces any load
        if not waypoints or mission.service not in services:
            mission.state = "FAILED"
            self.missions[vehicle.vehicle_id] = mission
            return [self._status(vehicle.vehicle_id, ctx)]
        self.missions[vehicle.vehicle_id] = mission
        if mission.listed:
            return [self._load(mission, vehicle.vehicle_id, ctx),
                    self._status(vehicle.vehicle_id, ctx)]
        mission.active, mission.state = 0, "EXECUTING"
        # a waypoint driver drives at its travel speed: set it first (its own throttle
        # slot, so it is not coalesced away by the waypoint)
        speed = Command(vehicle.vehicle_id, mission.operator_id, "waypoint_speed",
                        "SetTravelSpeed", {"speed": _clamp(self._speed(mission), 0.0, 327.67)},
                        mission.service)
        return [speed, self._waypoint(vehicle.vehicle_id, 0),
                self._status(vehicle.vehicle_id, ctx)]

    def on_segments(self, sample: Mapping[str, Any],
                    ctx: TranslatorContext) -> list[Action]:
        """A ``PathSegmentPlan``: the List Manager sequence to a path segment driver."""
        vehicle = ctx.vehicle
        if vehicle is None:
            return []
        local = _is_local(sample.get("frame", "GLOBAL"))
        segments = [dict(s) for s in sample.get("segments") or ()]
        service = LOCAL_SEGMENT_DRIVER if local else GLOBAL_SEGMENT_DRIVER
        old = self.missions.get(vehicle.vehicle_id)
        mission = _Mission(str(sample.get("plan_id", "")), str(sample.get("operator_id", "")),
                           local, service, True, segments, float(sample.get("speed") or 0.0),
                           "SetLocalPathSegment" if local else "SetGlobalPathSegment",
                           [segment_fields(seg, local) for seg in segments],
                           travel_speed=old.travel_speed if old else math.nan)
        self.missions[vehicle.vehicle_id] = mission
        self.lists.loads.pop(vehicle.vehicle_id, None)  # a new plan replaces any load
        if not segments or service not in {uri for uri, _ in vehicle.services}:
            mission.state = "FAILED"
            return [self._status(vehicle.vehicle_id, ctx)]
        return [self._load(mission, vehicle.vehicle_id, ctx),
                self._status(vehicle.vehicle_id, ctx)]

    @staticmethod
    def _speed(mission: _Mission) -> float:
        """The plan's speed; 0 means the last reported travel speed, else the default."""
        if mission.speed > 0:
            return mission.speed
        return mission.travel_speed if mission.travel_speed > 0 else DEFAULT_SPEED

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        vehicle_id = ctx.vehicle.vehicle_id if ctx.vehicle is not None else ""
        mission = self.missions.get(vehicle_id)
        if name == "ReportTravelSpeed":
            if mission is None:
                mission = self.missions[vehicle_id] = _Mission("", "", False, "", True, [], 0.0,
                                                               state="IDLE")
            mission.travel_speed = float(fields.get("speed", math.nan))
            return [self._status(vehicle_id, ctx)]
        if mission is None:
            return []
        if name in LIST_REPLIES:
            steps = self.lists.on_reply(vehicle_id, name, fields)
            if steps is None:
                return []
            load = self.lists.loads[vehicle_id]
            if load.state == "FAILED":
                mission.state = "FAILED"
                return [self._status(vehicle_id, ctx)]
            if load.state == "EXECUTING":
                # ExecuteList starts the driver at element 1. Its every-change
                # ReportActiveElement says so only if that is a change: a driver already
                # at element 1 of the list this one replaced sends nothing.
                mission.active, mission.state = 0, "EXECUTING"
            actions: list[Action] = list(steps)
            if mission.state != "PENDING":
                actions.append(self._status(vehicle_id, ctx))
            return actions
        if name == "ReportActiveElement" and mission.listed and mission.state != "FAILED":
            uid = int(fields.get("element_uid", 0))
            if 1 <= uid <= len(mission.waypoints):
                mission.active, mission.state = uid - 1, "EXECUTING"
            elif uid == 0 and mission.state == "EXECUTING":
                mission.active, mission.state = -1, "COMPLETED"
            return [self._status(vehicle_id, ctx)]
        return []

    def on_pose(self, name: str, fields: Mapping[str, Any],
                ctx: TranslatorContext) -> list[Action]:
        """Advance a single-waypoint mission when the vehicle reached its waypoint."""
        vehicle_id = ctx.vehicle.vehicle_id if ctx.vehicle is not None else ""
        mission = self.missions.get(vehicle_id)
        if (mission is None or mission.listed or mission.state != "EXECUTING"
                or mission.local != (name == "ReportLocalPose")):
            return []
        target = mission.waypoints[mission.active]
        sent = waypoint_fields(target, mission.local)  # where the vehicle was sent
        if _distance(sent, fields, mission.local) > (target.get("tolerance") or
                                                     DEFAULT_TOLERANCE):
            return []
        mission.active += 1
        if mission.active >= len(mission.waypoints):
            mission.active, mission.state = -1, "COMPLETED"
            return [self._status(vehicle_id, ctx)]
        return [self._waypoint(vehicle_id, mission.active), self._status(vehicle_id, ctx)]

    # -- steps ---------------------------------------------------------------------------

    def _load(self, mission: _Mission, vehicle_id: str, ctx: TranslatorContext) -> Command:
        """Start loading the plan into its list driver (the kit's list mechanism); the
        elements are encoded with the context's catalogue, so a profile's JSIDL applies.
        ExecuteList takes the speed when the list is complete (a travel speed reported
        meanwhile counts)."""
        def execute() -> dict[str, Any]:
            return {"speed": _clamp(self._speed(mission), 0.0, 327.67), "element_uid": 1}

        return self.lists.load(vehicle_id, vehicle_id, mission.operator_id,
                               DRIVERS[mission.service], mission.element,
                               mission.element_fields, ctx.catalogue, execute)

    def _waypoint(self, vehicle_id: str, index: int) -> Command:
        mission = self.missions[vehicle_id]
        name = "SetLocalWaypoint" if mission.local else "SetGlobalWaypoint"
        return Command(vehicle_id, mission.operator_id, "waypoint", name,
                       waypoint_fields(mission.waypoints[index], mission.local),
                       mission.service)

    def _status(self, vehicle_id: str, ctx: TranslatorContext) -> Publish:
        mission = self.missions[vehicle_id]
        return Publish("MissionStatus", {
            "vehicle_id": vehicle_id, "plan_id": mission.plan_id,
            "active_waypoint": mission.active, "state": mission.state,
            "travel_speed": mission.travel_speed, "timestamp_ms": ctx.timestamp_ms})


def _distance(target: Mapping[str, Any], pose: Mapping[str, Any], local: bool) -> float:
    """Horizontal metres from ``pose`` to ``target`` (inf when the pose lacks them)."""
    if local:
        if pose.get("x") is None or pose.get("y") is None:
            return math.inf
        return math.hypot(float(pose["x"]) - target.get("x", 0.0),
                          float(pose["y"]) - target.get("y", 0.0))
    if pose.get("latitude") is None or pose.get("longitude") is None:
        return math.inf
    lat = math.radians(float(pose["latitude"]))
    dlat = math.radians(target.get("latitude", 0.0)) - lat
    dlon = math.radians(target.get("longitude", 0.0) - float(pose["longitude"]))
    return _EARTH_RADIUS * math.hypot(dlat, dlon * math.cos(lat))


# -- plan read-back (List Manager reports, drivers' current target -> VehiclePlan) -------

#: element queries one component has outstanding at a time (the kit's list read-back)
PLAN_QUERIES_IN_FLIGHT = QUERIES_IN_FLIGHT
#: presence vectors asking for every field of Report{Global,Local}Waypoint and
#: Report{Global,Local}PathSegment
ALL_WAYPOINT = 0x3F
ALL_SEGMENT = 0x07
PLAN_MESSAGES = ("ReportElementList", "ReportElement", "ReportElementCount",
                 "ReportGlobalWaypoint", "ReportLocalWaypoint", "ReportGlobalPathSegment",
                 "ReportLocalPathSegment")
#: (report, query, driver, presence vector) of what a driver is going to
_CURRENT_TARGETS = (
    ("ReportGlobalWaypoint", "QueryGlobalWaypoint", GLOBAL_WAYPOINT_DRIVER, ALL_WAYPOINT),
    ("ReportLocalWaypoint", "QueryLocalWaypoint", LOCAL_WAYPOINT_DRIVER, ALL_WAYPOINT),
    ("ReportGlobalPathSegment", "QueryGlobalPathSegment", GLOBAL_SEGMENT_DRIVER, ALL_SEGMENT),
    ("ReportLocalPathSegment", "QueryLocalPathSegment", LOCAL_SEGMENT_DRIVER, ALL_SEGMENT),
)
PLAN_REPORTS = (
    *(driver.read_back() for driver in DRIVERS.values()),
    *(ReportSpec(report, query, service, {"presence_vector": pv}, rate=0.5, on_change=True)
      for report, query, service, pv in _CURRENT_TARGETS),
)
#: element message -> (PlanElement member, message field) pairs
_ELEMENT_MEMBERS: dict[str, tuple[tuple[str, str], ...]] = {
    "SetGlobalWaypoint": (("latitude", "latitude"), ("longitude", "longitude"),
                          ("altitude", "altitude"), ("tolerance", "waypoint_tolerance")),
    "SetLocalWaypoint": (("x", "x"), ("y", "y"), ("z", "z"),
                         ("tolerance", "waypoint_tolerance")),
    "SetGlobalPathSegment": (
        ("latitude", "p2_latitude"), ("longitude", "p2_longitude"),
        ("altitude", "p2_altitude"), ("control_latitude", "p1_latitude"),
        ("control_longitude", "p1_longitude"), ("control_altitude", "p1_altitude"),
        ("weighting_factor", "weighting_factor"), ("tolerance", "path_tolerance")),
    "SetLocalPathSegment": (
        ("x", "p2_x"), ("y", "p2_y"), ("z", "p2_z"), ("control_x", "p1_x"),
        ("control_y", "p1_y"), ("control_z", "p1_z"),
        ("weighting_factor", "weighting_factor"), ("tolerance", "path_tolerance")),
}
#: the numeric members of a PlanElement (NaN unless the element's message sets them)
_PLAN_NUMBERS = tuple(dict.fromkeys(m for pairs in _ELEMENT_MEMBERS.values() for m, _ in pairs))
#: a driver's report of its current target reads like the Set message of an element
_ELEMENT_MEMBERS["ReportGlobalWaypoint"] = _ELEMENT_MEMBERS["SetGlobalWaypoint"]
_ELEMENT_MEMBERS["ReportLocalWaypoint"] = _ELEMENT_MEMBERS["SetLocalWaypoint"]
_ELEMENT_MEMBERS["ReportGlobalPathSegment"] = _ELEMENT_MEMBERS["SetGlobalPathSegment"]
_ELEMENT_MEMBERS["ReportLocalPathSegment"] = _ELEMENT_MEMBERS["SetLocalPathSegment"]


def plan_element(message: str, fields: Mapping[str, Any], uid: int = 0, previous: int = 0,
                 following: int = 0) -> dict[str, Any]:
    """A ``PlanElement`` of a waypoint or path segment message's fields (NaN where the
    message left a member out; ``message`` renamed to the Set message it stands for)."""
    members = _ELEMENT_MEMBERS.get(message, ())
    element: dict[str, Any] = {"uid": uid, "previous_uid": previous, "next_uid": following,
                               "message": message.replace("Report", "Set", 1),
                               **dict.fromkeys(_PLAN_NUMBERS, NAN)}
    for member, jaus in members:
        element[member] = number(fields.get(jaus))
    return element


def _held_element(message: str, fields: Mapping[str, Any], uid: int, previous: int,
                  following: int) -> dict[str, Any]:
    """A list element read back: a ``PlanElement`` named after its decoded message."""
    element = plan_element(message, fields, uid, previous, following)
    element["message"] = message
    return element


def _vehicle_plan(vehicle_id: str, component: JausAddress, held: HeldList,
                  ctx: TranslatorContext) -> Publish:
    """``VehiclePlan``: the plan one component holds, as read back so far."""
    return Publish("VehiclePlan", {
        "vehicle_id": vehicle_id, "component": str(component), "element_count": held.count,
        "elements": held.listed(), "complete": held.complete(),
        "current": held.current or plan_element("", {}), "timestamp_ms": ctx.timestamp_ms})


def plan_read_back() -> ListReadBack:
    """The plan each component of a vehicle holds, read back from it -> ``VehiclePlan``.

    The engine keeps ReportElementList flowing from every waypoint list and path segment
    driver (an every-change event, or polling) and, likewise, each waypoint and path
    segment driver's report of its current target. A list that changed is read element by
    element with QueryElement, at most :data:`PLAN_QUERIES_IN_FLIGHT` at a time per
    component; an element the list no longer holds is dropped. After the relay's own
    plan was confirmed, and when an operator asks (``PlanQuery``), every element is read
    again, so an element replaced under the same UID is seen too. The kit's list
    read-back (:class:`~edge_vis.kit.lists.ListReadBack`) does the reading.
    """
    return ListReadBack(tuple(DRIVERS.values()), _held_element, _vehicle_plan)


class MobilityTranslator(RuleTranslator):
    """Mobility service set (AS6009) <-> pose, velocity, driver and mission topics.

    The rule tables (:data:`REPORT_RULES`, :data:`COMMAND_RULES`) declare the plain
    mappings; waypoint missions (:class:`WaypointMissions`) keep per-vehicle state and are
    hooked into :meth:`on_message` / :meth:`on_sample` around them.
    """

    name = "mobility"
    options_type = MobilityOptions
    report_rules = REPORT_RULES
    command_rules = COMMAND_RULES
    extra_messages = (*MISSION_MESSAGES, *PLAN_MESSAGES)
    extra_publishes = ("MissionStatus", "VehiclePlan")

    @classmethod
    def _derive(cls) -> None:
        super()._derive()
        cls.reports = (*(s for s in cls.reports if s.report not in OPTIONAL_REPORTS),
                       *MISSION_REPORTS, *PLAN_REPORTS)
        cls.subscribes = (*cls.subscribes, "WaypointPlan", "PathSegmentPlan", "PlanQuery")
        # the List Manager's messages from its list drivers only, and mobility's
        # ReportActiveElement (the manipulator's list drivers have their own, 0x461E)
        cls.bindings = {**cls.bindings, **list_bindings(tuple(DRIVERS.values()))}
        # Holding a vehicle means holding every component that can move it, waypoint
        # list drivers included, so nothing else drives it meanwhile.
        cls.controlled_services = tuple(dict.fromkeys((
            *cls.controlled_services, LOCAL_LIST_DRIVER, GLOBAL_LIST_DRIVER,
            LOCAL_WAYPOINT_DRIVER, GLOBAL_WAYPOINT_DRIVER, GLOBAL_SEGMENT_DRIVER,
            LOCAL_SEGMENT_DRIVER)))

    def __init__(self) -> None:
        super().__init__()
        self.missions = WaypointMissions()
        self.plans = plan_read_back()

    def apply_options(self, options: MobilityOptions) -> None:
        """Ask for the optional reports the profile lists, too."""
        wanted = options.extra_reports
        chosen = set(OPTIONAL_REPORTS) if "*" in wanted else set(wanted)
        # instance attribute: this deployment's choice
        self.reports = (*type(self).reports, *(  # type: ignore[misc]
            ReportSpec(r.message, r.query, r.service, dict(r.query_fields), r.rate, r.on_change)
            for r in self.report_rules if r.message in chosen))

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if ctx.vehicle is None:
            return []
        if name in LIST_REPORTS:
            return self.plans.on_report(name, fields, ctx)
        if name in PLAN_MESSAGES:  # a driver's current target
            return self.plans.on_current(plan_element(name, fields), ctx)
        if name in MISSION_MESSAGES:
            actions = self.missions.on_message(name, fields, ctx)
            if ctx.source is not None and any(
                    isinstance(a, Command) and a.name == "ExecuteList" for a in actions):
                # the relay's plan is complete on the vehicle: read all of it back
                actions += self.plans.refresh(ctx.vehicle.vehicle_id, ctx.source)
            return actions
        actions = super().on_message(name, fields, ctx)
        if name in ("ReportGlobalPose", "ReportLocalPose"):
            actions.extend(self.missions.on_pose(name, fields, ctx))
        return actions

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if topic == "WaypointPlan":
            return self.missions.on_plan(sample, ctx)
        if topic == "PathSegmentPlan":
            return self.missions.on_segments(sample, ctx)
        if topic == "PlanQuery":
            return self.plans.on_query(sample, ctx)
        return super().on_sample(topic, sample, ctx)

    def command(self, rule: Cmd, sample: Mapping[str, Any]) -> Command | None:
        """As the rule says, except that a sample setting nothing (every optional member
        absent) gives no command: the vehicle would be told nothing."""
        puts = [spec for spec in rule.fields.values() if isinstance(spec, Put)]
        if puts and all(p.optional for p in puts) and not any(
                _is_set(sample.get(p.dds)) for p in puts):
            return None
        return super().command(rule, sample)

    def describe(self) -> list[dict[str, Any]]:
        """Mapping-table rows (``edge-vis mappings``): the rule tables, then missions."""
        rows = super().describe()
        row = _row
        plan = [("latitude/longitude/altitude | x/y/z", "waypoints[]", "element data"),
                ("waypoint_tolerance", "waypoints[].tolerance", "when > 0")]
        for name, note in (
                ("DeleteElement", "every element (UID 65535) before a new plan"),
                ("SetElement", f"<= {ELEMENTS_PER_SET} waypoints each, linked previous/next"),
                ("SetGlobalWaypoint", "list element data, or sent alone to a waypoint driver"),
                ("SetLocalWaypoint", "frame LOCAL"),
                ("SetTravelSpeed", "before the first waypoint, for waypoint drivers"),
                ("ExecuteList", "speed; after the last ConfirmElementRequest")):
            fields = {"ExecuteList": [("speed", "speed", "0 = last travel speed"),
                                      ("element_uid", "= 1", "the first waypoint")],
                      "SetTravelSpeed": [("speed", "speed", "0 = last travel speed")],
                      "DeleteElement": [("delete_element_list[].element_uid", "= 65535",
                                         "")],
                      "SetElement": [("element_list[].element_data", "waypoints[]",
                                      "Set*Waypoint message, UIDs 1..n")],
                      }.get(name, plan)
            rows.append(row("dds->jaus", name, "WaypointPlan", fields, doc=note))
        for name, fields in (
                ("ReportActiveElement", [("element_uid", "active_waypoint", "uid - 1"),
                                         ("element_uid", "state", "0 after executing = "
                                                                  "COMPLETED")]),
                ("ReportTravelSpeed", [("speed", "travel_speed", "m/s")]),
                ("ConfirmElementRequest", [("request_id", "state", "next step")]),
                ("RejectElementRequest", [("response_code", "state", "FAILED")])):
            query = {"ReportActiveElement": "QueryActiveElement",
                     "ReportTravelSpeed": "QueryTravelSpeed"}.get(name, "")
            rows.append(row("jaus->dds", name, "MissionStatus", fields, query))
        segment = [("p2_* (latitude/longitude/altitude | x/y/z)", "segments[]", "end point"),
                   ("p1_*", "segments[].control_*", "control point"),
                   ("weighting_factor", "segments[].weighting_factor", "0 = straight"),
                   ("path_tolerance", "segments[].tolerance", "when > 0")]
        for name, note in (("SetGlobalPathSegment", "list element data, frame GLOBAL"),
                           ("SetLocalPathSegment", "list element data, frame LOCAL")):
            rows.append(row("dds->jaus", name, "PathSegmentPlan", segment,
                            doc=f"{note}; DeleteElement, SetElement, ExecuteList as for "
                                "WaypointPlan, to the path segment driver"))
        rows.append(row("dds->jaus", "QueryElementCount", "PlanQuery",
                        [("(none)", "vehicle_id", "every list driver")],
                        doc="with QueryElementList: read the plan back now (the holder)"))
        rows.append(row("dds->jaus", "QueryElementList", "PlanQuery",
                        [("(none)", "vehicle_id", "every list driver")],
                        doc="every element is read again"))
        element = [("element_uid / previous_uid / next_uid", "elements[].uid / previous_uid"
                    " / next_uid", ""),
                   ("element_data (Set*Waypoint | Set*PathSegment)", "elements[].message, "
                    "position, control_*, weighting_factor, tolerance", "decoded")]
        target = [("latitude/longitude/altitude | x/y/z | p2_*", "current.*", "NaN if absent"),
                  ("p1_*, weighting_factor", "current.control_*, weighting_factor", ""),
                  ("waypoint_tolerance | path_tolerance", "current.tolerance", "")]
        for name, fields, query, doc in (
                ("ReportElementList", [("element_list[].element_uid", "elements (order), "
                                        "element_count", "")], "QueryElementList",
                 "every-change event; a changed list is read with QueryElement, "
                 f"{PLAN_QUERIES_IN_FLIGHT} at a time"),
                ("ReportElement", element, "QueryElement", "asked for each listed element"),
                ("ReportElementCount", [("element_count", "element_count",
                                         "a different count re-reads the list")],
                 "QueryElementCount", "asked for on PlanQuery"),
                *((report, target, query, "the driver's current target; every-change event")
                  for report, query, _, _ in _CURRENT_TARGETS)):
            rows.append(row("jaus->dds", name, "VehiclePlan", fields, query, doc))
        return rows


def _is_set(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def _row(direction: str, message: str, topic: str, fields: list[tuple[str, str, str]],
         query: str = "", doc: str = "") -> dict[str, Any]:
    return {"translator": "mobility", "direction": direction, "message": message,
            "topic": topic, "query": query, "service": "", "rate": None,
            "fields": [{"jaus": j, "dds": d, "note": n} for j, d, n in fields], "doc": doc}
