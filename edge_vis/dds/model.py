"""The edge-vis data model: one DDS topic type per kind of vehicle data. No I/O.

The model follows the UCS-MDE style: one topic per data type, every vehicle-related topic
keyed by ``vehicle_id`` (the name the vehicle profile gives it), so a DDS reader keeps one
instance per vehicle. The same model ships as IDL in ``edge_vis/data/edge_vis.idl`` for
operator stations written in C, C++ or Java; a test checks that the two agree.

Conventions, shared by every type:

* Angles are radians, positions metres, speeds metres per second, latitude and longitude
  WGS 84 degrees. ``timestamp_ms`` is milliseconds since the Unix epoch (UTC) of the
  measurement, or 0 when the vehicle did not report one.
* A ``double`` that the vehicle did not report is NaN; an ``@optional`` member that is
  absent means "do not change" in commands.
* Enumerations are carried as IDL enums; as dict values (see :mod:`edge_vis.dds.convert`)
  they are their literal names (``"READY"``). IDL scopes enumerators at module level, so
  some carry a prefix (``"MISSION_EXECUTING"``); dicts may leave it out (``"EXECUTING"``).

Members without a default must be present in a sample dict; members with one may be
omitted.

This module deliberately omits ``from __future__ import annotations``: cyclonedds builds
its serialisers from the evaluated annotations and cannot resolve postponed ones.
"""

import math
from dataclasses import dataclass, field
from typing import Optional

from cyclonedds.idl import IdlEnum, IdlStruct
from cyclonedds.idl.annotations import key
from cyclonedds.idl.types import float64, int32, int64, sequence, uint8, uint16, uint32, uint64

NAN = math.nan

# --------------------------------------------------------------------------- enumerations


class VehicleState(IdlEnum, typename="edge_vis::VehicleState"):
    """Operational state of a vehicle: the JAUS Management states, UNKNOWN before the first
    status report, OFFLINE once the relay has lost it."""

    UNKNOWN = 0
    INITIALIZE = 1
    READY = 2
    STANDBY = 3
    SHUTDOWN = 4
    FAILURE = 5
    EMERGENCY = 6
    OFFLINE = 7


class ControlState(IdlEnum, typename="edge_vis::ControlState"):
    """Where the relay stands in JAUS access control of a vehicle."""

    NOT_CONTROLLED = 0
    REQUESTED = 1
    CONTROLLED = 2
    REJECTED = 3
    RELEASING = 4


class ControlAction(IdlEnum, typename="edge_vis::ControlAction"):
    """What an operator asks for in a :class:`ControlRequest`."""

    REQUEST = 0
    RELEASE = 1


class EmergencyAction(IdlEnum, typename="edge_vis::EmergencyAction"):
    """What an operator asks for in an :class:`EmergencyCommand`."""

    SET = 0
    CLEAR = 1


class ManagementCommandType(IdlEnum, typename="edge_vis::ManagementCommandType"):
    """A JAUS Management command (prefixed: IDL enumerators share the module's scope;
    dicts may leave the prefix out, ``"STANDBY"``)."""

    MGMT_SHUTDOWN = 0
    MGMT_STANDBY = 1
    MGMT_RESUME = 2
    MGMT_RESET = 3


class Frame(IdlEnum, typename="edge_vis::Frame"):
    """Reference frame of waypoints: WGS 84 (GLOBAL) or the vehicle's local frame (LOCAL)."""

    GLOBAL = 0
    LOCAL = 1


class MissionState(IdlEnum, typename="edge_vis::MissionState"):
    """Execution state of a waypoint plan."""

    MISSION_IDLE = 0
    MISSION_PENDING = 1
    MISSION_EXECUTING = 2
    MISSION_PAUSED = 3
    MISSION_COMPLETED = 4
    MISSION_ABORTED = 5
    MISSION_FAILED = 6


class SpoolerAction(IdlEnum, typename="edge_vis::SpoolerAction"):
    """What a :class:`MissionSpoolCommand` asks a vehicle's Mission Spooler to do
    (prefixed; dicts may leave the prefix out, ``"RUN"``)."""

    SPOOLER_SPOOL = 0
    SPOOLER_RUN = 1
    SPOOLER_PAUSE = 2
    SPOOLER_RESUME = 3
    SPOOLER_ABORT = 4
    SPOOLER_INSERT_MESSAGES = 5
    SPOOLER_REMOVE_MESSAGES = 6
    SPOOLER_INSERT_TASK = 7
    SPOOLER_REMOVE_TASK = 8
    SPOOLER_QUERY_PLAN = 9


class HealthLevel(IdlEnum, typename="edge_vis::HealthLevel"):
    """Summary health of a vehicle."""

    HEALTH_UNKNOWN = 0
    HEALTH_OK = 1
    HEALTH_WARNING = 2
    HEALTH_FAULT = 3
    HEALTH_CRITICAL = 4


class TransferState(IdlEnum, typename="edge_vis::TransferState"):
    """State of a bulk (image) transfer."""

    TRANSFER_PENDING = 0
    TRANSFER_ACTIVE = 1
    TRANSFER_PAUSED = 2
    TRANSFER_COMPLETE = 3
    TRANSFER_FAILED = 4
    TRANSFER_CANCELLED = 5


# --------------------------------------------------------------------------- nested structs


@dataclass
class ServiceInfo(IdlStruct, typename="edge_vis::ServiceInfo"):
    """One JAUS service a vehicle reports (``urn:jaus:jss:core:AccessControl``, ``"1.1"``)."""

    uri: str
    version: str = ""


@dataclass
class Waypoint(IdlStruct, typename="edge_vis::Waypoint"):
    """A waypoint: latitude/longitude/altitude for GLOBAL plans, x/y/z for LOCAL plans."""

    latitude: float64 = 0.0
    longitude: float64 = 0.0
    altitude: float64 = 0.0
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    tolerance: float64 = 0.0


@dataclass
class ClassCount(IdlStruct, typename="edge_vis::ClassCount"):
    """A counter for one traffic class of a link (``command``, ``telemetry``, ``bulk`` ...)."""

    traffic_class: str
    count: uint64 = 0


@dataclass
class RangePoint(IdlStruct, typename="edge_vis::RangePoint"):
    """One range return in the sensor frame: range (m), bearing and inclination (rad)."""

    range: float64
    bearing: float64
    inclination: float64 = 0.0


@dataclass
class AtrTarget(IdlStruct, typename="edge_vis::AtrTarget"):
    """One automatic-target-recognition detection in an image."""

    target_class: str
    confidence: float64
    latitude: float64 = NAN
    longitude: float64 = NAN
    depth: float64 = NAN


# --------------------------------------------------------------------------- identity and state


@dataclass
class VehicleIdentification(IdlStruct, typename="edge_vis::VehicleIdentification"):
    """Who a vehicle is and which JAUS services it offers."""

    vehicle_id: str
    key("vehicle_id")
    name: str = ""
    jaus_address: str = ""
    jaus_subsystem: uint16 = 0
    vehicle_type: str = ""
    services: sequence[ServiceInfo] = field(default_factory=list)


@dataclass
class VehicleStatus(IdlStruct, typename="edge_vis::VehicleStatus"):
    """Operational state and liveness of a vehicle as the relay sees it."""

    vehicle_id: str
    key("vehicle_id")
    state: VehicleState = VehicleState.UNKNOWN
    link: str = ""
    online: bool = False
    last_seen_ms: int64 = 0
    #: an emergency stop is in force (set through the relay or reported by the vehicle)
    emergency: bool = False
    #: the operator who set it through the relay ("" when set by another JAUS client)
    emergency_operator: str = ""
    emergency_reason: str = ""
    #: the relay serving the vehicle (its ``RelayStatus.relay``)
    relay: str = ""


@dataclass
class ComponentHolder(IdlStruct, typename="edge_vis::ComponentHolder"):
    """Who controls one component (JAUS address ``S.N.C``; ``controller`` empty: nobody)."""

    component: str = ""
    controller: str = ""
    authority: uint8 = 0
    current_authority: uint8 = 0
    is_relay: bool = False


@dataclass
class ControlStatus(IdlStruct, typename="edge_vis::ControlStatus"):
    """JAUS access control of a vehicle: which operator holds it through the relay, and
    who controls each of its components (whether or not through this relay)."""

    vehicle_id: str
    key("vehicle_id")
    state: ControlState = ControlState.NOT_CONTROLLED
    operator_id: str = ""
    authority: uint8 = 0
    rejected_commands: uint32 = 0
    last_rejection: str = ""
    timestamp_ms: int64 = 0
    #: an emergency stop is in force: no motion command is sent
    emergency: bool = False
    holders: sequence[ComponentHolder] = field(default_factory=list)


@dataclass
class VehicleClock(IdlStruct, typename="edge_vis::VehicleClock"):
    """A vehicle's clock against the relay's (JAUS Time): ``offset_ms`` = vehicle minus
    relay, measured over a round trip of ``round_trip_ms``."""

    vehicle_id: str
    key("vehicle_id")
    component: str = ""
    offset_ms: float64 = NAN
    round_trip_ms: float64 = NAN
    set_time_sent: uint32 = 0
    note: str = ""
    timestamp_ms: int64 = 0


@dataclass
class MissionStatus(IdlStruct, typename="edge_vis::MissionStatus"):
    """Progress of the active waypoint plan; ``active_waypoint`` is -1 when none."""

    vehicle_id: str
    key("vehicle_id")
    plan_id: str = ""
    active_waypoint: int32 = -1
    state: MissionState = MissionState.MISSION_IDLE
    travel_speed: float64 = 0.0
    timestamp_ms: int64 = 0


@dataclass
class LinkStatus(IdlStruct, typename="edge_vis::LinkStatus"):
    """Load of one radio link of one relay; ``vehicle_id`` is empty for a link shared by
    many vehicles."""

    link: str
    key("link")
    vehicle_id: str = ""
    key("vehicle_id")
    relay: str = ""
    key("relay")
    up: bool = False
    budget_bps: float64 = 0.0
    measured_bps: float64 = 0.0
    queue_depth: uint32 = 0
    drops: sequence[ClassCount] = field(default_factory=list)
    bytes_in: uint64 = 0
    bytes_out: uint64 = 0
    messages_in: uint64 = 0
    messages_out: uint64 = 0
    timestamp_ms: int64 = 0


# -- relays sharing a domain (edge_vis.engine.duty) ---------------------------------------


@dataclass
class RelayLink(IdlStruct, typename="edge_vis::RelayLink"):
    """One link of a relay and whether it is open."""

    link: str = ""
    up: bool = False


@dataclass
class RelayVehicle(IdlStruct, typename="edge_vis::RelayVehicle"):
    """A vehicle a relay reaches: over which link, how well (``quality`` 0..1, the share of
    liveness periods it was heard in; ``score`` adds the profile preference), whether this
    relay serves it and, if so, for which operator it holds it."""

    vehicle_id: str = ""
    link: str = ""
    quality: float64 = 0.0
    score: float64 = 0.0
    serving: bool = False
    operator_id: str = ""
    authority: uint8 = 0


@dataclass
class RelayStatus(IdlStruct, typename="edge_vis::RelayStatus"):
    """One relay on the domain: its links and the vehicles it reaches and serves, every
    ``heartbeat_ms``; ``leaving`` when it stops. Relays decide from these which one
    serves each vehicle."""

    relay: str
    key("relay")
    jaus_id: str = ""
    links: sequence[RelayLink] = field(default_factory=list)
    vehicles: sequence[RelayVehicle] = field(default_factory=list)
    leaving: bool = False
    heartbeat_ms: uint32 = 0
    timestamp_ms: int64 = 0


@dataclass
class HealthStatus(IdlStruct, typename="edge_vis::HealthStatus"):
    """Summary health: level, battery (percent) and supply voltage (V), active faults."""

    vehicle_id: str
    key("vehicle_id")
    level: HealthLevel = HealthLevel.HEALTH_UNKNOWN
    battery_percent: float64 = NAN
    supply_voltage: float64 = NAN
    faults: sequence[str] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class SensorInfo(IdlStruct, typename="edge_vis::SensorInfo"):
    """Static description of one sensor: ranges (m), fields of view (rad), rate (Hz)."""

    vehicle_id: str
    key("vehicle_id")
    sensor_id: uint16
    key("sensor_id")
    name: str = ""
    kind: str = ""
    min_range: float64 = 0.0
    max_range: float64 = 0.0
    horizontal_fov: float64 = 0.0
    vertical_fov: float64 = 0.0
    update_rate_hz: float64 = 0.0
    # mounting (ReportSensorGeometricProperties): position (m) and orientation (unit
    # quaternion w, x, y, z) in the vehicle frame, or on a manipulator joint (mounted_on)
    mount_x: float64 = NAN
    mount_y: float64 = NAN
    mount_z: float64 = NAN
    mount_qw: float64 = NAN
    mount_qx: float64 = NAN
    mount_qy: float64 = NAN
    mount_qz: float64 = NAN
    mounted_on: str = ""


@dataclass
class SensorState(IdlStruct, typename="edge_vis::SensorState"):
    """What a sensor of one ``kind`` (visual, digital_video, analog_video, still_image,
    range) is set to: its configuration as ``name=value`` pairs (JAUS field names and
    values), the answer to the last configuration sent, and the video stream state last
    asked for through the relay (JAUS reports no stream state)."""

    vehicle_id: str
    key("vehicle_id")
    sensor_id: uint16
    key("sensor_id")
    kind: str
    key("kind")
    configuration: str = ""
    confirmation: str = ""
    stream: str = ""
    timestamp_ms: int64 = 0


@dataclass
class SensorCommand(IdlStruct, typename="edge_vis::SensorCommand"):
    """An operator's order to one sensor: ``action`` configure (``kind`` visual,
    digital_video, analog_video, still_image or range; ``settings`` as ``name=value``
    pairs of the JAUS Set...SensorConfiguration fields), play / pause / stop (the digital
    video stream) or capture (one still image now)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    sensor_id: uint16
    action: str
    kind: str = ""
    settings: str = ""


@dataclass
class HmiInput(IdlStruct, typename="edge_vis::HmiInput"):
    """An input device of an operator interface on the vehicle's JAUS network (a hand-held
    controller, a panel): ``device`` is ``keyboard``, ``pointer``, ``dcm_<ref>`` (a
    digital control) or ``analog_<ref>`` (a joystick; axes -1..1 of full deflection);
    ``state`` the last action (``PRESSED``, ``LEFT DOWN``...), ``code`` the key or
    control, ``x``/``y`` the pointer position (viewport pixels)."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    name: str = ""
    state: str = ""
    code: int32 = 0
    x: float64 = NAN
    y: float64 = NAN
    z: float64 = NAN
    roll: float64 = NAN
    pitch: float64 = NAN
    yaw: float64 = NAN
    valid: bool = True
    timestamp_ms: int64 = 0


@dataclass
class TransferStatus(IdlStruct, typename="edge_vis::TransferStatus"):
    """Progress of one bulk transfer; ``rate_bps`` is bits per second."""

    vehicle_id: str
    key("vehicle_id")
    transfer_id: str
    key("transfer_id")
    image_id: str = ""
    state: TransferState = TransferState.TRANSFER_PENDING
    bytes_done: uint64 = 0
    bytes_total: uint64 = 0
    rate_bps: float64 = 0.0
    error: str = ""
    timestamp_ms: int64 = 0


# --------------------------------------------------------------------------- telemetry


@dataclass
class GlobalPose(IdlStruct, typename="edge_vis::GlobalPose"):
    """WGS 84 position (deg, m above the ellipsoid) and attitude (rad)."""

    vehicle_id: str
    key("vehicle_id")
    latitude: float64
    longitude: float64
    altitude: float64
    roll: float64
    pitch: float64
    yaw: float64
    timestamp_ms: int64


@dataclass
class LocalPose(IdlStruct, typename="edge_vis::LocalPose"):
    """Position (m) and attitude (rad) in the vehicle's local frame."""

    vehicle_id: str
    key("vehicle_id")
    x: float64
    y: float64
    z: float64
    roll: float64
    pitch: float64
    yaw: float64
    timestamp_ms: int64


@dataclass
class Velocity(IdlStruct, typename="edge_vis::Velocity"):
    """Linear (m/s) and angular (rad/s) velocity in the vehicle frame."""

    vehicle_id: str
    key("vehicle_id")
    vx: float64
    vy: float64
    vz: float64
    roll_rate: float64
    pitch_rate: float64
    yaw_rate: float64
    timestamp_ms: int64


@dataclass
class RangeScan(IdlStruct, typename="edge_vis::RangeScan"):
    """One scan of a range sensor (laser, sonar)."""

    vehicle_id: str
    key("vehicle_id")
    sensor_id: uint16
    key("sensor_id")
    points: sequence[RangePoint]
    timestamp_ms: int64 = 0


@dataclass
class EnvironmentalData(IdlStruct, typename="edge_vis::EnvironmentalData"):
    """Water temperature (deg C), salinity (PSU), depth (m), current speed (m/s) and set (rad)."""

    vehicle_id: str
    key("vehicle_id")
    water_temperature: float64 = NAN
    salinity: float64 = NAN
    depth: float64 = NAN
    current_speed: float64 = NAN
    current_direction: float64 = NAN
    timestamp_ms: int64 = 0


# --------------------------------------------------------------------------- commands


@dataclass
class ControlRequest(IdlStruct, typename="edge_vis::ControlRequest"):
    """An operator asks the relay to take (REQUEST) or give up (RELEASE) control of a vehicle."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    action: ControlAction
    authority: uint8 = 0


@dataclass
class EmergencyCommand(IdlStruct, typename="edge_vis::EmergencyCommand"):
    """An operator sets (SET) or clears (CLEAR) a vehicle's emergency stop; no control is
    needed. ``authority`` is checked against the operator's maximum and, for CLEAR,
    against the setter's (profile ``[emergency]``)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    action: EmergencyAction
    authority: uint8 = 0
    reason: str = ""


@dataclass
class ManagementCommand(IdlStruct, typename="edge_vis::ManagementCommand"):
    """Shutdown, Standby, Resume or Reset a vehicle (every Management component, or the
    one ``component`` names as ``S.N.C``); needs the operator to hold the vehicle."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    command: ManagementCommandType
    component: str = ""


@dataclass
class WrenchEffortCommand(IdlStruct, typename="edge_vis::WrenchEffortCommand"):
    """Open-loop effort in percent: propulsive -100..100, resistive 0..100; absent = unchanged."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    propulsive_linear_x: Optional[float64] = None  # noqa: UP045 (cyclonedds needs Optional)
    propulsive_linear_y: Optional[float64] = None  # noqa: UP045
    propulsive_linear_z: Optional[float64] = None  # noqa: UP045
    propulsive_rotational_x: Optional[float64] = None  # noqa: UP045
    propulsive_rotational_y: Optional[float64] = None  # noqa: UP045
    propulsive_rotational_z: Optional[float64] = None  # noqa: UP045
    resistive_linear_x: Optional[float64] = None  # noqa: UP045
    resistive_linear_y: Optional[float64] = None  # noqa: UP045
    resistive_linear_z: Optional[float64] = None  # noqa: UP045
    resistive_rotational_x: Optional[float64] = None  # noqa: UP045
    resistive_rotational_y: Optional[float64] = None  # noqa: UP045
    resistive_rotational_z: Optional[float64] = None  # noqa: UP045


@dataclass
class VelocityCommand(IdlStruct, typename="edge_vis::VelocityCommand"):
    """Commanded linear (m/s) and angular (rad/s) velocity in the vehicle frame."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    vx: float64 = 0.0
    vy: float64 = 0.0
    vz: float64 = 0.0
    roll_rate: float64 = 0.0
    pitch_rate: float64 = 0.0
    yaw_rate: float64 = 0.0


@dataclass
class WaypointPlan(IdlStruct, typename="edge_vis::WaypointPlan"):
    """A list of waypoints to drive in order at ``speed`` m/s (0 = the vehicle's default)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    plan_id: str
    waypoints: sequence[Waypoint]
    frame: Frame = Frame.GLOBAL
    speed: float64 = 0.0


# -- plan read-back, path segments, mission spooler ----------------------------------------


@dataclass
class PlanElement(IdlStruct, typename="edge_vis::PlanElement"):
    """One element a vehicle holds: a waypoint, or a path segment ending at the position
    with ``control_*`` its control point (P1) and ``weighting_factor`` (0 = straight).
    ``message`` names the JAUS message the element carries (``SetGlobalWaypoint``...;
    ``""`` when it is not one the relay knows). Unset members are NaN."""

    uid: uint16 = 0
    previous_uid: uint16 = 0
    next_uid: uint16 = 0
    message: str = ""
    latitude: float64 = NAN
    longitude: float64 = NAN
    altitude: float64 = NAN
    x: float64 = NAN
    y: float64 = NAN
    z: float64 = NAN
    tolerance: float64 = NAN
    control_latitude: float64 = NAN
    control_longitude: float64 = NAN
    control_altitude: float64 = NAN
    control_x: float64 = NAN
    control_y: float64 = NAN
    control_z: float64 = NAN
    weighting_factor: float64 = NAN


@dataclass
class VehiclePlan(IdlStruct, typename="edge_vis::VehiclePlan"):
    """The plan one component of a vehicle actually holds, read back from it: its List
    Manager's elements in list order (``complete`` once every listed element was read),
    and ``current``, the waypoint or path segment its driver reports it is going to."""

    vehicle_id: str
    key("vehicle_id")
    component: str
    key("component")
    element_count: int32 = -1
    elements: sequence[PlanElement] = field(default_factory=list)
    complete: bool = False
    current: PlanElement = field(default_factory=PlanElement)
    timestamp_ms: int64 = 0


@dataclass
class PlanQuery(IdlStruct, typename="edge_vis::PlanQuery"):
    """Read the plan of a vehicle again now (the operator holding it)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str


@dataclass
class PathSegment(IdlStruct, typename="edge_vis::PathSegment"):
    """A path segment ending at latitude/longitude/altitude (GLOBAL) or x/y/z (LOCAL),
    bent towards its control point by ``weighting_factor`` (0 = a straight line)."""

    latitude: float64 = 0.0
    longitude: float64 = 0.0
    altitude: float64 = 0.0
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    control_latitude: float64 = 0.0
    control_longitude: float64 = 0.0
    control_altitude: float64 = 0.0
    control_x: float64 = 0.0
    control_y: float64 = 0.0
    control_z: float64 = 0.0
    weighting_factor: float64 = 0.0
    tolerance: float64 = 0.0


@dataclass
class PathSegmentPlan(IdlStruct, typename="edge_vis::PathSegmentPlan"):
    """Path segments to drive in order at ``speed`` m/s (0 = the vehicle's default)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    plan_id: str
    segments: sequence[PathSegment]
    frame: Frame = Frame.GLOBAL
    speed: float64 = 0.0


@dataclass
class MissionMessage(IdlStruct, typename="edge_vis::MissionMessage"):
    """One JAUS message of a spooled mission task: ``message`` by name with its fields as
    a JSON object (``fields_json``), for component ``destination`` (``S.N.C``; empty:
    the spooler's own subsystem, node and component 1). ``blocking``: the spooler waits for
    it to finish before the next one."""

    uid: uint16
    message: str
    fields_json: str = "{}"
    destination: str = ""
    blocking: bool = False


@dataclass
class MissionTask(IdlStruct, typename="edge_vis::MissionTask"):
    """A task of a spooled mission: its messages, and its sub-tasks as indices into the
    mission's task list."""

    task_id: uint16
    messages: sequence[MissionMessage] = field(default_factory=list)
    child_tasks: sequence[uint16] = field(default_factory=list)


@dataclass
class MissionSpoolCommand(IdlStruct, typename="edge_vis::MissionSpoolCommand"):
    """An operator's order to a vehicle's Mission Spooler (see :class:`SpoolerAction`):
    SPOOL sends ``tasks`` as mission ``mission_id``; RUN, PAUSE, RESUME, ABORT act on it
    (``task_id``/``message_uid`` narrow RUN and PAUSE when non-zero); INSERT_MESSAGES puts
    the first task's messages before or after (``after``) ``message_uid`` of ``task_id``;
    REMOVE_MESSAGES removes ``uids`` from ``task_id``; INSERT_TASK puts the first task
    before or after ``task_id`` under ``parent_task_id``; REMOVE_TASK removes ``uids``
    (task IDs) under ``task_id``; QUERY_PLAN reads the stored plan of ``mission_id``."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    action: SpoolerAction
    mission_id: uint16 = 0
    task_id: uint16 = 0
    message_uid: uint16 = 0
    after: bool = False
    parent_task_id: uint16 = 0
    tasks: sequence[MissionTask] = field(default_factory=list)
    uids: sequence[uint16] = field(default_factory=list)


@dataclass
class SpoolerStatus(IdlStruct, typename="edge_vis::SpoolerStatus"):
    """What a vehicle's Mission Spooler says of a mission, task or message (``scope``
    MISSION, TASK or MESSAGE, ``id`` its ID): ``status`` INIT, RUNNING, PAUSING, PAUSED,
    ABORTING, ABORTED, BLOCKED or FINISHED; ``detail`` the secondary status."""

    vehicle_id: str
    key("vehicle_id")
    scope: str
    key("scope")
    id: uint16 = 0
    status: str = ""
    detail: str = ""
    timestamp_ms: int64 = 0


@dataclass
class StoredMission(IdlStruct, typename="edge_vis::StoredMission"):
    """A mission a spooler holds and the JAUS address (``S.N.C``) of who spooled it."""

    mission_id: uint16
    creator: str = ""


@dataclass
class SpoolerMissions(IdlStruct, typename="edge_vis::SpoolerMissions"):
    """The missions a vehicle's spooler holds (ReportStoredMissions), the plan of the last
    one read back (``plan_mission_id``, ``plan``: its tasks as the vehicle holds them) and
    its spooling preference (``preference``, NaN until reported)."""

    vehicle_id: str
    key("vehicle_id")
    missions: sequence[StoredMission] = field(default_factory=list)
    plan_mission_id: int32 = -1
    plan_source: str = ""
    plan: sequence[MissionTask] = field(default_factory=list)
    preference: float64 = NAN
    timestamp_ms: int64 = 0


# --------------------------------------------------------------------------- image products


@dataclass
class ImageProduct(IdlStruct, typename="edge_vis::ImageProduct"):
    """Metadata of one image file a vehicle produced, with its ATR detections."""

    vehicle_id: str
    key("vehicle_id")
    image_id: str
    key("image_id")
    file_name: str
    size_bytes: uint64
    sha256: str
    transfer_id: str = ""
    format: str = ""
    capture_time_ms: int64 = 0
    targets: sequence[AtrTarget] = field(default_factory=list)
    #: a PNG of at most 96 px a side, made by the receiver that verified the file
    #: (empty for formats the standard library cannot decode: see links/udt/thumbnail.py)
    thumbnail_png: sequence[uint8] = field(default_factory=list)


@dataclass
class ImageData(IdlStruct, typename="edge_vis::ImageData"):
    """One chunk (``chunk_index`` of ``chunk_count``) of an image file's bytes."""

    vehicle_id: str
    key("vehicle_id")
    image_id: str
    key("image_id")
    chunk_index: uint32
    chunk_count: uint32
    data: sequence[uint8]


# --------------------------------------------------------------------------- translator data
# (vehicle subsystems beyond pose and velocity: manipulators, UGV drive train, IOP platform
# services, and user-mapped messages)


@dataclass
class GenericField(IdlStruct, typename="edge_vis::GenericField"):
    """One field of a user-mapped JAUS message: as text always, as a number when it is one."""

    name: str
    text: str = ""
    number: float64 = NAN


@dataclass
class MeasurementReading(IdlStruct, typename="edge_vis::MeasurementReading"):
    """One reading of a measurement device (IOP MeasurementSensor)."""

    sensor: str
    source: str = ""
    type: str = ""
    unit: str = ""
    alert_level: str = ""
    values: sequence[float64] = field(default_factory=list)


@dataclass
class AccelerationState(IdlStruct, typename="edge_vis::AccelerationState"):
    """Linear (m/s^2) and angular (rad/s^2) acceleration in the vehicle frame."""

    vehicle_id: str
    key("vehicle_id")
    ax: float64 = NAN
    ay: float64 = NAN
    az: float64 = NAN
    roll_acceleration: float64 = NAN
    pitch_acceleration: float64 = NAN
    yaw_acceleration: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class JointState(IdlStruct, typename="edge_vis::JointState"):
    """Per-joint values of a manipulator or pan-tilt: ``quantity`` is position (rad or m),
    velocity (rad/s or m/s), effort (percent) or force_torque (N m or N), optionally
    ``commanded_``; ``units`` per joint."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    quantity: str
    key("quantity")
    values: sequence[float64] = field(default_factory=list)
    units: sequence[str] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class JointSpecification(IdlStruct, typename="edge_vis::JointSpecification"):
    """What the joints of ``device`` (manipulator, pan_tilt, end_effector) are, as the
    vehicle reports them: joint i of ``JointState.values`` is ``names[i]``, ``types[i]``
    revolute or prismatic, limits in ``units[i]`` (rad or m; speeds per second; NaN: not
    reported). ``parent_id`` is an end effector's parent link."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    names: sequence[str] = field(default_factory=list)
    types: sequence[str] = field(default_factory=list)
    min_values: sequence[float64] = field(default_factory=list)
    max_values: sequence[float64] = field(default_factory=list)
    max_speeds: sequence[float64] = field(default_factory=list)
    units: sequence[str] = field(default_factory=list)
    parent_id: int64 = -1
    timestamp_ms: int64 = 0


@dataclass
class EndEffectorPose(IdlStruct, typename="edge_vis::EndEffectorPose"):
    """Tool point position (m) and orientation (unit quaternion) in the manipulator frame;
    ``kind`` is actual, commanded or tool_offset."""

    vehicle_id: str
    key("vehicle_id")
    kind: str
    key("kind")
    x: float64 = NAN
    y: float64 = NAN
    z: float64 = NAN
    qw: float64 = NAN
    qx: float64 = NAN
    qy: float64 = NAN
    qz: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class EndEffectorVelocity(IdlStruct, typename="edge_vis::EndEffectorVelocity"):
    """Tool point linear (m/s) and angular (rad/s) velocity; ``kind`` actual or commanded."""

    vehicle_id: str
    key("vehicle_id")
    kind: str
    key("kind")
    vx: float64 = NAN
    vy: float64 = NAN
    vz: float64 = NAN
    wx: float64 = NAN
    wy: float64 = NAN
    wz: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class Odometry(IdlStruct, typename="edge_vis::Odometry"):
    """Distance travelled (m) on one odometer (PLATFORM, TRIP_A, TRIP_B, TRIP_C)."""

    vehicle_id: str
    key("vehicle_id")
    odometer: str
    key("odometer")
    distance: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class PlatformSpecifications(IdlStruct, typename="edge_vis::PlatformSpecifications"):
    """Static description of a ground platform: steering kind, limits (m/s, rad/s, m/s^2),
    extent from the vehicle origin (m) and weight (kg)."""

    vehicle_id: str
    key("vehicle_id")
    platform_name: str = ""
    steering: str = ""
    max_forward_speed: float64 = NAN
    max_reverse_speed: float64 = NAN
    max_rotational_speed: float64 = NAN
    max_forward_acceleration: float64 = NAN
    max_forward_deceleration: float64 = NAN
    front: float64 = NAN
    back: float64 = NAN
    left: float64 = NAN
    right: float64 = NAN
    top: float64 = NAN
    bottom: float64 = NAN
    wheel_base: float64 = NAN
    track_width: float64 = NAN
    min_turn_radius: float64 = NAN
    weight: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class PowerPlantStatus(IdlStruct, typename="edge_vis::PowerPlantStatus"):
    """One power plant (engine, battery, fuel cell, hydraulics): remaining charge or fuel
    (percent), voltage (V), current (A), temperature (deg C) and running hours."""

    vehicle_id: str
    key("vehicle_id")
    plant_id: uint8
    key("plant_id")
    description: str = ""
    kind: str = ""
    remaining_percent: float64 = NAN
    voltage: float64 = NAN
    current: float64 = NAN
    temperature: float64 = NAN
    hours: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class DeviceStatus(IdlStruct, typename="edge_vis::DeviceStatus"):
    """State of one simple vehicle device (parking_brake, illumination, transmission,
    skid_steer, ackermann ...): ``state`` and ``value`` as reported, ``commanded_*`` as last
    commanded (empty/NaN when the vehicle does not say)."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    state: str = ""
    commanded_state: str = ""
    value: float64 = NAN
    commanded_value: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class PlatformStatus(IdlStruct, typename="edge_vis::PlatformStatus"):
    """IOP platform state (Initialize, Operational, Emergency ...) and mode (Standard,
    Training, Maintenance) of a vehicle."""

    vehicle_id: str
    key("vehicle_id")
    platform_state: str = ""
    platform_mode: str = ""
    mode_status: str = ""
    supported_modes: sequence[str] = field(default_factory=list)
    last_response: str = ""
    timestamp_ms: int64 = 0


@dataclass
class DigitalResource(IdlStruct, typename="edge_vis::DigitalResource"):
    """A digital resource (video stream, file server) a vehicle announces."""

    vehicle_id: str
    key("vehicle_id")
    url: str
    key("url")
    server_type: str = ""
    resource_id: int32 = -1
    jaus_address: str = ""
    timestamp_ms: int64 = 0


@dataclass
class PathReport(IdlStruct, typename="edge_vis::PathReport"):
    """The path a vehicle travelled (historical) or will travel (planned)."""

    vehicle_id: str
    key("vehicle_id")
    path_type: str
    key("path_type")
    frame: Frame = Frame.GLOBAL
    points: sequence[Waypoint] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class MeasurementReport(IdlStruct, typename="edge_vis::MeasurementReport"):
    """Readings of one measurement device, with where they were taken (deg, m)."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    designation: str = ""
    classification: str = ""
    readings: sequence[MeasurementReading] = field(default_factory=list)
    latitude: float64 = NAN
    longitude: float64 = NAN
    altitude: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class GenericReport(IdlStruct, typename="edge_vis::GenericReport"):
    """A user-mapped JAUS message (profile ``[[translators.generic.mappings]]``)."""

    vehicle_id: str
    key("vehicle_id")
    message: str
    key("message")
    fields: sequence[GenericField] = field(default_factory=list)
    timestamp_ms: int64 = 0


# ----- commands


@dataclass
class JointCommand(IdlStruct, typename="edge_vis::JointCommand"):
    """Joint set-points for ``device`` (manipulator or pan_tilt): ``quantity`` position
    (rad, or m with units "m"), velocity (rad/s or m/s) or effort (percent)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    device: str = "manipulator"
    quantity: str = "position"
    values: sequence[float64] = field(default_factory=list)
    units: sequence[str] = field(default_factory=list)


@dataclass
class EndEffectorCommand(IdlStruct, typename="edge_vis::EndEffectorCommand"):
    """End-effector set-point: ``mode`` pose (m, unit quaternion), velocity (m/s, rad/s) or
    effort (percent, e.g. gripper)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    mode: str = "pose"
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    qw: float64 = 1.0
    qx: float64 = 0.0
    qy: float64 = 0.0
    qz: float64 = 0.0
    vx: float64 = 0.0
    vy: float64 = 0.0
    vz: float64 = 0.0
    wx: float64 = 0.0
    wy: float64 = 0.0
    wz: float64 = 0.0
    effort: float64 = 0.0


# -- the manipulator's List Manager: plans of joint positions or end-effector poses -------


@dataclass
class ManipulatorTarget(IdlStruct, typename="edge_vis::ManipulatorTarget"):
    """One target of a manipulator plan: joint positions (``values``, rad, or m where
    ``units[i]`` is "m") or an end-effector pose (m, unit quaternion)."""

    values: sequence[float64] = field(default_factory=list)
    units: sequence[str] = field(default_factory=list)
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    qw: float64 = 1.0
    qx: float64 = 0.0
    qy: float64 = 0.0
    qz: float64 = 0.0


@dataclass
class ManipulatorPlan(IdlStruct, typename="edge_vis::ManipulatorPlan"):
    """Targets for a manipulator to go through in order: loaded into its joint-position
    (``mode`` joint_positions) or end-effector-pose (end_effector_pose) list driver, then
    executed."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    plan_id: str
    targets: sequence[ManipulatorTarget]
    mode: str = "joint_positions"


@dataclass
class ManipulatorPlanStatus(IdlStruct, typename="edge_vis::ManipulatorPlanStatus"):
    """Progress of the manipulator plan: ``active_target`` is -1 when none; ``reason`` says
    why it FAILED."""

    vehicle_id: str
    key("vehicle_id")
    plan_id: str = ""
    mode: str = ""
    active_target: int32 = -1
    target_count: int32 = 0
    state: MissionState = MissionState.MISSION_IDLE
    reason: str = ""
    timestamp_ms: int64 = 0


@dataclass
class ManipulatorListElement(IdlStruct, typename="edge_vis::ManipulatorListElement"):
    """One element a manipulator's list holds: ``message`` (SetJointPositions,
    SetEndEffectorPose; "" when not one the relay knows) and its target (NaN where the
    message does not set it)."""

    uid: uint16 = 0
    previous_uid: uint16 = 0
    next_uid: uint16 = 0
    message: str = ""
    target: ManipulatorTarget = field(default_factory=ManipulatorTarget)


@dataclass
class ManipulatorList(IdlStruct, typename="edge_vis::ManipulatorList"):
    """The list one manipulator component holds, read back from its List Manager
    (``complete`` once every listed element was read)."""

    vehicle_id: str
    key("vehicle_id")
    component: str
    key("component")
    element_count: int32 = -1
    elements: sequence[ManipulatorListElement] = field(default_factory=list)
    complete: bool = False
    timestamp_ms: int64 = 0


@dataclass
class DeviceCommand(IdlStruct, typename="edge_vis::DeviceCommand"):
    """Set a simple vehicle device: parking_brake (value percent), illumination (state: the
    lights to switch on, comma separated), transmission (state: gear), odometer (state:
    trip to reset)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    device: str
    state: str = ""
    value: float64 = 0.0


@dataclass
class PlatformCommand(IdlStruct, typename="edge_vis::PlatformCommand"):
    """Ask for an IOP platform state and/or mode (empty = leave unchanged); with
    ``update_health`` the health monitor is asked to refresh its summary."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    platform_state: str = ""
    platform_mode: str = ""
    update_health: bool = False

# --------------------------------------------------------------------------- IOP and UGV extras


@dataclass
class HandoffRequest(IdlStruct, typename="edge_vis::HandoffRequest"):
    """An operator asks the operator holding a vehicle to hand it over (``action``
    REQUEST; publish it again within the re-assert timeout to keep it), or withdraws
    (CANCEL). IOP EnhancedAccessControl."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    authority: uint8 = 0
    explanation: str = ""
    action: str = "REQUEST"


@dataclass
class HandoffResponse(IdlStruct, typename="edge_vis::HandoffResponse"):
    """The holder's answer to hand-off request ``request_id``: GRANTED (the requester holds
    the vehicle from now on), DENIED, or WAIT (decide later; the timeout restarts)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    request_id: uint8
    response: str = "DENIED"


@dataclass
class HandoffEntry(IdlStruct, typename="edge_vis::HandoffEntry"):
    """One hand-off request: ``requester`` an operator, or ``jaus:S.N.C`` for another JAUS
    client asking through vehicle component ``via``; ``state`` PENDING or DEFERRED while
    the holder decides, then GRANTED, DENIED, TIMEOUT, CANCELLED, NOT_AVAILABLE or
    INSUFFICIENT_AUTHORITY, with the ``reason``."""

    request_id: uint8 = 0
    requester: str = ""
    authority: uint8 = 0
    explanation: str = ""
    state: str = ""
    reason: str = ""
    via: str = ""


@dataclass
class HandoffStatus(IdlStruct, typename="edge_vis::HandoffStatus"):
    """Hand-off requests of a vehicle for its ``holder`` to answer, and their outcomes;
    the timeouts in force (s, 0 = none; the vehicle's own NaN when it reports none)."""

    vehicle_id: str
    key("vehicle_id")
    holder: str = ""
    handoff_timeout: float64 = 0.0
    reassert_timeout: float64 = 0.0
    vehicle_handoff_timeout: float64 = NAN
    requests: sequence[HandoffEntry] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class CostMap(IdlStruct, typename="edge_vis::CostMap"):
    """A 2-D cost map (IOP CostMap2D): ``rows`` x ``columns`` cells, row-major, over
    ``width`` x ``height`` m centred at the GLOBAL (deg) or LOCAL (m) centre, rotated by
    ``rotation`` rad; ``costs`` per cell 0..255, ``confidence`` percent per cell (empty when
    the vehicle sends none)."""

    vehicle_id: str
    key("vehicle_id")
    rows: uint16 = 0
    columns: uint16 = 0
    width: float64 = NAN
    height: float64 = NAN
    frame: Frame = Frame.GLOBAL
    center_latitude: float64 = NAN
    center_longitude: float64 = NAN
    center_x: float64 = NAN
    center_y: float64 = NAN
    rotation: float64 = NAN
    costs: sequence[uint8] = field(default_factory=list)
    confidence: sequence[float64] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class CostMapRequest(IdlStruct, typename="edge_vis::CostMapRequest"):
    """Ask for a cost map of at most ``max_width`` x ``max_height`` m (NaN: the vehicle's
    choice) around a GLOBAL (deg) or LOCAL (m) centre (NaN: the vehicle's)."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str = ""
    max_width: float64 = NAN
    max_height: float64 = NAN
    frame: Frame = Frame.GLOBAL
    center_latitude: float64 = NAN
    center_longitude: float64 = NAN
    center_x: float64 = NAN
    center_y: float64 = NAN
    rotation: float64 = 0.0


@dataclass
class NoGoZone(IdlStruct, typename="edge_vis::NoGoZone"):
    """A polygon the vehicle must not enter: GLOBAL (lat/lon) or LOCAL (x/y) vertices."""

    zone_id: uint16 = 0
    frame: Frame = Frame.GLOBAL
    vertices: sequence[Waypoint] = field(default_factory=list)


@dataclass
class NoGoZones(IdlStruct, typename="edge_vis::NoGoZones"):
    """Every no-go zone the vehicle holds."""

    vehicle_id: str
    key("vehicle_id")
    zones: sequence[NoGoZone] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class NoGoZoneCommand(IdlStruct, typename="edge_vis::NoGoZoneCommand"):
    """ADD a no-go zone (``vertices`` in ``frame``; the vehicle answers with its zone id in
    ``RequestResult``, matched by ``request_id``) or REMOVE zone ``zone_id``."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    action: str = "ADD"
    request_id: uint16 = 0
    zone_id: uint16 = 0
    frame: Frame = Frame.GLOBAL
    vertices: sequence[Waypoint] = field(default_factory=list)


@dataclass
class RequestResult(IdlStruct, typename="edge_vis::RequestResult"):
    """A vehicle's answer to a request that carries an ID: ``request`` names it
    (AddNoGoZone, DigitalResourceEndpoint for a register or remove),
    ``result`` how it went, ``id`` what the vehicle assigned (zone, endpoint)."""

    vehicle_id: str
    key("vehicle_id")
    request: str
    key("request")
    request_id: uint16 = 0
    result: str = ""
    id: uint32 = 0
    timestamp_ms: int64 = 0


@dataclass
class DigitalResourceCommand(IdlStruct, typename="edge_vis::DigitalResourceCommand"):
    """REGISTER an endpoint (``url``, ``server_type`` RTSP, MPEG2_TS, FTP, SFTP,
    FTP_over_SSH, HTTP, HTTPS, SCP; optional ``jaus_address`` S.N.C and ``resource_id``) with
    the vehicle's DigitalResourceDiscovery, or REMOVE endpoint ``endpoint_id``."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    action: str = "REGISTER"
    request_id: uint8 = 0
    url: str = ""
    server_type: str = "RTSP"
    jaus_address: str = ""
    resource_id: int32 = -1
    endpoint_id: uint32 = 0


@dataclass
class CbrnStatus(IdlStruct, typename="edge_vis::CbrnStatus"):
    """State of one CBRN payload station (IOP CBRNSensor; ``station`` 1..32, 0 = the
    payload as a whole): the operating, configuration and scan window reports merged; each
    report's every field by its JAUS name in ``operating``, ``configuration`` and
    ``scan_window`` (enumerations as their number)."""

    vehicle_id: str
    key("vehicle_id")
    station: uint32
    key("station")
    payload_state: str = ""
    operating_mode: str = ""
    sampling_state: str = ""
    product_name: str = ""
    payload_type: str = ""
    power_mode: str = ""
    battery_remaining: float64 = NAN
    operating: sequence[GenericField] = field(default_factory=list)
    configuration: sequence[GenericField] = field(default_factory=list)
    scan_window: sequence[GenericField] = field(default_factory=list)
    timestamp_ms: int64 = 0


@dataclass
class CbrnDetection(IdlStruct, typename="edge_vis::CbrnDetection"):
    """A CBRN report of one station: ``kind`` CBRN4 (ATP-45 text) or MEASUREMENT (detailed
    measurement text), ``detection`` Below/Above Threshold, Above Threshold Update or NIL."""

    vehicle_id: str
    key("vehicle_id")
    station: uint32
    key("station")
    kind: str
    key("kind")
    detection: str = ""
    report_id: int64 = -1
    text: str = ""
    time: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class CbrnCommand(IdlStruct, typename="edge_vis::CbrnCommand"):
    """Command a CBRN payload station (1..32, 0 = all): ``kind`` COMMAND (CBRNCommand),
    CONFIGURATION (CBRNConfigurationCommand, which needs ``set_cbrn4_delivery_mode``) or
    DISPLAY (CBRNDisplayConfigurationCommand); ``settings`` names the JAUS fields
    (``set_power_mode``) with a label in ``text`` (``On``) or a ``number``."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    station: uint8 = 0
    kind: str = "COMMAND"
    settings: sequence[GenericField] = field(default_factory=list)


@dataclass
class SkidSteerCommand(IdlStruct, typename="edge_vis::SkidSteerCommand"):
    """Open-loop track efforts, percent -100..100 (UGV SkidSteerDriver); a motion command."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    left_effort: float64 = 0.0
    right_effort: float64 = 0.0


@dataclass
class AckermannCommand(IdlStruct, typename="edge_vis::AckermannCommand"):
    """Open-loop steering (rad), throttle and brake (percent 0..100) (UGV AckermannDriver);
    rate (rad/s) and torque (N m) limits optional. A motion command."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    steering_angle: float64 = 0.0
    throttle_effort: float64 = 0.0
    brake_effort: float64 = 0.0
    max_steering_rate: Optional[float64] = None  # noqa: UP045 (cyclonedds needs Optional)
    max_steering_torque: Optional[float64] = None  # noqa: UP045


@dataclass
class DeviceCapabilities(IdlStruct, typename="edge_vis::DeviceCapabilities"):
    """What a UGV device can do: ``supported`` names (lights, sounders, gears, transfer case
    modes) and ``limits`` (a stabilizer's angles, a power plant's capacities) by name with
    their unit in ``text``; ``points`` a stabilizer's outline (m)."""

    vehicle_id: str
    key("vehicle_id")
    device: str
    key("device")
    supported: sequence[str] = field(default_factory=list)
    limits: sequence[GenericField] = field(default_factory=list)
    points: sequence[Waypoint] = field(default_factory=list)
    timestamp_ms: int64 = 0



# --------------------------------------------------------------------------- mobility extras


@dataclass
class WrenchEffortState(IdlStruct, typename="edge_vis::WrenchEffortState"):
    """The effort the primitive driver is applying, percent: propulsive -100..100,
    resistive 0..100 (NaN = not reported)."""

    vehicle_id: str
    key("vehicle_id")
    propulsive_linear_x: float64 = NAN
    propulsive_linear_y: float64 = NAN
    propulsive_linear_z: float64 = NAN
    propulsive_rotational_x: float64 = NAN
    propulsive_rotational_y: float64 = NAN
    propulsive_rotational_z: float64 = NAN
    resistive_linear_x: float64 = NAN
    resistive_linear_y: float64 = NAN
    resistive_linear_z: float64 = NAN
    resistive_rotational_x: float64 = NAN
    resistive_rotational_y: float64 = NAN
    resistive_rotational_z: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class VelocityCommandState(IdlStruct, typename="edge_vis::VelocityCommandState"):
    """A velocity the velocity state driver holds: ``command_type`` CURRENT (what it is
    driving now), MAXIMUM, MINIMUM or DEFAULT; m/s and rad/s in the vehicle frame."""

    vehicle_id: str
    key("vehicle_id")
    command_type: str
    key("command_type")
    vx: float64 = NAN
    vy: float64 = NAN
    vz: float64 = NAN
    roll_rate: float64 = NAN
    pitch_rate: float64 = NAN
    yaw_rate: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class VectorState(IdlStruct, typename="edge_vis::VectorState"):
    """The vector a vector driver is steering to: ``frame`` GLOBAL (``altitude``, m above
    the ellipsoid) or LOCAL (``z``, m); heading, roll, pitch in rad; speed in m/s."""

    vehicle_id: str
    key("vehicle_id")
    frame: str
    key("frame")
    speed: float64 = NAN
    heading: float64 = NAN
    altitude: float64 = NAN
    z: float64 = NAN
    roll: float64 = NAN
    pitch: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class VectorCommand(IdlStruct, typename="edge_vis::VectorCommand"):
    """Steer by vector: heading (rad), speed (m/s) and altitude (GLOBAL, m) or z (LOCAL, m);
    an absent member is left unchanged."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    frame: Frame = Frame.GLOBAL
    speed: Optional[float64] = None  # noqa: UP045 (cyclonedds needs Optional)
    heading: Optional[float64] = None  # noqa: UP045
    altitude: Optional[float64] = None  # noqa: UP045
    z: Optional[float64] = None  # noqa: UP045
    roll: Optional[float64] = None  # noqa: UP045
    pitch: Optional[float64] = None  # noqa: UP045


@dataclass
class AccelerationLimit(IdlStruct, typename="edge_vis::AccelerationLimit"):
    """An acceleration limit of the velocity state driver: ``limit`` MAXIMUM or MINIMUM;
    m/s^2 and rad/s^2 (NaN = not reported)."""

    vehicle_id: str
    key("vehicle_id")
    limit: str
    key("limit")
    ax: float64 = NAN
    ay: float64 = NAN
    az: float64 = NAN
    roll_acceleration: float64 = NAN
    pitch_acceleration: float64 = NAN
    yaw_acceleration: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class AccelerationLimitCommand(IdlStruct, typename="edge_vis::AccelerationLimitCommand"):
    """Set the MAXIMUM or MINIMUM acceleration (m/s^2, rad/s^2); absent = unchanged."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    limit: str = "MAXIMUM"
    ax: Optional[float64] = None  # noqa: UP045 (cyclonedds needs Optional)
    ay: Optional[float64] = None  # noqa: UP045
    az: Optional[float64] = None  # noqa: UP045
    roll_acceleration: Optional[float64] = None  # noqa: UP045
    pitch_acceleration: Optional[float64] = None  # noqa: UP045
    yaw_acceleration: Optional[float64] = None  # noqa: UP045


@dataclass
class GeomagneticProperty(IdlStruct, typename="edge_vis::GeomagneticProperty"):
    """Magnetic variation (declination) the global pose sensor applies, rad, east positive."""

    vehicle_id: str
    key("vehicle_id")
    magnetic_variation: float64 = NAN
    timestamp_ms: int64 = 0


@dataclass
class PoseCommand(IdlStruct, typename="edge_vis::PoseCommand"):
    """Reset a pose sensor's estimate: GLOBAL (deg, m) or LOCAL (m) position, attitude (rad),
    and their RMS uncertainty; an absent member is left unchanged. ``magnetic_variation``
    (rad, east positive), when given, sets the global pose sensor's geomagnetic property."""

    vehicle_id: str
    key("vehicle_id")
    operator_id: str
    frame: Frame = Frame.GLOBAL
    latitude: Optional[float64] = None  # noqa: UP045 (cyclonedds needs Optional)
    longitude: Optional[float64] = None  # noqa: UP045
    altitude: Optional[float64] = None  # noqa: UP045
    x: Optional[float64] = None  # noqa: UP045
    y: Optional[float64] = None  # noqa: UP045
    z: Optional[float64] = None  # noqa: UP045
    roll: Optional[float64] = None  # noqa: UP045
    pitch: Optional[float64] = None  # noqa: UP045
    yaw: Optional[float64] = None  # noqa: UP045
    position_rms: Optional[float64] = None  # noqa: UP045
    attitude_rms: Optional[float64] = None  # noqa: UP045
    magnetic_variation: Optional[float64] = None  # noqa: UP045 (rad, east positive)


STRUCTS: tuple[type[IdlStruct], ...] = (
    VehicleIdentification,
    VehicleStatus,
    GlobalPose,
    LocalPose,
    Velocity,
    ControlRequest,
    ControlStatus,
    EmergencyCommand,
    WrenchEffortCommand,
    VelocityCommand,
    WaypointPlan,
    MissionStatus,
    VehiclePlan,
    PlanQuery,
    PathSegmentPlan,
    MissionSpoolCommand,
    SpoolerStatus,
    SpoolerMissions,
    LinkStatus,
    RelayStatus,
    HealthStatus,
    RangeScan,
    SensorInfo,
    SensorState,
    SensorCommand,
    HmiInput,
    ImageProduct,
    ImageData,
    TransferStatus,
    EnvironmentalData,
    AccelerationState,
    JointState,
    JointSpecification,
    EndEffectorPose,
    EndEffectorVelocity,
    Odometry,
    PlatformSpecifications,
    PowerPlantStatus,
    DeviceStatus,
    PlatformStatus,
    DigitalResource,
    PathReport,
    MeasurementReport,
    GenericReport,
    JointCommand,
    EndEffectorCommand,
    ManipulatorPlan,
    ManipulatorPlanStatus,
    ManipulatorList,
    DeviceCommand,
    PlatformCommand,
    HandoffRequest,
    HandoffResponse,
    HandoffStatus,
    CostMap,
    CostMapRequest,
    NoGoZones,
    NoGoZoneCommand,
    RequestResult,
    DigitalResourceCommand,
    CbrnStatus,
    CbrnDetection,
    CbrnCommand,
    SkidSteerCommand,
    AckermannCommand,
    DeviceCapabilities,
    WrenchEffortState,
    VelocityCommandState,
    VectorState,
    VectorCommand,
    AccelerationLimit,
    AccelerationLimitCommand,
    GeomagneticProperty,
    PoseCommand,
    ManagementCommand,
    VehicleClock,
)
"""Every top-level type of the standard model; each is carried by the topic of its name."""
