"""The ``management`` translator: Management commands and the vehicle's clock. No I/O.

DDS -> JAUS: ``ManagementCommand {vehicle_id, operator_id, command, component}`` ->
Shutdown, Standby, Resume or Reset (AS5710 Management). The engine sends each only while
the operator holds the vehicle through the relay and the relay holds JAUS control of the
component (control is enough: Resume must reach a component in STANDBY); otherwise it is
refused, or expires, with the reason in ``ControlStatus.last_rejection``. It goes to every
component offering Management, or to the one ``component`` names (``S.N.C``). The relay
keeps an operator's Standby: it does not bring the component back to READY by itself
until the operator sends Resume (or releases the vehicle). Shutdown and Reset end the
component's control (it sends RejectControl); after a Reset the relay takes control again
once the component is available.

JAUS -> DDS: the engine reads each vehicle's clock (QueryTime) and this translator
publishes it as ``VehicleClock``: the offset from the relay's clock, the round trip it was
measured over, and how many SetTime the relay sent (``[time]`` in the profile).
"""

from __future__ import annotations

from typing import Any

from edge_vis.kit import Action, CommandRule, Publish, RuleTranslator, TranslatorContext

MANAGEMENT = "urn:jaus:jss:core:Management"

#: ManagementCommand.command -> the JAUS Management message
COMMANDS = {"SHUTDOWN": "Shutdown", "STANDBY": "Standby", "RESUME": "Resume",
            "RESET": "Reset"}


def _rule(command: str, message: str) -> CommandRule:
    return CommandRule(
        "ManagementCommand", message, MANAGEMENT, "management", {},
        when={"command": (command, f"MGMT_{command}")}, needs_ready=False,
        every_provider=True, component="component",
        doc="needs the operator's and the relay's control, not READY; to every Management "
            "component or `component` (S.N.C); refused in EMERGENCY")


def clock_sample(ctx: TranslatorContext) -> dict[str, Any] | None:
    """VehicleClock for the context's vehicle, None before its clock was read."""
    view = ctx.vehicle
    if view is None or view.clock is None:
        return None
    clock = view.clock
    return {"vehicle_id": view.vehicle_id, "component": str(clock.component),
            "offset_ms": clock.offset * 1000.0, "round_trip_ms": clock.round_trip * 1000.0,
            "set_time_sent": clock.set_time_sent, "note": clock.note,
            "timestamp_ms": ctx.timestamp_ms}


class ManagementTranslator(RuleTranslator):
    """Management commands from operators; the vehicles' clocks to DDS."""

    name = "management"
    command_rules = tuple(_rule(command, message) for command, message in COMMANDS.items())
    extra_publishes = ("VehicleClock",)

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        if change != "clock":
            return []
        sample = clock_sample(ctx)
        return [Publish("VehicleClock", sample)] if sample is not None else []

    def describe(self) -> list[dict[str, Any]]:
        """The command rules, and where VehicleClock comes from."""
        return [*super().describe(), {
            "translator": self.name, "direction": "jaus->dds", "message": "ReportTime",
            "topic": "VehicleClock", "query": "QueryTime", "service": "urn:jaus:jss:core:Time",
            "rate": None,
            "fields": [
                {"jaus": "time_stamp, date_stamp", "dds": "offset_ms",
                 "note": "vehicle minus relay, at the middle of the round trip"},
                {"jaus": "(query to report)", "dds": "round_trip_ms", "note": ""},
                {"jaus": "(source address)", "dds": "component", "note": "S.N.C"},
                {"jaus": "(SetTime sent)", "dds": "set_time_sent, note",
                 "note": "time.set_on_discovery above time.set_threshold"},
            ],
            "doc": "asked on discovery and every time.query_period s",
        }]
