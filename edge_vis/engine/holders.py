"""Who holds JAUS control of each component, whether or not it is this relay. No I/O.

The relay knows its own control from ConfirmControl and RejectControl, but not who else
controls a component: another operator control unit, a local safety controller. Every
component with AccessControl answers QueryControl with the controlling client's address
and authority (zeros when nobody controls it) and QueryAuthority with its current
authority, in any state (AS5710 AccessControl, default state). The relay asks both when
the vehicle's services become known or it is found again, whenever its own control of the
vehicle changes (a request confirmed, preempted, released, an authority changed), and
every ``control.holder_query_period`` seconds in between; translators are told
``"control"`` when an answer changes what is known.
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
        """Ask again when due, or when the relay's own control changed."""
        state = self._state
        if not vehicle.online or not vehicle.services_known or state.shutting_down:
            return
        ours = (vehicle.times_lost, *sorted((a, c.state.value, c.authority)
                                            for a, c in vehicle.controls.items()))
        due = vehicle.next_holder_query is not None and now >= vehicle.next_holder_query
        if ours == vehicle.holders_asked_for and not due:
            return
        vehicle.holders_asked_for = ours
        period = state.profile.control.holder_query_period
        vehicle.next_holder_query = now + period if period > 0 else None
        for address in vehicle.providers(ACCESS_CONTROL):
            state.send(address, "QueryControl", {}, "control")
            state.send(address, "QueryAuthority", {}, "control")

    def on_control(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ReportControl from ``source``: its controlling client (zeros: none)."""
        ids = (int(pick(fields, "subsystem_id", 0)), int(pick(fields, "node_id", 0)),
               int(pick(fields, "component_id", 0)))
        controller = JausAddress(*ids) if any(ids) else None
        old = vehicle.holders.get(source) or HolderView(source)
        new = dataclasses.replace(
            old, controller=controller,
            authority=int(pick(fields, "authority_code", 0)) if controller else 0,
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
