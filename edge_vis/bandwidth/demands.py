"""What the relay's vehicles want from each link, as planner input; the live plan. No I/O.

:func:`report_demand` prices one report of one vehicle (bytes per delivery from the
catalogue, rates and priority from the profiles); :func:`liveness_load` prices the
liveness traffic the engine sends whatever the plan. :class:`FleetPlanner` keeps the
current plan of every planned link for the engine: it is asked again whenever a vehicle
joins or leaves, a report falls back to polling or a link's measured rate changes, and
says which rates changed so the engine updates those events (and only those).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from edge_vis.bandwidth.linkspec import LinkSpec
from edge_vis.bandwidth.planner import FixedLoad, LinkPlan, ReportDemand, plan_link
from edge_vis.bandwidth.sizes import event_payload, packet_bytes, payload_size

if TYPE_CHECKING:
    from edge_vis.config import RelayProfile, VehicleProfile
    from edge_vis.kit.contract import ReportSpec

log = logging.getLogger(__name__)

#: payload bytes assumed for a message the catalogue does not know
UNKNOWN_PAYLOAD = 64
#: engine.STATUS_EVERY: status is queried every this many liveness periods
STATUS_EVERY = 5
#: characters assumed for a vehicle's identification string
NOMINAL_IDENTIFICATION = 16


class SizeSource:
    """Payload sizes from a catalogue (anything with ``by_name(name)``), cached."""

    def __init__(self, catalogue: Any) -> None:
        self._catalogue = catalogue
        self._cache: dict[tuple[str, int | None], int] = {}

    def payload(self, name: str, query_fields: Mapping[str, Any] | None = None) -> int:
        """Payload bytes of message ``name`` with the fields ``query_fields`` ask for."""
        pv = (query_fields or {}).get("presence_vector")
        key = (name, pv if isinstance(pv, int) else None)
        if key not in self._cache:
            try:
                defn = self._catalogue.by_name(name)
            except KeyError:
                log.warning("no definition of %s: assuming %d bytes", name, UNKNOWN_PAYLOAD)
                self._cache[key] = UNKNOWN_PAYLOAD
            else:
                self._cache[key] = payload_size(defn, query_fields)
        return self._cache[key]


def report_demand(vehicle_id: str, spec: ReportSpec, relay: RelayProfile,
                  vehicle: VehicleProfile | None, link: LinkSpec, sizes: SizeSource, *,
                  polled: bool = False) -> ReportDemand:
    """The demand of ``spec`` from ``vehicle_id`` on ``link``."""
    desired = min(relay.report_rate(spec.report, spec.rate, vehicle), 1092.0)
    report = sizes.payload(spec.report, spec.query_fields)
    query = sizes.payload(spec.query)
    if polled:
        report_bytes = packet_bytes(report, link.overhead, link.mtu)
        query_bytes = packet_bytes(query, link.overhead, link.mtu)
    else:
        report_bytes = packet_bytes(event_payload(report), link.overhead, link.mtu)
        query_bytes = 0
    return ReportDemand(
        vehicle_id, spec.report, desired, relay.report_minimum(spec.report, desired, vehicle),
        relay.report_priority(spec.report, vehicle), report_bytes, query_bytes, polled,
        spec.on_change)


def liveness_load(vehicle_id: str, relay: RelayProfile, link: LinkSpec,
                  components: int = 1) -> FixedLoad:
    """What keeping a vehicle known costs: QueryHeartbeatPulse/ReportHeartbeatPulse every
    liveness period to each of its ``components`` with Liveness, QueryStatus now and then,
    and its share of discovery (QueryIdentification / ReportIdentification)."""
    components = max(components, 1)
    period = relay.discovery.liveness_period
    query = packet_bytes(2, link.overhead, link.mtu)
    pulse = packet_bytes(2, link.overhead, link.mtu)
    status = packet_bytes(2 + 1 + 4, link.overhead, link.mtu)
    # heartbeat per component every period, status every STATUS_EVERY periods
    out = components * query * (1 + 1 / STATUS_EVERY) / period
    inbound = components * (pulse + status / STATUS_EVERY) / period
    # discovery: the broadcast QueryIdentification (shared) and this vehicle's answer
    ident = packet_bytes(2 + 2 + 2 + 1 + NOMINAL_IDENTIFICATION, link.overhead, link.mtu)
    inbound += ident / relay.discovery.period
    out += query / relay.discovery.period
    return FixedLoad("liveness", vehicle_id, inbound, out)


@dataclass(frozen=True, slots=True)
class VehicleWants:
    """A vehicle as the planner sees it: where it is and which reports it delivers how."""

    vehicle_id: str
    link: str
    profile: VehicleProfile | None
    reports: tuple[tuple[ReportSpec, bool], ...]  # (spec, polled)
    liveness_components: int = 1


def plan_fleet(relay: RelayProfile, links: Mapping[str, LinkSpec],
               vehicles: Iterable[VehicleWants], sizes: SizeSource) -> dict[str, LinkPlan]:
    """Plan every link of ``links`` for the vehicles behind it."""
    per_link: dict[str, list[ReportDemand]] = {name: [] for name in links}
    fixed: dict[str, list[FixedLoad]] = {name: [] for name in links}
    for v in vehicles:
        spec = links.get(v.link)
        if spec is None:
            continue
        fixed[v.link].append(liveness_load(v.vehicle_id, relay, spec,
                                           v.liveness_components))
        for report, polled in v.reports:
            per_link[v.link].append(report_demand(v.vehicle_id, report, relay, v.profile, spec,
                                                  sizes, polled=polled))
    return {name: plan_link(name, links[name], per_link[name], fixed[name]) for name in links}


class FleetPlanner:
    """The live plan of a relay's links (sans-I/O; the engine drives it).

    ``links`` maps link names to their medium; ``link_of(address)`` (from the router's
    address book) says on which link a vehicle was heard when its profile does not say.
    """

    def __init__(self, relay: RelayProfile, links: Mapping[str, LinkSpec], catalogue: Any,
                 link_of: Callable[[Any], str | None] | None = None) -> None:
        self.relay = relay
        self.links: dict[str, LinkSpec] = dict(links)
        self.sizes = SizeSource(catalogue)
        self.link_of = link_of
        self.plans: dict[str, LinkPlan] = {}
        self.replans = 0
        self._warned: set[str] = set()

    def link_for(self, profile_link: str, address: Any) -> str:
        """The planned link a vehicle sits behind ("" when none is planned)."""
        if profile_link:
            return profile_link if profile_link in self.links else ""
        if self.link_of is not None and address is not None:
            name = self.link_of(address)
            if name in self.links:
                return name
        planned = [n for n, s in self.links.items() if s.limited]
        return planned[0] if len(planned) == 1 and len(self.links) == 1 else ""

    def set_link_rate(self, link: str, bit_rate: float) -> bool:
        """A measured rate for ``link``; True when it changes the medium (re-plan)."""
        spec = self.links.get(link)
        if spec is None or abs(spec.bit_rate - bit_rate) < 1e-6 * max(bit_rate, 1.0):
            return False
        log.info("link %s: rate now %.0f bit/s (was %.0f): re-planning", link, bit_rate,
                 spec.bit_rate)
        self.links[link] = spec.with_rate(bit_rate)
        return True

    def plan(self, vehicles: Sequence[VehicleWants]) -> dict[str, LinkPlan]:
        """Plan again for ``vehicles``; log loudly what does not fit."""
        self.replans += 1
        self.plans = plan_fleet(self.relay, self.links, vehicles, self.sizes)
        for plan in self.plans.values():
            for warning in plan.warnings:
                if warning not in self._warned:
                    log.warning("%s", warning)
            self._warned = {w for p in self.plans.values() for w in p.warnings}
        return self.plans

    def rate(self, link: str, vehicle_id: str, report: str) -> float | None:
        """The planned rate, or None when the report is not planned."""
        plan = self.plans.get(link)
        return plan.rate(vehicle_id, report) if plan is not None else None
