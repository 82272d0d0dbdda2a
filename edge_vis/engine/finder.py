"""Finding vehicles: identification, the service tree, the vehicle table. No I/O.

The relay broadcasts QueryIdentification(2) every discovery period; a subsystem that
answers becomes a vehicle, and is then asked QueryConfiguration and QueryServices until
its service tree is known. Which queries a round sends, and whether an answer is taken
as complete (JAUS++ answers the wildcard QueryServices with an empty list), is the
vehicle's :class:`~edge_vis.engine.discovery.ServiceDiscovery`'s decision; this module
feeds it the answers and sends what it asks for. A message from a subsystem not yet
identified gets a rate-limited QueryIdentification of its own. Vehicles may also be
declared without discovery: static ones from the profile at start, and custom ones by a
translator (DeclareVehicle). This module keeps the vehicle table.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

from edge_vis.engine.discovery import (
    IDENTIFICATION_TYPES,
    Component,
    Query,
    components_from_configuration,
    services_from_report,
)
from edge_vis.engine.liveness import Liveness
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.kit.contract import derive_vehicle_id

log = logging.getLogger(__name__)


def _component(address: JausAddress) -> Component:
    return address.node, address.component


class Finder:
    """Discovers vehicles and their service trees, and keeps the vehicle table."""

    def __init__(self, state: EngineState, changed: Changed, liveness: Liveness) -> None:
        self._state = state
        self._changed = changed
        self._liveness = liveness
        self.started = False
        #: when the next broadcast QueryIdentification is due
        self.next_discovery: float | None = None
        #: unidentified subsystem -> when it may be probed again
        self.probed: dict[int, float] = {}

    def start(self, now: float) -> None:
        """First input: discovery starts now; static vehicles of the profile are declared."""
        if self.started:
            return
        self.started = True
        self.next_discovery = now
        for vp in self._state.profile.vehicles:
            if vp.is_static:
                components = {c.address: tuple((s.uri, s.version) for s in c.services)
                              for c in vp.components}
                self.declare(vp.vehicle_id, components, vp.name, vp.vehicle_type, now,
                             seen=False)

    def broadcast(self, now: float) -> None:
        """Broadcast QueryIdentification when the discovery period has come."""
        if self.next_discovery is not None and now >= self.next_discovery:
            self.next_discovery = now + self._state.profile.discovery.period
            self._state.send(BROADCAST, "QueryIdentification", {"query_type": 2})

    def declare(self, vehicle_id: str, components: Mapping[JausAddress, Sequence[tuple[str, str]]],
                name: str, vehicle_type: str, now: float, *, seen: bool) -> Vehicle | None:
        """A vehicle whose components and services are given, not discovered."""
        state = self._state
        if not components:
            return None
        subsystem = next(iter(components)).subsystem
        if subsystem == state.profile.jaus_id.subsystem:
            log.warning("vehicle %s declared in the relay's own subsystem: ignored", vehicle_id)
            return None
        vehicle = state.vehicles.get(subsystem)
        if vehicle is None and len(state.vehicles) >= state.profile.limits.max_vehicles:
            state.counters["vehicles_refused_table_full"] += 1
            return None
        if vehicle is None:
            vehicle = self._add_vehicle(subsystem, vehicle_id, now)
        before = (vehicle.name, vehicle.vehicle_type, vehicle.address, dict(vehicle.components))
        vehicle.static = True
        vehicle.name = name or vehicle.name or vehicle_id
        vehicle.vehicle_type = vehicle_type or vehicle.vehicle_type
        vehicle.address = vehicle.address or min(components)
        for address, services in components.items():
            vehicle.set_services(address, list(services))
        vehicle.services_known = True
        vehicle.discovery.stop()
        vehicle.next_services_query = None
        if (vehicle.name, vehicle.vehicle_type, vehicle.address, vehicle.components) != before:
            self._changed(vehicle, "identified", now)
        if seen:
            self._liveness.seen(vehicle, now)
        self._liveness.setup(vehicle, now)
        return vehicle

    def _add_vehicle(self, subsystem: int, vehicle_id: str, now: float) -> Vehicle:
        state = self._state
        profile = state.profile.vehicle_by_subsystem(subsystem)
        if profile is not None:
            vehicle_id = profile.vehicle_id
        if vehicle_id in state.by_id:  # two subsystems reporting the same name
            vehicle_id = f"{vehicle_id}-{subsystem}"
        vehicle = Vehicle(subsystem, vehicle_id, profile)
        if profile is not None:
            vehicle.name = profile.name
            vehicle.vehicle_type = profile.vehicle_type
        vehicle.next_liveness = now + state.profile.discovery.liveness_period
        state.vehicles[subsystem] = vehicle
        state.by_id[vehicle_id] = vehicle
        log.info("vehicle %s (subsystem %d) discovered", vehicle_id, subsystem)
        return vehicle

    def on_identification(self, source: JausAddress, fields: Mapping[str, Any],
                          now: float) -> Vehicle | None:
        """ReportIdentification: the sender's subsystem is (or stays) a vehicle."""
        state = self._state
        if source.subsystem == state.profile.jaus_id.subsystem:
            return None
        ident = str(fields.get("identification", "") or "")
        vehicle = state.vehicles.get(source.subsystem)
        if vehicle is None and len(state.vehicles) >= state.profile.limits.max_vehicles:
            state.counters["vehicles_refused_table_full"] += 1
            return None
        if vehicle is None:
            vehicle = self._add_vehicle(source.subsystem,
                                        derive_vehicle_id(ident, source.subsystem), now)
        changed = False
        # JTS answers every QueryIdentification with a subsystem (type 2) report; a
        # component-level answer (JAUS++, query type 4) does not rename the vehicle.
        if fields.get("query_type", 2) == 2 and ident and not (
            vehicle.profile is not None and vehicle.profile.name
        ):
            changed = vehicle.name != ident
            vehicle.name = ident
            kind = IDENTIFICATION_TYPES.get(int(fields.get("type", 0) or 0), "")
            if kind and not (vehicle.profile is not None and vehicle.profile.vehicle_type):
                vehicle.vehicle_type = kind
        elif ident and not vehicle.name:  # a node or component name beats none
            vehicle.name = ident
            changed = True
        vehicle.discovery.on_identification(ident, state.counters)
        if vehicle.address is None:
            vehicle.address = source
            changed = True
        if not vehicle.services_known and vehicle.next_services_query is None:
            vehicle.next_services_query = vehicle.discovery.start(now)
        if changed:
            self._changed(vehicle, "identified", now)
        return vehicle

    def probe_unknown(self, source: JausAddress, now: float) -> None:
        """A message from an unidentified subsystem: ask who it is (rate-limited)."""
        state = self._state
        state.counters["messages_unidentified"] += 1
        if source.subsystem == state.profile.jaus_id.subsystem or state.shutting_down:
            return
        limit = state.profile.limits.max_unidentified
        due = self.probed.get(source.subsystem, 0.0)
        if now >= due and source.subsystem not in self.probed and len(self.probed) >= limit:
            # bounded: forget expired probes first, else ignore this stranger (counted)
            self.probed = {k: v for k, v in self.probed.items() if v > now}
            if len(self.probed) >= limit:
                state.counters["probes_skipped_table_full"] += 1
                return
        if now >= due:
            self.probed[source.subsystem] = now + state.profile.discovery.response_timeout
            state.send(source, "QueryIdentification", {"query_type": 2})

    def query_services(self, vehicle: Vehicle, now: float) -> None:
        """A discovery round is due (see :class:`~edge_vis.engine.discovery.ServiceDiscovery`)."""
        if vehicle.address is None:
            vehicle.next_services_query = None
            return
        state = self._state
        self._discovery_sends(vehicle, vehicle.discovery.next_round(
            _component(vehicle.address), now, state.profile.discovery, state.counters))

    def _discovery_sends(self, vehicle: Vehicle, queries: Sequence[Query]) -> None:
        """Send discovery's queries to the component that identified the vehicle."""
        if vehicle.address is not None:
            for name, fields in queries:
                self._state.send(vehicle.address, name, fields)
        vehicle.next_services_query = vehicle.discovery.next_at

    def on_services(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                    now: float) -> None:
        """ReportServices: record the tree; subscribe and take control as needed."""
        state = self._state
        changed = False
        report = services_from_report(fields)
        for (node, comp), services in report.items():
            address = JausAddress(vehicle.subsystem, node, comp)
            changed |= vehicle.set_services(address, services)
        if not vehicle.static and vehicle.address is not None:
            self._discovery_sends(vehicle, vehicle.discovery.on_services(
                report, _component(vehicle.address), now, state.profile.discovery,
                state.counters))
        # an empty answer proves nothing (JAUS++ reads the wildcards literally)
        first = not vehicle.services_known and (vehicle.static or vehicle.discovery.known)
        vehicle.services_known = vehicle.services_known or first
        if changed or first:
            self._changed(vehicle, "identified", now)
        self._liveness.setup(vehicle, now)

    def on_configuration(self, vehicle: Vehicle, source: JausAddress,
                         fields: Mapping[str, Any], now: float) -> None:
        """ReportConfiguration: the components whose services discovery must learn."""
        if not vehicle.static and vehicle.address is not None:
            state = self._state
            self._discovery_sends(vehicle, vehicle.discovery.on_configuration(
                components_from_configuration(fields), _component(vehicle.address), now,
                state.profile.discovery, state.counters))
