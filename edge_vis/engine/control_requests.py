"""Operators asking for a vehicle: the ControlRequest topic, arbitrated. No I/O.

Operators take and give back a vehicle by publishing ControlRequest samples; which one
holds it is :class:`~edge_vis.engine.arbitration.Arbitration`'s decision, after the
profile's operator allowlist (:mod:`edge_vis.config.operators`) has had its say. When the
holder changes, the old holder's queued commands are void; whether the relay must hold
JAUS control follows from there being a holder at all
(:meth:`~edge_vis.engine.access.Access.update`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from edge_vis.engine.access import Access
from edge_vis.engine.state import Changed, EngineState

log = logging.getLogger(__name__)


class ControlRequests:
    """Applies operators' ControlRequest samples to each vehicle's arbitration."""

    def __init__(self, state: EngineState, access: Access, changed: Changed) -> None:
        self._state = state
        self._access = access
        self._changed = changed

    def on_sample(self, sample: Mapping[str, Any], now: float) -> None:
        """One ControlRequest sample (request or release) at ``now``."""
        state = self._state
        vehicle = state.by_id.get(str(sample.get("vehicle_id", "")))
        if vehicle is None:
            state.counters["control_requests_unknown_vehicle"] += 1
            return
        state.touch(vehicle)
        operator = str(sample.get("operator_id", ""))
        raw = sample.get("action", "request")
        # the enum's name ("REQUEST"/"RELEASE"), or its value (0/1)
        action = {0: "request", 1: "release"}.get(raw, str(raw)) if isinstance(raw, int) \
            else str(getattr(raw, "name", raw)).lower()
        arb = vehicle.arbitration
        previous = arb.holder
        if action == "release":
            decision = arb.release(operator)
        elif action == "request" and (refusal := state.profile.operators.refusal(
                operator, int(sample.get("authority", 0)))):
            # not in the profile's allowlist (edge_vis.config.operators): counted, logged, reported
            state.counters["control_requests_refused"] += 1
            if arb.last_rejection != refusal:
                log.warning("vehicle %s: control request %s", vehicle.vehicle_id, refusal)
            arb.last_rejection = refusal
            decision = None
        elif action == "request":
            decision = arb.request(operator, int(sample.get("authority", 0)))
        else:
            arb.last_rejection = f"unknown action {action!r} from {operator}"
            decision = None
        if decision is not None and decision.changed and (
            previous is None or arb.holder is None
            or previous.operator_id != arb.holder.operator_id
        ):
            for slot in vehicle.commands.values():  # the old holder's intent is void
                state.counters["commands_dropped"] += slot.clear()
        self._access.update(vehicle, now)
        self._changed(vehicle, "control", now)
