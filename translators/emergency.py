"""The ``emergency`` translator: ``EmergencyCommand`` -> SetEmergency / ClearEmergency. No I/O.

A pure mapping: an operator's ``EmergencyCommand {vehicle_id, operator_id, action SET or
CLEAR, authority, reason}`` becomes an :class:`~edge_vis.kit.EmergencyRequest`. Who may
set and clear, delivery ahead of every other message, retransmission until the vehicle
confirms, remembering it for an offline vehicle and refusing motion meanwhile are the
engine's (``edge_vis.engine.estop``), the same for every vehicle.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import Action, EmergencyRequest, Translator, TranslatorContext

_ACTIONS = {0: "set", 1: "clear"}


def action_name(raw: Any) -> str:
    """``"set"``/``"clear"`` from the enum member, its name or its value."""
    if isinstance(raw, int):
        return _ACTIONS.get(raw, str(raw))
    return str(getattr(raw, "name", raw)).lower()


class EmergencyTranslator(Translator):
    """Management's emergency messages (AS5710) <- the ``EmergencyCommand`` topic."""

    name = "emergency"
    subscribes = ("EmergencyCommand",)

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        return [EmergencyRequest(
            vehicle_id=str(sample.get("vehicle_id", "")),
            operator_id=str(sample.get("operator_id", "")),
            action=action_name(sample.get("action", "set")),
            authority=int(sample.get("authority", 0) or 0),
            reason=str(sample.get("reason", "") or ""),
        )]

    def describe(self) -> list[dict[str, Any]]:
        """Mapping-table rows."""
        return [
            _row("SetEmergency", "action = SET",
                 "no control needed; to every Management (and IOP PlatformState) component, "
                 "ahead of every queue, sent again until ReportStatus says EMERGENCY; kept "
                 "for an offline vehicle; [emergency] set_by"),
            _row("ClearEmergency", "action = CLEAR",
                 "only what the relay set; sent again until no component reports "
                 "EMERGENCY, then Resume to READY before motion; [emergency] clear_by"),
        ]


def _row(message: str, dds: str, doc: str) -> dict[str, Any]:
    return {"translator": "emergency", "direction": "dds->jaus", "message": message,
            "topic": "EmergencyCommand", "query": "", "service": "urn:jaus:jss:core:Management",
            "rate": None,
            "fields": [{"jaus": "emergency_code", "dds": dds, "note": "STOP (1)"}],
            "doc": doc}
