"""IOP and UGV services of a simulated UGV (``iop = true``): the component side. No I/O.

A fourth component, ``Iop`` (component 4), offers what an operator station reaches through
the ``iop``, ``costmap``, ``cbrn`` and ``ugv`` translators:

* EnhancedAccessControl: a JAUS client that does not control the component asks for it
  with RequestHandoff; the component queues it (ConfirmHandoffRequest QUEUED) and asks its
  controller with RequestReleaseControl, which answers with ConfirmReleaseControl:
  GRANTED moves control to the requester (RejectControl to the old controller,
  ConfirmHandoffRequest GRANTED to the new), DENIED and WAIT are passed on (DENIED,
  DEFERRED); a request still open after the hand-off timeout is answered TIMEOUT.
  QueryHandoffTimeout/QueryEnhancedTimeout are answered;
* CostMap2D over the yard the range sensor sees (posts no-go, outside the wall unknown),
  no-go zones added and removed by the controller (local x/y or lat/lon vertices);
* SkidSteerDriver and AckermannDriver driving the same kinematic model as the primitive
  driver; illumination, annunciator, drive-train capabilities; a battery power plant that
  runs down; a CBRN payload (one station) with state, configuration and CBRN4 reports;
  DigitalResourceDiscovery with a camera stream endpoint and register/remove.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from edge_vis.jaus.address import JausAddress
from edge_vis.tools.sim.components import CORE, TRANSPORT, ComponentSpec
from edge_vis.tools.sim.kinematics import clamp

IOP = "urn:jaus:jss:iop:"
UGV = "urn:jaus:jss:ugv:"
ENHANCED_ACCESS_CONTROL = IOP + "EnhancedAccessControl"
COSTMAP = IOP + "CostMap2D"
CBRN = IOP + "CBRNSensor"
RESOURCES = IOP + "DigitalResourceDiscovery"
SKID_STEER = UGV + "SkidSteerDriver"
ACKERMANN = UGV + "AckermannDriver"
ILLUMINATION = UGV + "IlluminationService"
ANNUNCIATOR = UGV + "AnnunciatorService"
DRIVE_TRAIN = UGV + "DriveTrainDriver"
POWER_PLANT = UGV + "PowerPlantManager"

COMPONENT = ComponentSpec(4, "Iop", (
    TRANSPORT, CORE + "Events", CORE + "AccessControl", CORE + "Management", CORE + "Liveness",
    ENHANCED_ACCESS_CONTROL, COSTMAP, CBRN, RESOURCES, SKID_STEER, ACKERMANN, ILLUMINATION,
    ANNUNCIATOR, DRIVE_TRAIN, POWER_PLANT))

#: hand-off timeout the component reports and applies, s
HANDOFF_TIMEOUT = 20
#: cells per side of the cost map, and their size (m)
CELLS, CELL = 20, 4.0
#: ConfirmHandoffRequest response codes
GRANTED, NOT_AVAILABLE, TIMEOUT, DENIED, QUEUED, DEFERRED = 0, 1, 2, 3, 4, 5


@dataclass
class Handoff:
    """One queued RequestHandoff."""

    request_id: int
    source: JausAddress
    authority: int
    explanation: str
    since: float


@dataclass
class IopState:
    """What the Iop component keeps between messages."""

    zones: dict[int, dict[str, Any]] = field(default_factory=dict)
    next_zone: int = 1
    handoffs: list[Handoff] = field(default_factory=list)
    next_request: int = 0
    skid: dict[str, float] = field(default_factory=lambda: {
        "left_side_propulsive_effort": 0.0, "right_side_propulsive_effort": 0.0})
    ackermann: dict[str, float] = field(default_factory=lambda: {
        "steering_angle": 0.0, "throttle_effort": 0.0, "brake_effort": 0.0})
    cbrn: dict[str, Any] = field(default_factory=lambda: {
        "power_mode": 1, "operating_mode": 0, "sampling_state": 1})
    endpoints: dict[int, dict[str, Any]] = field(default_factory=lambda: {1: {
        "server_type": 0, "server_url": "rtsp://127.0.0.1:8554/front"}})
    next_endpoint: int = 2


def state(vehicle: Any) -> IopState:
    """The vehicle's Iop state (made on first use)."""
    found = getattr(vehicle, "iop_state", None)
    if found is None:
        found = vehicle.iop_state = IopState()
    return found  # type: ignore[no-any-return]


def send(vehicle: Any, comp: Any, to: JausAddress, name: str,
         fields: dict[str, Any]) -> list[Any]:
    return vehicle._send(comp, to, name, fields)  # type: ignore[no-any-return]


# -- hand-off (EnhancedAccessControl) ----------------------------------------------------


def expire(vehicle: Any, comp: Any, now: float) -> list[Any]:
    """Requests open longer than the hand-off timeout: answered TIMEOUT."""
    iop, out = state(vehicle), []
    for h in [h for h in iop.handoffs if now - h.since >= HANDOFF_TIMEOUT]:
        iop.handoffs.remove(h)
        out += send(vehicle, comp, h.source, "ConfirmHandoffRequest",
                    {"id": h.request_id, "response_code": TIMEOUT})
    return out


def _ask_controller(vehicle: Any, comp: Any) -> list[Any]:
    iop = state(vehicle)
    if comp.controller is None or not iop.handoffs:
        return []
    return send(vehicle, comp, comp.controller, "RequestReleaseControl", {
        "request_release_control_list": [{
            "id": h.request_id, "src_subsystem_id": h.source.subsystem,
            "src_node_id": h.source.node, "src_component_id": h.source.component,
            "authority_code": h.authority, "explanation": h.explanation}
            for h in iop.handoffs]})


def request_handoff(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                    now: float) -> list[Any]:
    """RequestHandoff: queued and passed to the controller, or refused."""
    iop = state(vehicle)
    out = expire(vehicle, comp, now)
    if comp.controller is None:  # control is free: RequestControl instead
        return out + send(vehicle, comp, source, "ConfirmHandoffRequest",
                          {"id": 0, "response_code": DENIED})
    if comp.controller == source:
        comp.authority = fields.get("authority_code", comp.authority)
        return out + send(vehicle, comp, source, "ConfirmHandoffRequest",
                          {"id": 0, "response_code": GRANTED})
    if fields.get("authority_code", 0) < comp.default_authority:
        return out + send(vehicle, comp, source, "ConfirmHandoffRequest",
                          {"id": 0, "response_code": 6})  # INSUFFICIENT_AUTHORITY
    queued = next((h for h in iop.handoffs if h.source == source), None)
    if queued is None:
        iop.next_request = iop.next_request % 255 + 1
        queued = Handoff(iop.next_request, source, 0, "", now)
        iop.handoffs.append(queued)
    queued.authority = int(fields.get("authority_code", 0))
    queued.explanation = str(fields.get("explanation", ""))
    vehicle.counters["handoffs_requested"] += 1
    return out + send(vehicle, comp, source, "ConfirmHandoffRequest",
                      {"id": queued.request_id, "response_code": QUEUED}) \
        + _ask_controller(vehicle, comp)


def remove_handoff(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                   now: float) -> list[Any]:
    """RemoveHandoffRequest: the requester withdraws."""
    iop = state(vehicle)
    iop.handoffs = [h for h in iop.handoffs if h.source != source]
    return send(vehicle, comp, source, "ConfirmHandoffRequest",
                {"id": int(fields.get("id", 0)), "response_code": DENIED}) \
        + _ask_controller(vehicle, comp)


def confirm_release(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                    now: float) -> list[Any]:
    """ConfirmReleaseControl from the controller: grant, deny or defer each request."""
    iop = state(vehicle)
    if source != comp.controller:
        return []
    out = expire(vehicle, comp, now)
    for answer in fields.get("release_control_list") or []:
        h = next((h for h in iop.handoffs if h.request_id == answer.get("id")), None)
        if h is None:
            continue
        code = int(answer.get("response_code", 1))
        if code == 0:  # GRANTED: the requester controls the component from now on
            out += vehicle._lose_control(comp, f"handed off to {h.source}")
            comp.controller, comp.authority, comp.control_renewed = h.source, h.authority, now
            iop.handoffs.remove(h)
            out += send(vehicle, comp, h.source, "ConfirmHandoffRequest",
                        {"id": h.request_id, "response_code": GRANTED})
            for other in list(iop.handoffs):  # at most one is granted
                iop.handoffs.remove(other)
                out += send(vehicle, comp, other.source, "ConfirmHandoffRequest",
                            {"id": other.request_id, "response_code": DENIED})
            vehicle.counters["handoffs_granted"] += 1
            break
        if code == 1:
            iop.handoffs.remove(h)
        out += send(vehicle, comp, h.source, "ConfirmHandoffRequest",
                    {"id": h.request_id, "response_code": DENIED if code == 1 else DEFERRED})
    return out


# -- cost map and no-go zones ---------------------------------------------------------------


def cost_map(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    """The yard: posts and no-go zones at 254, the rest free, outside the wall unknown."""
    posts = ((15.0, 5.0, 1.0), (-8.0, 12.0, 1.5))
    costs = []
    half = CELLS * CELL / 2
    for row in range(CELLS):
        y = half - (row + 0.5) * CELL
        for col in range(CELLS):
            x = -half + (col + 0.5) * CELL
            cost = 0
            if math.hypot(x, y) > 40.0:
                cost = 255
            elif any(math.hypot(x - px, y - py) < r + CELL / 2 for px, py, r in posts) or \
                    any(_inside(x, y, z) for z in state(vehicle).zones.values()):
                cost = 254
            costs.append({"cost": cost})
    return {"cost_map2_d_rec": {"number_of_rows": CELLS, "number_of_columns": CELLS,
                                "map_width": CELLS * CELL, "map_height": CELLS * CELL},
            "cost_map2_d_pose_var": {"cost_map2_d_local_pose_rec": {
                "map_center_x": 0.0, "map_center_y": 0.0, "map_rotation": 0.0}},
            "cost_map2_d_data_var": {"cost_data_list": costs}}


def _inside(x: float, y: float, zone: dict[str, Any]) -> bool:
    points = [(p["x"], p["y"]) for p in zone.get("local_vertex_list") or []]
    hit = False
    for (x1, y1), (x2, y2) in zip(points, points[1:] + points[:1], strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            hit = not hit
    return hit


def add_zone(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
             now: float) -> list[Any]:
    """AddNoGoZone from the controller: stored, its new id answered."""
    if not vehicle._commanding(comp, source, "AddNoGoZone"):
        return []
    iop = state(vehicle)
    zone_id, iop.next_zone = iop.next_zone, iop.next_zone + 1
    iop.zones[zone_id] = dict(fields["vertex_var"])
    return send(vehicle, comp, source, "AddNoGoZoneResponse", {
        "request_id": fields["request_id_rec"]["request_id"], "response_code": 0,
        "zone_id": zone_id})


def remove_zone(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                now: float) -> list[Any]:
    """RemoveNoGoZone from the controller."""
    if vehicle._commanding(comp, source, "RemoveNoGoZone"):
        state(vehicle).zones.pop(int(fields.get("zone_id", 0)), None)
    return []


def no_go_zones(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    wanted = int(fields.get("zone_id", 0))
    return {"no_go_zones_list": [{"zone_id_rec": {"zone_id": z}, "vertex_var": v}
                                 for z, v in state(vehicle).zones.items()
                                 if wanted in (0, z)]}


# -- drivers ----------------------------------------------------------------------------------


def set_skid_steer(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                   now: float) -> list[Any]:
    """SetSkidSteerEffort: track efforts drive the kinematic model."""
    if not vehicle._commanding(comp, source, "SetSkidSteerEffort"):
        return []
    left = float(fields["left_side_propulsive_effort"])
    right = float(fields["right_side_propulsive_effort"])
    state(vehicle).skid = dict(fields)
    vehicle.waypoints.stop()
    vehicle.motion.command(vehicle.spec.max_speed * (left + right) / 200.0,
                           vehicle.spec.max_yaw_rate * (right - left) / 200.0)
    vehicle.counters["commands_obeyed"] += 1
    return []


def set_ackermann(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                  now: float) -> list[Any]:
    """SetAckermannConfiguration: throttle less brake sets the speed, steering the turn."""
    if not vehicle._commanding(comp, source, "SetAckermannConfiguration"):
        return []
    state(vehicle).ackermann = {k: float(fields[k]) for k in (
        "steering_angle", "throttle_effort", "brake_effort")}
    speed = vehicle.spec.max_speed * max(0.0, fields["throttle_effort"]
                                         - fields["brake_effort"]) / 100.0
    vehicle.waypoints.stop()
    vehicle.motion.command(speed, clamp(speed * math.tan(fields["steering_angle"]) / 1.5,
                                        -vehicle.spec.max_yaw_rate,
                                        vehicle.spec.max_yaw_rate))
    vehicle.counters["commands_obeyed"] += 1
    return []


def power_plant(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    """One battery, running down 0.1 %/s from 95 %."""
    charge = clamp(95.0 - 0.1 * (vehicle._now - vehicle._start), 5.0, 100.0)
    return {"power_plant_status_list": [{
        "power_plant_desc_rec": {"power_plant_id": 1, "description": "main battery"},
        "power_plant_status_var": {"battery_status": [{
            "percent_charge_remaining": charge, "voltage": 22.0 + charge / 25.0,
            "current_draw": 8.5, "battery_temp": 31.0}]}}]}


# -- CBRN and digital resources ----------------------------------------------------------------


def cbrn_operating(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    cbrn = state(vehicle).cbrn
    return {"station_number": 1, "payload_state": 3 if cbrn["power_mode"] else 4,
            "operating_mode": cbrn["operating_mode"], "sampling_state": cbrn["sampling_state"],
            "battery_remaining": 88.0}


def cbrn_configuration(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    return {"station_number": 1, "product_name": "SimCAD", "identifier": "SIM-1",
            "sw_firmware_version": "1.0", "payload_cbrn_type": 0,
            "power_mode": state(vehicle).cbrn["power_mode"]}


def cbrn4(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    return {"station_number": 1, "detection_type": 0, "cbrn4_report_id": 1,
            "cbrn4": "ALFA/SIM-1//BRAVO/NIL//"}


def cbrn_command(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                 now: float) -> list[Any]:
    """CBRNCommand from the controller: power, operating and sampling modes."""
    if vehicle._commanding(comp, source, "CBRNCommand"):
        cbrn = state(vehicle).cbrn
        for key, name in (("set_power_mode", "power_mode"),
                          ("set_operating_mode", "operating_mode")):
            if key in fields:
                cbrn[name] = int(fields[key])
        if "set_sampling_mode" in fields:
            cbrn["sampling_state"] = 1 if fields["set_sampling_mode"] == 1 else 0
    return []


def endpoints(vehicle: Any, comp: Any, fields: dict[str, Any]) -> dict[str, Any]:
    return {"digital_resource_endpoint_list": [
        {**e, "resource_id": i} for i, e in state(vehicle).endpoints.items()]}


def register_endpoint(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Any]:
    iop = state(vehicle)
    endpoint_id, iop.next_endpoint = iop.next_endpoint, iop.next_endpoint + 1
    record = fields["digital_resource_endpoint_rec"]
    iop.endpoints[endpoint_id] = {"server_type": record["server_type"],
                                  "server_url": record["server_url"]}
    return send(vehicle, comp, source, "ConfirmDigitalResourceEndpoint",
                {"id": endpoint_id, "request_id": fields["request_id_rec"]["request_id"]})


def remove_endpoint(vehicle: Any, comp: Any, source: JausAddress, fields: dict[str, Any],
                    now: float) -> list[Any]:
    state(vehicle).endpoints.pop(int(fields.get("id", 0)), None)
    return send(vehicle, comp, source, "ConfirmDigitalResourceEndpoint",
                {"id": int(fields.get("id", 0)), "request_id": int(fields.get("request_id", 0))})


def _const(body: dict[str, Any]) -> Any:
    return lambda vehicle, comp, fields: body


#: message -> (service, handler), merged into the sim's handler table
HANDLERS: dict[str, tuple[str, Any]] = {
    "RequestHandoff": (ENHANCED_ACCESS_CONTROL, request_handoff),
    "RemoveHandoffRequest": (ENHANCED_ACCESS_CONTROL, remove_handoff),
    "ConfirmReleaseControl": (ENHANCED_ACCESS_CONTROL, confirm_release),
    "AddNoGoZone": (COSTMAP, add_zone),
    "RemoveNoGoZone": (COSTMAP, remove_zone),
    "SetSkidSteerEffort": (SKID_STEER, set_skid_steer),
    "SetAckermannConfiguration": (ACKERMANN, set_ackermann),
    "CBRNCommand": (CBRN, cbrn_command),
    "RegisterDigitalResourceEndpoint": (RESOURCES, register_endpoint),
    "RemoveDigitalResourceEndpoint": (RESOURCES, remove_endpoint),
}

#: query -> (service, report, builder), merged into the sim's query table
QUERIES: dict[str, tuple[str, str, Any]] = {
    "QueryHandoffTimeout": (ENHANCED_ACCESS_CONTROL, "ReportHandoffTimeout",
                            _const({"timeout": HANDOFF_TIMEOUT})),
    "QueryEnhancedTimeout": (ENHANCED_ACCESS_CONTROL, "ReportEnhancedTimeout",
                             _const({"timeout": 0})),
    "QueryCostMap2D": (COSTMAP, "ReportCostMap2D", cost_map),
    "QueryNoGoZones": (COSTMAP, "ReportNoGoZones", no_go_zones),
    "QuerySkidSteerEffort": (SKID_STEER, "ReportSkidSteerEffort",
                             lambda v, c, f: dict(state(v).skid)),
    "QueryAckermannConfiguration": (ACKERMANN, "ReportAckermannConfiguration",
                                    lambda v, c, f: dict(state(v).ackermann)),
    "QueryIlluminationConfiguration": (ILLUMINATION, "ReportIlluminationConfiguration",
                                       _const({"types": {"headlights": 1, "brake_lights": 1,
                                                         "ir_light_source": 1}})),
    "QueryAnnunciatorConfiguration": (ANNUNCIATOR, "ReportAnnunciatorConfiguration",
                                      _const({"types": {"horn": 1, "backup": 1}})),
    "QueryTransmissionCapabilities": (DRIVE_TRAIN, "ReportTransmissionCapabilities",
                                      _const({"transmission_bf": {"park": 1, "neutral": 1,
                                                                  "reverse": 1, "drive": 1},
                                              "transfer_case_bf": {"fwd": 1}})),
    "QueryPowerPlantStatus": (POWER_PLANT, "ReportPowerPlantStatus", power_plant),
    "QueryCBRNOperatingState": (CBRN, "CBRNOperatingState", cbrn_operating),
    "QueryCBRNConfiguration": (CBRN, "CBRNConfigurationState", cbrn_configuration),
    "QueryCBRN4": (CBRN, "CBRN4", cbrn4),
    "QueryDigitalResourceEndpoint": (RESOURCES, "ReportDigitalResourceEndpoint", endpoints),
}
