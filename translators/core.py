"""The ``core`` translator: vehicle identity, status, control status and heartbeat. No I/O.

Publishes, from the engine's view of each vehicle:

* ``VehicleIdentification`` when a vehicle is identified or its services change;
* ``VehicleStatus`` when it comes online, goes offline, on every ReportStatus and every
  ReportHeartbeatPulse (so ``last_seen_ms`` moves while the vehicle is alive);
* ``ControlStatus`` when operator arbitration or JAUS access control changes, including
  refused commands (``rejected_commands``, ``last_rejection``) and, per component with
  AccessControl, who controls it with which authority and whether that is this relay
  (``holders``, from the engine's QueryControl and QueryAuthority);
* both when an emergency stop is set, confirmed or cleared (``emergency``);
* all three when this relay starts serving the vehicle (``serving``, another relay
  served it before); ``VehicleStatus.relay`` names the relay serving it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import Action, Publish, Translator, TranslatorContext, VehicleView

#: ControlStatus.state for the relay's JAUS control while an operator holds the vehicle.
_HELD_STATES = {
    "controlled": "CONTROLLED",
    "requesting": "REQUESTED",
    "refused": "REJECTED",
    "releasing": "RELEASING",
    "none": "REQUESTED",
}


def identification_sample(view: VehicleView) -> dict[str, Any]:
    """VehicleIdentification for ``view``."""
    return {
        "vehicle_id": view.vehicle_id,
        "name": view.name,
        "jaus_subsystem": view.subsystem,
        "jaus_address": str(view.address) if view.address is not None else "",
        "vehicle_type": view.vehicle_type,
        "services": [{"uri": uri, "version": version} for uri, version in view.services],
    }


def status_sample(view: VehicleView) -> dict[str, Any]:
    """VehicleStatus for ``view``."""
    return {
        "vehicle_id": view.vehicle_id,
        "state": view.state,
        "link": view.link,
        "online": view.online,
        "last_seen_ms": view.last_seen_ms,
        "emergency": view.emergency,
        "emergency_operator": view.emergency_operator,
        "emergency_reason": view.emergency_reason,
        "relay": view.relay,
    }


def control_sample(view: VehicleView, timestamp_ms: int) -> dict[str, Any]:
    """ControlStatus for ``view``: NOT_CONTROLLED, or the holder and the relay's JAUS
    control state (REQUESTED, CONTROLLED, REJECTED by the vehicle, RELEASING)."""
    if view.controller:
        state = _HELD_STATES.get(view.jaus_control, view.jaus_control.upper())
    else:
        state = "RELEASING" if view.jaus_control == "releasing" else "NOT_CONTROLLED"
    return {
        "vehicle_id": view.vehicle_id,
        "operator_id": view.controller,
        "authority": view.controller_authority,
        "state": state,
        "rejected_commands": view.rejected_commands,
        "last_rejection": view.last_rejection,
        "timestamp_ms": timestamp_ms,
        "emergency": view.emergency,
        "holders": [{"component": str(h.component),
                     "controller": str(h.controller) if h.controller is not None else "",
                     "authority": h.authority, "current_authority": h.current_authority,
                     "is_relay": h.is_relay} for h in view.holders],
    }


class CoreTranslator(Translator):
    """Core service set (AS5710) -> vehicle identity, status and control topics."""

    name = "core"
    messages = ("ReportStatus", "ReportHeartbeatPulse")
    publishes = ("VehicleIdentification", "VehicleStatus", "ControlStatus")

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if ctx.vehicle is None:
            return []
        return [Publish("VehicleStatus", status_sample(ctx.vehicle))]

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        view = ctx.vehicle
        if view is None:
            return []
        if change == "identified":
            return [Publish("VehicleIdentification", identification_sample(view))]
        if change in ("online", "offline"):  # status changes arrive as ReportStatus
            return [Publish("VehicleStatus", status_sample(view))]
        if change == "control":
            return [Publish("ControlStatus", control_sample(view, ctx.timestamp_ms))]
        if change == "serving":  # this relay took the vehicle over: its state, afresh
            return [Publish("VehicleIdentification", identification_sample(view)),
                    Publish("VehicleStatus", status_sample(view)),
                    Publish("ControlStatus", control_sample(view, ctx.timestamp_ms))]
        if change == "emergency":
            return [Publish("VehicleStatus", status_sample(view)),
                    Publish("ControlStatus", control_sample(view, ctx.timestamp_ms))]
        return []

    def describe(self) -> list[dict[str, Any]]:
        """Mapping-table rows: what reaches these topics, through the engine's vehicle view."""
        return [_row(*row) for row in _ROWS]


#: (direction, JAUS message, DDS topic, [(JAUS field, DDS member, note)], query, doc)
_ROWS: tuple[tuple[str, str, str, list[tuple[str, str, str]], str, str], ...] = (
    ("jaus->dds", "ReportIdentification", "VehicleIdentification",
     [("identification", "name", "as reported"), ("type", "vehicle_type", "VEHICLE, OCU, ..."),
      ("(source address)", "jaus_subsystem, jaus_address", "")],
     "QueryIdentification", "broadcast by discovery; vehicle_id = profile id or name-subsystem"),
    ("jaus->dds", "ReportServices", "VehicleIdentification",
     [("node_list[].component_list[].service_list[]", "services[] (uri, version)",
       "major.minor; inherited core services added")], "QueryServices", ""),
    ("jaus->dds", "ReportStatus", "VehicleStatus",
     [("status", "state", "INITIALIZE, READY, STANDBY, SHUTDOWN, FAILURE, EMERGENCY")],
     "QueryStatus", "also online/offline and last_seen_ms from liveness"),
    ("jaus->dds", "ReportHeartbeatPulse", "VehicleStatus",
     [("(arrival)", "online, last_seen_ms", "")], "QueryHeartbeatPulse", "liveness"),
    ("jaus->dds", "ConfirmControl", "ControlStatus",
     [("response_code", "state", "0 -> CONTROLLED, else REJECTED")], "",
     "answer to the relay's RequestControl"),
    ("jaus->dds", "RejectControl", "ControlStatus",
     [("response_code", "state", "control lost -> REQUESTED again or NOT_CONTROLLED")], "", ""),
    ("jaus->dds", "ReportControl", "ControlStatus",
     [("subsystem_id, node_id, component_id", "holders[].controller", "S.N.C, '' when none"),
      ("authority_code", "holders[].authority", ""),
      ("(controller == relay id)", "holders[].is_relay", "")], "QueryControl",
     "every component with AccessControl (or IOP EnhancedAccessControl): on discovery, "
     "when the relay loses control of it, every control.holder_query_period s"),
    ("jaus->dds", "ReportAuthority", "ControlStatus",
     [("authority_code", "holders[].current_authority", "")], "QueryAuthority", ""),
    ("dds->jaus", "SetAuthority", "ControlRequest",
     [("authority_code", "authority", "capped at relay.authority")], "",
     "control.authority_from_operator: the holder lowers its authority (raising it "
     "sends RequestControl)"),
    ("dds->jaus", "RequestControl", "ControlRequest",
     [("authority_code", "(relay authority)", "when an operator wins arbitration")], "",
     "one operator at a time; higher authority preempts; renewed before the timeout"),
    ("dds->jaus", "ReleaseControl", "ControlRequest",
     [("", "action = release", "when the last operator releases")], "", ""),
)


def _row(direction: str, message: str, topic: str, fields: list[tuple[str, str, str]],
         query: str, doc: str) -> dict[str, Any]:
    return {"translator": "core", "direction": direction, "message": message, "topic": topic,
            "query": query, "service": "", "rate": None,
            "fields": [{"jaus": j, "dds": d, "note": n} for j, d, n in fields], "doc": doc}
