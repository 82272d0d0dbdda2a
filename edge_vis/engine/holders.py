"""Who holds JAUS control of each component, whether or not it is this relay. No I/O.

The relay knows its own control from ConfirmControl and RejectControl, but not who else
controls a component: another operator control unit, a local safety controller. Every
component with AccessControl answers QueryControl with the controlling client's address
and authority (zeros when nobody controls it) and QueryAuthority with its current
authority, in any state (AS5710 AccessControl, default state). The relay asks every such
component when the vehicle's services become known or it is found again and every
``control.holder_query_period`` seconds, and a component at once when the relay loses
control of it (who took it?). Control the relay gains, or an authority it changes, is
recorded from ConfirmControl without asking. QueryAuthority goes only to components
nobody held when last asked: a controlled component's authority is its controller's,
which ReportControl carries. A slow radio thus carries little of it.
Translators are told ``"control"`` when an answer changes what is known.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from edge_vis.engine.discovery import CORE, pick
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import HolderView

ACCESS_CONTROL = CORE + "AccessControl"


class Holders:
    """Asks each component who controls it and keeps the answers on the vehicle."""

    def __init__(self, state: EngineState, changed: Changed) -> None:
        self._state = state
        self._changed = changed

    def poll(self, vehicle: Vehicle, now: float) -> None:
        """Ask every component when due (or first after found), a component at once when
        the relay lost it; record control the relay gained."""
        state = self._state
        if not vehicle.online or not vehicle.services_known or state.shutting_down:
            return
        ours = {a: (c.controlled, c.authority) for a, c in vehicle.controls.items()}
        due = (vehicle.next_holder_query is not None and now >= vehicle.next_holder_query) \
            or vehicle.holders_round != vehicle.times_lost
        if due:
            vehicle.holders_round = vehicle.times_lost
            period = state.profile.control.holder_query_period
            vehicle.next_holder_query = now + period if period > 0 else None
            asked = vehicle.providers(ACCESS_CONTROL)
        else:  # what changed: control gained is known from ConfirmControl, a loss is not
            asked = []
            for address, (controlled, authority) in ours.items():
                before = vehicle.holders_asked_for.get(address)
                if controlled and before != (controlled, authority):
                    self._store(vehicle, address, dataclasses.replace(
                        vehicle.holders.get(address) or HolderView(address),
                        controller=state.profile.jaus_id, authority=authority,
                        current_authority=authority, is_relay=True), now)
                elif before is not None and before[0] and not controlled:
                    asked.append(address)
        vehicle.holders_asked_for = ours
        for address in asked:
            state.send(address, "QueryControl", {}, "telemetry")
            # a controlled component's authority is its controller's, which ReportControl
            # carries: QueryAuthority only where nobody held it when last asked
            known = vehicle.holders.get(address)
            if known is None or known.controller is None:
                state.send(address, "QueryAuthority", {}, "telemetry")

    def on_control(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ReportControl from ``source``: its controlling client (zeros: none)."""
        ids = (int(pick(fields, "subsystem_id", 0)), int(pick(fields, "node_id", 0)),
               int(pick(fields, "component_id", 0)))
        controller = JausAddress(*ids) if any(ids) else None
        authority = int(pick(fields, "authority_code", 0)) if controller else 0
        old = vehicle.holders.get(source) or HolderView(source)
        new = dataclasses.replace(
            old, controller=controller, authority=authority,
            current_authority=authority if controller else old.current_authority,
            is_relay=controller == self._state.profile.jaus_id)
        self._store(vehicle, source, new, now)

    def on_authority(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                     now: float) -> None:
        """ReportAuthority from ``source``: the component's current authority."""
        old = vehicle.holders.get(source) or HolderView(source)
        new = dataclasses.replace(old, current_authority=int(pick(fields, "authority_code",
                                                                  0)))
        self._store(vehicle, source, new, now)

    def _store(self, vehicle: Vehicle, source: JausAddress, new: HolderView,
               now: float) -> None:
        if vehicle.holders.get(source) != new:
            vehicle.holders[source] = new
            self._changed(vehicle, "control", now)
