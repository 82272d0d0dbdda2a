"""The ``mobility`` translator (AS6009 slice): pose and velocity out, drive commands in.

No I/O. JAUS -> DDS:

* ReportGlobalPose -> ``GlobalPose`` (degrees, metres, radians)
* ReportLocalPose -> ``LocalPose`` (metres, radians)
* ReportVelocityState -> ``Velocity`` (m/s, rad/s)
* ReportAccelerationState -> ``AccelerationState`` (m/s^2, rad/s^2)
* ReportActiveElement, ReportTravelSpeed, Confirm/RejectElementRequest and, for
  single-waypoint drivers, the pose reaching a waypoint -> ``MissionStatus``

DDS -> JAUS (commands, throttled and control-checked by the engine):

* ``WrenchEffortCommand`` -> SetWrenchEffort to the PrimitiveDriver (percent; propulsive
  clamped to [-100, 100], resistive to [0, 100]; an absent field is left out, i.e. left
  unchanged by the vehicle; stop = all propulsive efforts zero)
* ``VelocityCommand`` -> SetVelocityCommand (current command) to the VelocityStateDriver
  (stop = all zero)
* ``WaypointPlan`` -> the List Manager sequence to the Global/LocalWaypointListDriver
  (DeleteElement, SetElement with Set{Global,Local}Waypoint elements, ExecuteList), or
  SetTravelSpeed and Set{Global,Local}Waypoint one at a time to a vehicle with only a
  waypoint driver (see
  :class:`WaypointMissions`)

Fields a vehicle does not report are published as NaN, so "not reported" never reads as
zero. ``timestamp_ms`` is the relay's reception time (wall clock, ms since the epoch):
the JAUS TimeStamp carries no date and cannot be converted without guessing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from edge_vis.catalogue import default_catalogue
from edge_vis.engine.actions import Action, Command, Publish
from edge_vis.translator import ReportSpec, Translator, TranslatorContext

MOBILITY = "urn:jaus:jss:mobility:"
PRIMITIVE_DRIVER = MOBILITY + "PrimitiveDriver"
VELOCITY_DRIVER = MOBILITY + "VelocityStateDriver"

#: presence vector asking for every field of the pose and velocity reports
ALL_FIELDS = 0x01FF

#: (JAUS report field, DDS sample field) per report
_GLOBAL_POSE = (("latitude", "latitude"), ("longitude", "longitude"), ("altitude", "altitude"),
                ("roll", "roll"), ("pitch", "pitch"), ("yaw", "yaw"))
_LOCAL_POSE = (("x", "x"), ("y", "y"), ("z", "z"), ("roll", "roll"), ("pitch", "pitch"),
               ("yaw", "yaw"))
_VELOCITY = (("velocity_x", "vx"), ("velocity_y", "vy"), ("velocity_z", "vz"),
             ("roll_rate", "roll_rate"), ("pitch_rate", "pitch_rate"), ("yaw_rate", "yaw_rate"))
_ACCELERATION = (("acceleration_x", "ax"), ("acceleration_y", "ay"), ("acceleration_z", "az"),
                 ("roll_acceleration", "roll_acceleration"),
                 ("pitch_acceleration", "pitch_acceleration"),
                 ("yaw_acceleration", "yaw_acceleration"))
_REPORTS = {
    "ReportGlobalPose": ("GlobalPose", _GLOBAL_POSE),
    "ReportLocalPose": ("LocalPose", _LOCAL_POSE),
    "ReportVelocityState": ("Velocity", _VELOCITY),
    "ReportAccelerationState": ("AccelerationState", _ACCELERATION),
}

#: (DDS sample field, SetWrenchEffort field, lowest, highest)
_WRENCH = tuple(
    (f"{kind}_{axis}", f"{kind}_effort_{axis}", low, 100.0)
    for kind, low in (("propulsive_linear", -100.0), ("propulsive_rotational", -100.0),
                      ("resistive_linear", 0.0), ("resistive_rotational", 0.0))
    for axis in ("x", "y", "z")
)
_WRENCH_STOP = {jaus: 0.0 for dds, jaus, _, _ in _WRENCH if dds.startswith("propulsive")}

#: (DDS sample field, SetVelocityCommand field, limit)
_VELOCITY_CMD = (
    ("vx", "velocity_x", 327.67), ("vy", "velocity_y", 327.67), ("vz", "velocity_z", 327.67),
    ("roll_rate", "roll_rate", 32.767), ("pitch_rate", "pitch_rate", 32.767),
    ("yaw_rate", "yaw_rate", 32.767),
)


def _clamp(value: Any, low: float, high: float) -> float:
    if value is None:  # an optional DDS field the operator left unset
        return 0.0
    number = float(value)
    if math.isnan(number):
        return 0.0
    return max(low, min(high, number))


# -- waypoint missions (WaypointPlan -> List Manager / waypoint drivers -> MissionStatus) --

GLOBAL_LIST_DRIVER = MOBILITY + "GlobalWaypointListDriver"
LOCAL_LIST_DRIVER = MOBILITY + "LocalWaypointListDriver"
GLOBAL_WAYPOINT_DRIVER = MOBILITY + "GlobalWaypointDriver"
LOCAL_WAYPOINT_DRIVER = MOBILITY + "LocalWaypointDriver"
#: waypoints per SetElement: keeps each one inside a single JUDP packet
ELEMENTS_PER_SET = 50
#: UID that DeleteElement reads as "every element"
ALL_ELEMENTS = 0xFFFF
#: metres that count as "reached" for single-waypoint drivers when the plan says 0
DEFAULT_TOLERANCE = 2.0
#: ExecuteList speed when the plan says 0 and the vehicle never reported a travel speed
DEFAULT_SPEED = 1.0
_EARTH_RADIUS = 6_371_000.0
MISSION_MESSAGES = ("ConfirmElementRequest", "RejectElementRequest", "ReportActiveElement",
                    "ReportTravelSpeed")
MISSION_REPORTS = tuple(
    ReportSpec(report, query, service, rate=1.0, on_change=True)
    for service in (GLOBAL_LIST_DRIVER, LOCAL_LIST_DRIVER)
    for report, query in (("ReportActiveElement", "QueryActiveElement"),
                          ("ReportTravelSpeed", "QueryTravelSpeed"))
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
    steps: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    request_id: int | None = None
    pending: str = ""
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


class WaypointMissions:
    """WaypointPlan -> List Manager sequence (or single waypoints) -> MissionStatus.

    With a waypoint *list* driver the plan goes out as DeleteElement (every element),
    then SetElement batches of Set{Global,Local}Waypoint elements linked previous/next,
    each sent only after the vehicle confirmed the previous request, then ExecuteList
    with the speed. With only a waypoint driver the waypoints go out one at a time: the
    next when the reported pose comes within the waypoint's tolerance. Every step is a
    :class:`Command` (control-gated and throttled by the engine, kind ``waypoint``).
    """

    def __init__(self) -> None:
        self.missions: dict[str, _Mission] = {}
        self._request_id = 0

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
        if list_driver not in services:
            mission.service, mission.listed = single_driver, False
        if not waypoints or mission.service not in services:
            mission.state = "FAILED"
            self.missions[vehicle.vehicle_id] = mission
            return [self._status(vehicle.vehicle_id, ctx)]
        self.missions[vehicle.vehicle_id] = mission
        if mission.listed:
            mission.steps = self._list_steps(mission)
            return [self._next_step(vehicle.vehicle_id), self._status(vehicle.vehicle_id, ctx)]
        mission.active, mission.state = 0, "EXECUTING"
        # a waypoint driver drives at its travel speed: set it first (its own throttle
        # slot, so it is not coalesced away by the waypoint)
        speed = Command(vehicle.vehicle_id, mission.operator_id, "waypoint_speed",
                        "SetTravelSpeed", {"speed": _clamp(self._speed(mission), 0.0, 327.67)},
                        mission.service)
        return [speed, self._waypoint(vehicle.vehicle_id, 0),
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
        if name in ("ConfirmElementRequest", "RejectElementRequest"):
            if fields.get("request_id") != mission.request_id or mission.request_id is None:
                return []
            mission.request_id = None
            # an empty list may refuse "delete everything": nothing to delete is fine
            if name == "RejectElementRequest" and mission.pending != "DeleteElement":
                mission.state = "FAILED"
                return [self._status(vehicle_id, ctx)]
            actions: list[Action] = [self._next_step(vehicle_id)]
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

    def _list_steps(self, mission: _Mission) -> list[tuple[str, dict[str, Any]]]:
        message = "SetLocalWaypoint" if mission.local else "SetGlobalWaypoint"
        catalogue = default_catalogue()
        steps: list[tuple[str, dict[str, Any]]] = [
            ("DeleteElement", {"delete_element_list": [{"element_uid": ALL_ELEMENTS}]})]
        count = len(mission.waypoints)
        for start in range(0, count, ELEMENTS_PER_SET):
            batch = range(start, min(count, start + ELEMENTS_PER_SET))
            elements = [{
                "element_uid": i + 1,
                "previous_uid": i,  # 0 before the first
                "next_uid": i + 2 if i + 1 < batch.stop else 0,
                "element_data": {"format": 0, "data": catalogue.encode(
                    message, waypoint_fields(mission.waypoints[i], mission.local))},
            } for i in batch]
            steps.append(("SetElement", {"element_list": elements}))
        return steps

    def _next_step(self, vehicle_id: str) -> Command:
        mission = self.missions[vehicle_id]
        if mission.steps:
            name, fields = mission.steps.pop(0)
            mission.pending = name
            self._request_id = (self._request_id + 1) % 256
            mission.request_id = self._request_id
            fields = {"request_id_rec": {"request_id": mission.request_id}, **fields}
        else:
            name, fields = "ExecuteList", {"speed": _clamp(self._speed(mission), 0.0, 327.67),
                                           "element_uid": 1}
            mission.state = "EXECUTING"
        return Command(vehicle_id, mission.operator_id, "waypoint", name, fields,
                       mission.service)

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


class MobilityTranslator(Translator):
    """Mobility service set (AS6009) <-> pose, velocity and drive topics."""

    name = "mobility"
    messages = (*_REPORTS, *MISSION_MESSAGES)
    reports = (
        ReportSpec("ReportGlobalPose", "QueryGlobalPose", MOBILITY + "GlobalPoseSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
        ReportSpec("ReportLocalPose", "QueryLocalPose", MOBILITY + "LocalPoseSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
        ReportSpec("ReportVelocityState", "QueryVelocityState", MOBILITY + "VelocityStateSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
        ReportSpec("ReportAccelerationState", "QueryAccelerationState",
                   MOBILITY + "AccelerationStateSensor", {"presence_vector": ALL_FIELDS},
                   rate=1.0),
        *MISSION_REPORTS,
    )
    publishes = ("GlobalPose", "LocalPose", "Velocity", "AccelerationState", "MissionStatus")
    subscribes = ("WrenchEffortCommand", "VelocityCommand", "WaypointPlan")
    # Holding a vehicle means holding every component that can move it, waypoint list
    # drivers included, so nothing else drives it meanwhile.
    controlled_services = (
        PRIMITIVE_DRIVER,
        VELOCITY_DRIVER,
        MOBILITY + "LocalWaypointListDriver",
        MOBILITY + "GlobalWaypointListDriver",
        MOBILITY + "LocalWaypointDriver",
        MOBILITY + "GlobalWaypointDriver",
    )

    def __init__(self) -> None:
        self.missions = WaypointMissions()

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if ctx.vehicle is not None and name in MISSION_MESSAGES:
            return self.missions.on_message(name, fields, ctx)
        if ctx.vehicle is not None and name in ("ReportGlobalPose", "ReportLocalPose"):
            return [*self._publish(name, fields, ctx), *self.missions.on_pose(name, fields, ctx)]
        return self._publish(name, fields, ctx)

    def _publish(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if ctx.vehicle is None or name not in _REPORTS:
            return []
        topic, mapping = _REPORTS[name]
        sample: dict[str, Any] = {"vehicle_id": ctx.vehicle.vehicle_id}
        for jaus_name, dds_name in mapping:
            value = fields.get(jaus_name)
            sample[dds_name] = float(value) if value is not None else math.nan
        sample["timestamp_ms"] = ctx.timestamp_ms
        return [Publish(topic, sample)]

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        vehicle_id = str(sample.get("vehicle_id", ""))
        operator_id = str(sample.get("operator_id", ""))
        if topic == "WaypointPlan":
            return self.missions.on_plan(sample, ctx)
        if topic == "WrenchEffortCommand":
            fields = {jaus: _clamp(sample[dds], low, high) for dds, jaus, low, high in _WRENCH
                      if sample.get(dds) is not None}
            if not fields:
                return []
            return [Command(vehicle_id, operator_id, "wrench_effort", "SetWrenchEffort",
                            fields, PRIMITIVE_DRIVER, stop=dict(_WRENCH_STOP))]
        if topic == "VelocityCommand":
            fields = {"command_type": 0}
            fields.update({jaus: _clamp(sample.get(dds), -limit, limit)
                           for dds, jaus, limit in _VELOCITY_CMD})
            stop = {**dict.fromkeys(fields, 0.0), "command_type": 0}
            return [Command(vehicle_id, operator_id, "velocity", "SetVelocityCommand",
                            fields, VELOCITY_DRIVER, stop=stop)]
        return []

    def describe(self) -> list[dict[str, Any]]:
        """Mapping-table rows (``edge-vis mappings``), from the tables above."""
        row = _row
        rows = [row("jaus->dds", name, topic, [(jaus, dds, "") for jaus, dds in mapping],
                    next((s.query for s in self.reports if s.report == name), ""))
                for name, (topic, mapping) in _REPORTS.items()]
        rows.append(row("dds->jaus", "SetWrenchEffort", "WrenchEffortCommand",
                        [(jaus, dds, f"clamped to [{low}, {high}]")
                         for dds, jaus, low, high in _WRENCH]))
        rows.append(row("dds->jaus", "SetVelocityCommand", "VelocityCommand",
                        [(jaus, dds, f"clamped to +-{limit}")
                         for dds, jaus, limit in _VELOCITY_CMD]))
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
        return rows


def _row(direction: str, message: str, topic: str, fields: list[tuple[str, str, str]],
         query: str = "", doc: str = "") -> dict[str, Any]:
    return {"translator": "mobility", "direction": direction, "message": message,
            "topic": topic, "query": query, "service": "", "rate": None,
            "fields": [{"jaus": j, "dds": d, "note": n} for j, d, n in fields], "doc": doc}
