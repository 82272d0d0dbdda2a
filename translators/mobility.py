"""The ``mobility`` translator (AS6009 slice): pose and velocity out, drive commands in.

No I/O. JAUS -> DDS:

* ReportGlobalPose -> ``GlobalPose`` (degrees, metres, radians)
* ReportLocalPose -> ``LocalPose`` (metres, radians)
* ReportVelocityState -> ``Velocity`` (m/s, rad/s)

DDS -> JAUS (commands, throttled and control-checked by the engine):

* ``WrenchEffortCommand`` -> SetWrenchEffort to the PrimitiveDriver (percent, clamped to
  [-100, 100]; stop = all zero)
* ``VelocityCommand`` -> SetVelocityCommand (current command) to the VelocityStateDriver
  (stop = all zero)

Fields a vehicle does not report are published as NaN, so "not reported" never reads as
zero. ``timestamp_ms`` is the relay's reception time (wall clock, ms since the epoch):
the JAUS TimeStamp carries no date and cannot be converted without guessing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

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
_REPORTS = {
    "ReportGlobalPose": ("GlobalPose", _GLOBAL_POSE),
    "ReportLocalPose": ("LocalPose", _LOCAL_POSE),
    "ReportVelocityState": ("Velocity", _VELOCITY),
}

#: (DDS sample field, SetWrenchEffort field)
_WRENCH = (
    ("propulsive_linear_x", "propulsive_linear_effort_x"),
    ("propulsive_linear_y", "propulsive_linear_effort_y"),
    ("propulsive_linear_z", "propulsive_linear_effort_z"),
    ("propulsive_rotational_x", "propulsive_rotational_effort_x"),
    ("propulsive_rotational_y", "propulsive_rotational_effort_y"),
    ("propulsive_rotational_z", "propulsive_rotational_effort_z"),
)
#: (DDS sample field, SetVelocityCommand field, limit)
_VELOCITY_CMD = (
    ("vx", "velocity_x", 327.67), ("vy", "velocity_y", 327.67), ("vz", "velocity_z", 327.67),
    ("roll_rate", "roll_rate", 32.767), ("pitch_rate", "pitch_rate", 32.767),
    ("yaw_rate", "yaw_rate", 32.767),
)


def _clamp(value: Any, limit: float) -> float:
    if value is None:  # an optional DDS field the operator left unset
        return 0.0
    number = float(value)
    if math.isnan(number):
        return 0.0
    return max(-limit, min(limit, number))


class MobilityTranslator(Translator):
    """Mobility service set (AS6009) <-> pose, velocity and drive topics."""

    name = "mobility"
    messages = tuple(_REPORTS)
    reports = (
        ReportSpec("ReportGlobalPose", "QueryGlobalPose", MOBILITY + "GlobalPoseSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
        ReportSpec("ReportLocalPose", "QueryLocalPose", MOBILITY + "LocalPoseSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
        ReportSpec("ReportVelocityState", "QueryVelocityState", MOBILITY + "VelocityStateSensor",
                   {"presence_vector": ALL_FIELDS}, rate=5.0),
    )
    publishes = ("GlobalPose", "LocalPose", "Velocity")
    subscribes = ("WrenchEffortCommand", "VelocityCommand")
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

    def on_message(
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
        if topic == "WrenchEffortCommand":
            fields = {jaus: _clamp(sample.get(dds, 0.0), 100.0) for dds, jaus in _WRENCH}
            stop = dict.fromkeys(fields, 0.0)
            return [Command(vehicle_id, operator_id, "wrench_effort", "SetWrenchEffort",
                            fields, PRIMITIVE_DRIVER, stop=stop)]
        if topic == "VelocityCommand":
            fields = {"command_type": 0}
            fields.update({jaus: _clamp(sample.get(dds, 0.0), limit)
                           for dds, jaus, limit in _VELOCITY_CMD})
            stop = {**dict.fromkeys(fields, 0.0), "command_type": 0}
            return [Command(vehicle_id, operator_id, "velocity", "SetVelocityCommand",
                            fields, VELOCITY_DRIVER, stop=stop)]
        return []
