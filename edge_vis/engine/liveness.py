"""Liveness of vehicles: seen, lost, found again, and what is (re)built on the way. No I/O.

Any message from a vehicle counts as a sign of life. Each liveness period the relay asks
what keeps it hearing from a quiet vehicle (QueryHeartbeatPulse where Liveness is offered,
QueryStatus where Management is, QueryIdentification otherwise, except of a vehicle found by
its hello or its messages: :mod:`~edge_vis.engine.announcements`); a vehicle silent for the
silence timeout is *lost*: its events, control and queued commands are dropped and
translators are told it is offline. The next message makes it *found*: control is asked
for again and its report subscriptions are set up again (:meth:`Liveness.setup`, also run
when its service tree becomes known).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from edge_vis.engine.discovery import CORE, MANAGEMENT
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle

if TYPE_CHECKING:
    from edge_vis.engine.access import Access
    from edge_vis.engine.reports import Reports

log = logging.getLogger(__name__)

LIVENESS = CORE + "Liveness"
#: Status is also queried every this many liveness periods on components with Liveness.
STATUS_EVERY = 5


class Liveness:
    """Tracks whether each vehicle is heard from, and acts on the changes."""

    def __init__(self, state: EngineState, changed: Changed, access: Access,
                 reports: Reports) -> None:
        self._state = state
        self._changed = changed
        self._access = access
        self._reports = reports

    def seen(self, vehicle: Vehicle, now: float) -> None:
        """A message from ``vehicle`` arrived: online again if it was not."""
        self._state.touch(vehicle)
        vehicle.last_seen = now
        if vehicle.online:
            return
        vehicle.online = True
        if vehicle.times_lost:
            log.info("vehicle %s found again", vehicle.vehicle_id)
            if not vehicle.services_known and vehicle.next_services_query is None:
                vehicle.next_services_query = vehicle.discovery.restart(now)
        self._changed(vehicle, "online", now)
        for address, ctl in vehicle.controls.items():
            self._state.send_outgoing(address, ctl.on_found(now))
        self.setup(vehicle, now)

    def setup(self, vehicle: Vehicle, now: float) -> None:
        """Subscriptions and control for an online vehicle whose services are known and
        which this relay serves."""
        state = self._state
        if state.shutting_down or not vehicle.online or not vehicle.services_known \
                or not state.serves(vehicle):
            return
        self._reports.setup(vehicle, now)
        self._access.update(vehicle, now)

    def lose(self, vehicle: Vehicle, now: float) -> None:
        """``vehicle`` was silent for the silence timeout (the timer pass checks): drop what
        it held; it is re-established when found."""
        state = self._state
        log.warning("vehicle %s lost: silent for %.1f s", vehicle.vehicle_id,
                    now - (vehicle.last_seen or now))
        vehicle.online = False
        vehicle.heard = vehicle.probes = 0
        vehicle.times_lost += 1
        vehicle.statuses.clear()
        vehicle.event_timeout_asked.clear()
        for ctl in vehicle.controls.values():
            ctl.on_lost()
        for sub in vehicle.subscriptions.values():
            sub.on_lost()
        for slot in vehicle.commands.values():
            state.counters["commands_dropped"] += slot.clear()
        state.counters["vehicles_lost"] += 1
        state.plan_dirty = True
        self._changed(vehicle, "offline", now)

    def probe(self, vehicle: Vehicle, now: float) -> None:
        """Ask ``vehicle`` for a sign of life (due at ``vehicle.next_liveness``)."""
        # a lost vehicle is still probed, but only once per discovery period: the radio
        # link's capacity belongs to the vehicles that answer
        state = self._state
        period = state.profile.discovery.liveness_period
        if vehicle.online:  # one bit of link quality per period (edge_vis.engine.serving)
            heard = vehicle.last_seen is not None and (
                vehicle.last_probe_at is None or vehicle.last_seen > vehicle.last_probe_at)
            vehicle.heard = ((vehicle.heard << 1) | int(heard)) & 0xFFFF
            vehicle.probes += 1
        vehicle.last_probe_at = now
        vehicle.next_liveness = now + (period if vehicle.online
                                       else max(period, state.profile.discovery.period))
        tick = int(now / period) if period > 0 else 0
        sent = False
        if vehicle.services_known:
            for address in sorted(vehicle.components):
                if vehicle.offers(address, LIVENESS):
                    state.send(address, "QueryHeartbeatPulse", {})
                    sent = True
                    if vehicle.offers(address, MANAGEMENT) and tick % STATUS_EVERY == 0:
                        state.send(address, "QueryStatus", {})
                elif vehicle.offers(address, MANAGEMENT):
                    state.send(address, "QueryStatus", {})
                    sent = True
        if not sent and vehicle.address is not None and vehicle.announced_by is None:
            # a vehicle found by its hello or its messages need not answer this: anything
            # it sends is its sign of life
            state.send(vehicle.address, "QueryIdentification", {"query_type": 2})
