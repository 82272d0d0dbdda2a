"""Access control and management of a vehicle's commanded components. No I/O.

The JAUS machine for one component is :class:`~edge_vis.engine.control.ComponentControl`;
this module runs those machines for a whole vehicle: it decides which components must be
controlled (those offering a service some translator commands, while an operator holds
the vehicle, and those of the relay's own errands such as SetTime), with which authority
(the relay's, or the holding operator's with ``control.authority_from_operator``), feeds
them ConfirmControl, RejectControl, ReportTimeout and ReportStatus,
polls their timers, and tells translators when the vehicle's control summary changes.
ReportStatus is handled here too because management readiness gates control: a vehicle
in EMERGENCY drops queued motion commands.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping
from typing import Any

from edge_vis.engine.control import ComponentControl, ControlState
from edge_vis.engine.discovery import pick
from edge_vis.engine.liveness import MANAGEMENT
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress

log = logging.getLogger(__name__)

def jaus_control(vehicle: Vehicle) -> str:
    """One word for the vehicle's JAUS control: the worst state any wanted component is in."""
    states = {c.state for c in vehicle.controls.values()
              if not c.errand and (c.wanted or c.state is not ControlState.IDLE)}
    if not states:
        return "none"
    for state in (ControlState.REFUSED, ControlState.REQUESTING, ControlState.RELEASING):
        if state in states:
            return state.value
    return "controlled" if states == {ControlState.CONTROLLED} else "none"


class Access:
    """Keeps (or releases) control of every component a vehicle's commands go to."""

    def __init__(self, state: EngineState, controlled_services: Iterable[str],
                 changed: Changed) -> None:
        self._state = state
        self._controlled_services = sorted(controlled_services)
        self._changed = changed

    def update(self, vehicle: Vehicle, now: float) -> None:
        """Want control while an operator holds the online, known vehicle (and of the
        components of the relay's own errands); release the rest."""
        state = self._state
        usable = (vehicle.online and vehicle.services_known and not state.shutting_down
                  and state.serves(vehicle))
        operated = vehicle.arbitration.holder is not None and usable
        authority = self.authority(vehicle)
        commanded: set[JausAddress] = set()
        if operated:
            for uri in self._controlled_services:
                commanded.update(vehicle.providers(uri))
        errands = vehicle.errands if usable else set()
        for address in sorted(commanded | errands):
            if address not in vehicle.controls:
                vehicle.controls[address] = ComponentControl(
                    state.profile.control, authority, vehicle.offers(address, MANAGEMENT))
        before = jaus_control(vehicle)
        for address, ctl in vehicle.controls.items():
            ctl.errand = address in errands and address not in commanded
            state.send_outgoing(address, ctl.set_authority(authority, now))
            state.send_outgoing(address, ctl.want(address in commanded or ctl.errand, now))
        if jaus_control(vehicle) != before:
            self._changed(vehicle, "control", now)

    def authority(self, vehicle: Vehicle) -> int:
        """The authority the relay holds ``vehicle``'s components with: its own, or with
        ``control.authority_from_operator`` the holding operator's, capped at its own."""
        profile = self._state.profile
        holder = vehicle.arbitration.holder
        if profile.control.authority_from_operator and holder is not None:
            return min(holder.authority, profile.authority)
        return profile.authority

    def release(self, vehicle: Vehicle, now: float) -> None:
        """The relay is stopping: release every component (translators are not told)."""
        for address, ctl in vehicle.controls.items():
            self._state.send_outgoing(address, ctl.want(False, now))

    def poll(self, vehicle: Vehicle, now: float) -> None:
        """Renewals, retries and readiness attempts that are due."""
        if not vehicle.controls:  # the usual case on the report path: nothing to do
            return
        before = jaus_control(vehicle)
        for address, ctl in vehicle.controls.items():
            self._state.send_outgoing(address, ctl.poll(now))
        if jaus_control(vehicle) != before:
            self._changed(vehicle, "control", now)

    def on_confirm(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ConfirmControl from ``source``."""
        ctl = vehicle.controls.get(source)
        if ctl is None:
            return
        code = int(pick(fields, "response_code", 0))
        before = ctl.state
        self._state.send_outgoing(source, ctl.on_confirm(code, now))
        if ctl.state is not before:
            if code != 0:
                log.warning("vehicle %s component %s refused control (code %d)",
                            vehicle.vehicle_id, source, code)
            self._changed(vehicle, "control", now)

    def on_reject(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                  now: float) -> None:
        """RejectControl from ``source``: control ended."""
        ctl = vehicle.controls.get(source)
        if ctl is None:
            return
        before = ctl.state
        self._state.send_outgoing(source,
                                  ctl.on_reject(int(pick(fields, "response_code", 0)), now))
        if ctl.state is not before:
            self._changed(vehicle, "control", now)

    def on_timeout(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ReportTimeout from ``source``: renew control within it."""
        ctl = vehicle.controls.get(source)
        if ctl is not None:
            ctl.on_timeout_report(int(pick(fields, "timeout", 0)), now)

    def on_status(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                  now: float) -> None:
        """ReportStatus from ``source``: the vehicle's state, readiness for commands."""
        state = self._state
        status = int(pick(fields, "status", 0))
        before = vehicle.state_name()
        vehicle.statuses[source] = status
        ctl = vehicle.controls.get(source)
        if ctl is not None:
            state.send_outgoing(source, ctl.on_status(status, now))
        if vehicle.in_emergency() and (dropped := vehicle.drop_motion()):
            state.counters["commands_dropped"] += dropped
        if vehicle.state_name() != before:
            self._changed(vehicle, "status", now)
