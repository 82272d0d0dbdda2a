"""The ``iop`` translator (IOP services of the public JSIDL): platform, health, resources. No I/O.

JAUS -> DDS:

* ReportPlatformState, ConfirmPlatformStateRequest, ReportPlatformMode,
  ReportSupportedPlatformModes -> ``PlatformStatus`` (merged per vehicle);
* ReportUGVSummary (HealthMonitor) -> ``HealthStatus``: the worst severity as the level,
  each node that is not NONE/INFO as a fault;
* ReportDigitalResourceEndpoint -> one ``DigitalResource`` per endpoint (video streams,
  file servers the vehicle announces);
* ReportPath (PathReporter) -> ``PathReport`` (historical and planned, global or local);
* ReportMeasurement (MeasurementSensor) -> ``MeasurementReport``;
* ReportHeartbeatPulse sent unsolicited (UnsolicitedHeartbeat) needs no translation here:
  the engine treats any message as a sign of life, probes an unknown sender with
  QueryIdentification, and the ``core`` translator publishes ``VehicleStatus`` for it.

DDS -> JAUS (behind control, throttled): ``PlatformCommand`` -> SetPlatformState and/or
SetPlatformMode (an empty member leaves it unchanged).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import CommandRule as Cmd
from edge_vis.kit import (
    Computed,
    Each,
    From,
    Put,
    ReportRule,
    RuleTranslator,
    code_of,
    label,
)

IOP = "urn:jaus:jss:iop:"
HEALTH = "urn:jaus:jss:exp:aeodrs:HealthMonitor"

PLATFORM_STATES = {0: "Initialize", 1: "Operational", 2: "Shutdown", 3: "System_Abort",
                   4: "Emergency", 5: "Render_Useless"}
PLATFORM_MODES = {0: "Standard_Operating", 1: "Training", 2: "Maintenance"}
MODE_STATUS = {0: "Initializing", 1: "Active", 2: "Exiting"}
STATE_RESPONSES = {0: "Transitioning", 1: "InvalidState"}
SEVERITIES = {0: "NONE", 1: "INFO", 2: "WARN", 3: "ERR", 4: "FAIL"}
#: HealthMonitor severity -> HealthStatus.level
HEALTH_LEVELS = {0: "HEALTH_OK", 1: "HEALTH_OK", 2: "HEALTH_WARNING", 3: "HEALTH_FAULT",
                 4: "HEALTH_CRITICAL"}
SERVER_TYPES = {0: "RTSP", 1: "MPEG2_TS", 2: "FTP", 3: "SFTP", 4: "FTP_over_SSH", 5: "HTTP",
                6: "HTTPS", 7: "SCP"}
PATH_TYPES = {0: "HistoricalGlobalPath", 1: "HistoricalLocalPath", 2: "PlannedGlobalPath",
              3: "PlannedLocalPath"}
ALERT_LEVELS = {255: "NOT_SUPPORTED", 0: "NO_ALERT", 1: "LOW", 2: "MIDDLE", 3: "HIGH"}


def _faults(f: Mapping[str, Any]) -> list[str]:
    out = []
    for item in f.get("severity_list") or []:
        severity = int(item.get("severity_rec", {}).get("severity", 0))
        if severity >= 2:
            node = item.get("node_id", {}).get("node_id", "?")
            out.append(f"node {node}: {SEVERITIES.get(severity, severity)}")
    return out


def _jaus_id(value: Any) -> str:
    if not isinstance(value, Mapping):
        return ""
    parts = (value.get(k, 0) for k in ("subsystem_id", "node_id", "component_id"))
    return ".".join(str(int(p)) for p in parts)


def _path_points(f: Mapping[str, Any]) -> list[dict[str, float]]:
    var = f.get("path_var") or {}
    points = next(iter(var.values()), []) if var else []
    names = ("latitude", "longitude", "altitude", "x", "y", "z")
    return [{n: float(p.get(n, 0.0)) for n in names} for p in points or []]


def _path_type(f: Mapping[str, Any]) -> str:
    var = f.get("path_var") or {}
    name = next(iter(var), "")
    return "".join(part.capitalize() for part in name.split("_"))


def _frame(f: Mapping[str, Any]) -> str:
    return "LOCAL" if "local" in next(iter(f.get("path_var") or {}), "") else "GLOBAL"


class IopTranslator(RuleTranslator):
    """IOP platform state/mode, health, digital resources, paths and measurements."""

    name = "iop"
    report_rules = (
        ReportRule("ReportPlatformState", "PlatformStatus",
                   {"platform_state": From("platform_state", convert=label(PLATFORM_STATES))},
                   query="QueryPlatformState", service=IOP + "PlatformState", rate=1.0,
                   on_change=True, merge=True),
        ReportRule("ConfirmPlatformStateRequest", "PlatformStatus",
                   {"platform_state": From("platform_state", convert=label(PLATFORM_STATES)),
                    "last_response": From("response_code", convert=label(STATE_RESPONSES))},
                   merge=True, doc="the answer to SetPlatformState"),
        ReportRule("ReportPlatformMode", "PlatformStatus",
                   {"platform_mode": From("platform_mode", convert=label(PLATFORM_MODES)),
                    "mode_status": From("status", convert=label(MODE_STATUS))},
                   query="QueryPlatformMode", service=IOP + "PlatformMode", rate=1.0,
                   on_change=True, merge=True),
        ReportRule("ReportSupportedPlatformModes", "PlatformStatus",
                   {"supported_modes": Each("supported_platform_modes_list",
                                            From("platform_mode",
                                                 convert=label(PLATFORM_MODES)))},
                   query="QuerySupportedPlatformModes", service=IOP + "PlatformMode",
                   rate=0.1, on_change=True, merge=True),
        ReportRule("ReportUGVSummary", "HealthStatus",
                   {"level": From("ugv_severity_rec.severity", convert=label(
                       HEALTH_LEVELS, "HEALTH_UNKNOWN"), default="HEALTH_UNKNOWN"),
                    "faults": Computed(_faults, "severity_list[] with severity >= WARN")},
                   query="QueryUGVSummary", service=HEALTH, rate=1.0, on_change=True),
        ReportRule("ReportDigitalResourceEndpoint", "DigitalResource",
                   {"url": From("server_url", default=""),
                    "server_type": From("server_type", convert=label(SERVER_TYPES)),
                    "resource_id": From("resource_id", default=-1),
                    "jaus_address": From("jaus_id", convert=_jaus_id, default="")},
                   query="QueryDigitalResourceEndpoint",
                   service=IOP + "DigitalResourceDiscovery", rate=0.1, on_change=True,
                   split="digital_resource_endpoint_list", doc="one sample per endpoint"),
        ReportRule("ReportPath", "PathReport",
                   {"path_type": Computed(_path_type, "path_var alternative"),
                    "frame": Computed(_frame, "path_var alternative (global/local)"),
                    "points": Computed(_path_points, "path_var.*[] lat/lon/alt or x/y/z")},
                   query="QueryPath", service=IOP + "PathReporter",
                   query_fields={"path_type": 0, "maximum_points": 100}, rate=0.2),
        ReportRule("ReportMeasurement", "MeasurementReport",
                   {"device": From("device_rec.device_name", default=""),
                    "designation": From("device_rec.device_designation", default=""),
                    "classification": From("device_rec.classification", default=""),
                    "readings": Each("readings_list", {
                        "sensor": From("reading_rec.sensor", default=""),
                        "source": From("reading_rec.source", default=""),
                        "type": From("reading_rec.type", default=""),
                        "unit": From("reading_rec.unit", default=""),
                        "alert_level": From("reading_rec.alert_level",
                                            convert=label(ALERT_LEVELS), default=""),
                        "values": Each("value_list", From("value"))}),
                    "latitude": From("global_pose_rec.latitude", note="deg"),
                    "longitude": From("global_pose_rec.longitude", note="deg"),
                    "altitude": From("global_pose_rec.altitude", note="m")},
                   query="QueryMeasurement", service=IOP + "MeasurementSensor", rate=1.0),
    )
    command_rules = (
        Cmd("PlatformCommand", "SetPlatformState", IOP + "PlatformState", "platform_state",
            {"platform_state": Put("platform_state", convert=code_of(PLATFORM_STATES),
                                   note="state name")},
            when={"platform_state": tuple(PLATFORM_STATES.values())}),
        Cmd("PlatformCommand", "SetPlatformMode", IOP + "PlatformMode", "platform_mode",
            {"platform_mode": Put("platform_mode", convert=code_of(PLATFORM_MODES),
                                  note="mode name")},
            when={"platform_mode": tuple(PLATFORM_MODES.values())}),
    )
    not_translated = (
        ("ReportHeartbeatPulse", "unsolicited heartbeats keep the vehicle alive in the "
                                 "engine; VehicleStatus comes from the core translator"),
        ("ReportPathReporterCapabilities", "path limits: not exposed"),
        ("ReportCostMap2D", "cost maps: no topic in the model"),
        ("ReportNoGoZones", "no-go zones: no topic in the model"),
        ("CBRN4", "CBRN sensor family: no topic in the model"),
        ("RequestHandoff", "control handoff is the engine's operator arbitration"),
    )


