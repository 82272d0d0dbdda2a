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

* the engine's hand-off requests (IOP EnhancedAccessControl, HandoffController: operators
  asking the holder over ``HandoffRequest``, other JAUS clients through the vehicle's
  RequestReleaseControl, operators asking a vehicle another JAUS client holds and its
  ConfirmHandoffRequest) -> ``HandoffStatus``, whenever one is made, answered or times out;
* ConfirmDigitalResourceEndpoint -> ``RequestResult`` (the endpoint ID the vehicle gave).

DDS -> JAUS (behind control, throttled): ``PlatformCommand`` -> SetPlatformState and/or
SetPlatformMode (an empty member leaves it unchanged), UpdateUGVSummary when
``update_health``; ``DigitalResourceCommand`` ->
RegisterDigitalResourceEndpoint or RemoveDigitalResourceEndpoint. ``HandoffRequest`` and
``HandoffResponse`` are read by the engine (operator arbitration), which answers the
vehicle with ConfirmReleaseControl.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    Action,
    Build,
    Computed,
    Const,
    Each,
    From,
    Publish,
    Put,
    ReportRule,
    RuleTranslator,
    TranslatorContext,
    VehicleView,
    code_of,
    label,
)
from edge_vis.kit import CommandRule as Cmd

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


def _address(text: Any) -> dict[str, int]:
    """``"S.N.C"`` -> the JAUS ID bit field of an endpoint."""
    parts = [int(p) for p in str(text).split(".")]
    if len(parts) != 3:
        raise ValueError(f"jaus_address {text!r} is not S.N.C")
    return {"subsystem_id": parts[0], "node_id": parts[1], "component_id": parts[2]}


def _endpoint(sample: Mapping[str, Any]) -> dict[str, Any]:
    """The endpoint record of a REGISTER: URL, server type, optional JAUS ID and resource."""
    url = str(sample.get("url") or "")
    if not url:
        raise ValueError("REGISTER needs a url")
    record: dict[str, Any] = {"server_type": code_of(SERVER_TYPES)(
        sample.get("server_type") or "RTSP"), "server_url": url}
    if sample.get("jaus_address"):
        record["jaus_id"] = _address(sample["jaus_address"])
    if int(sample.get("resource_id", -1)) >= 0:
        record["resource_id"] = int(sample["resource_id"])
    return record


def handoff_sample(view: VehicleView, timestamp_ms: int) -> dict[str, Any]:
    """HandoffStatus for ``view``: the holder, the timeouts and every request."""
    return {"vehicle_id": view.vehicle_id, "holder": view.controller,
            "handoff_timeout": view.handoff_timeout,
            "reassert_timeout": view.handoff_reassert_timeout,
            "vehicle_handoff_timeout": view.vehicle_handoff_timeout,
            "requests": [{"request_id": h.request_id, "requester": h.requester,
                          "authority": h.authority, "explanation": h.explanation,
                          "state": h.state, "reason": h.reason, "via": h.via}
                         for h in view.handoffs],
            "timestamp_ms": timestamp_ms}


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
                   query="QueryUGVSummary", service=HEALTH, rate=1.0, on_change=True,
                   merge=True, doc="merged with the battery of the ugv translator's "
                                   "power plant rule"),
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
        ReportRule("ConfirmDigitalResourceEndpoint", "RequestResult",
                   {"request": Const("DigitalResourceEndpoint"),
                    "request_id": From("request_id"), "id": From("id"),
                    "result": Const("CONFIRMED")}, keys=("request",),
                   doc="the answer to RegisterDigitalResourceEndpoint (and Remove): the "
                       "endpoint ID"),
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
        Cmd("PlatformCommand", "UpdateUGVSummary", HEALTH, "health_update", {},
            when={"update_health": True}, doc="the health monitor refreshes its summary"),
        Cmd("DigitalResourceCommand", "RegisterDigitalResourceEndpoint",
            IOP + "DigitalResourceDiscovery", "digital_resource",
            {"request_id_rec.request_id": Put("request_id", 0, 255, convert=int),
             "digital_resource_endpoint_rec": Build(
                 "url, server_type, jaus_address, resource_id", _endpoint,
                 "server type by name; jaus_address S.N.C and resource_id >= 0 optional")},
            when={"action": "REGISTER"}),
        Cmd("DigitalResourceCommand", "RemoveDigitalResourceEndpoint",
            IOP + "DigitalResourceDiscovery", "digital_resource",
            {"id": Put("endpoint_id", convert=int),
             "request_id": Put("request_id", 0, 255, convert=int)},
            when={"action": "REMOVE"}),
    )
    extra_publishes = ("HandoffStatus",)
    not_translated = (
        ("ReportHeartbeatPulse", "unsolicited heartbeats keep the vehicle alive in the "
                                 "engine; VehicleStatus comes from the core translator"),
        ("ReportPathReporterCapabilities", "path limits: not exposed"),
        ("QueryPathReporterCapabilities", "asks for ReportPathReporterCapabilities, which is "
                                          "not exposed"),
    )

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        """HandoffStatus whenever a hand-off request or the holder changes."""
        view = ctx.vehicle
        if view is None or change not in ("handoff", "control"):
            return []
        if change == "control" and not view.handoffs:
            return []
        return [Publish("HandoffStatus", handoff_sample(view, ctx.timestamp_ms))]

    def describe(self) -> list[dict[str, Any]]:
        """The rule rows, and the hand-off the engine decides and this translator shows."""
        return [*super().describe(), *(_row(*row) for row in HANDOFF_ROWS)]


#: (direction, JAUS message, DDS topic, [(JAUS field, DDS member, note)], query, doc)
HANDOFF_ROWS: tuple[tuple[str, str, str, list[tuple[str, str, str]], str, str], ...] = (
    ("jaus->dds", "RequestReleaseControl", "HandoffStatus",
     [("request_release_control_list[].src_*_id", "requests[].requester", "jaus:S.N.C"),
      ("authority_code", "requests[].authority", ""),
      ("explanation", "requests[].explanation", ""),
      ("(sending component)", "requests[].via", "")], "",
     "another JAUS client asks the vehicle's EnhancedAccessControl for control: the "
     "holding operator sees the request (HandoffController)"),
    ("dds->jaus", "ConfirmReleaseControl", "HandoffResponse",
     [("release_control_list[].id", "request_id", "the vehicle's request ID"),
      ("response_code", "response", "GRANTED, DENIED, WAIT")], "",
     "only the holder's answer to a request made through the vehicle; GRANTED leaves the "
     "vehicle to the other client"),
    ("dds->jaus", "RequestHandoff", "HandoffRequest",
     [("authority_code", "authority", ""), ("explanation", "explanation", "")], "",
     "an operator asks for a vehicle nobody here holds but another JAUS client does: sent "
     "to its components with EnhancedAccessControl held by that client, again each time "
     "the operator asks again"),
    ("dds->jaus", "RemoveHandoffRequest", "HandoffRequest",
     [("id", "(the vehicle's request ID)", "action = CANCEL")], "", ""),
    ("jaus->dds", "ConfirmHandoffRequest", "HandoffStatus",
     [("response_code", "requests[].state", "QUEUED -> PENDING, DEFERRED, GRANTED, "
                                            "DENIED, TIMEOUT, NOT_AVAILABLE, "
                                            "INSUFFICIENT_AUTHORITY"),
      ("id", "(kept for RemoveHandoffRequest)", "")], "",
     "GRANTED: the requester holds the vehicle here and the relay confirms its control"),
    ("jaus->dds", "ReportHandoffTimeout", "HandoffStatus",
     [("timeout", "vehicle_handoff_timeout", "s; requests through the vehicle lapse after "
                                             "it")], "QueryHandoffTimeout",
     "asked once when a vehicle with EnhancedAccessControl is found"),
    ("jaus->dds", "ReportEnhancedTimeout", "HandoffStatus",
     [("timeout", "(recorded)", "s")], "QueryEnhancedTimeout",
     "asked once when a vehicle with EnhancedAccessControl is found"),
)


def _row(direction: str, message: str, topic: str, fields: list[tuple[str, str, str]],
         query: str, doc: str) -> dict[str, Any]:
    return {"translator": "iop", "direction": direction, "message": message, "topic": topic,
            "query": query, "service": IOP + "EnhancedAccessControl", "rate": None,
            "fields": [{"jaus": j, "dds": d, "note": n} for j, d, n in fields], "doc": doc}


