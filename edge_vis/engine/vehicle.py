"""Per-vehicle state shared by every translator: tree, liveness, control, events, commands.

No I/O. One :class:`Vehicle` per JAUS subsystem lives in the engine; translators only see
a read-only :class:`~edge_vis.kit.contract.VehicleView` of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from edge_vis.config import VehicleProfile
from edge_vis.engine.arbitration import Arbitration, Handoffs
from edge_vis.engine.command_slots import CommandSlot
from edge_vis.engine.control import ComponentControl
from edge_vis.engine.discovery import Service, ServiceDiscovery, with_inherited
from edge_vis.engine.estop import Estop
from edge_vis.engine.subscriptions import Subscription
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import STATUS_NAMES, ClockView, HolderView

#: Most severe first: the vehicle's state is the most severe of its components'.
_SEVERITY = (5, 4, 3, 0, 2, 1)


@dataclass
class Vehicle:
    """Everything the engine knows and keeps about one subsystem."""

    subsystem: int
    vehicle_id: str
    profile: VehicleProfile | None = None
    name: str = ""
    vehicle_type: str = ""
    #: the component that answered identification (usually the discovery component)
    address: JausAddress | None = None
    static: bool = False
    #: component -> services as reported (plus inherited ones)
    components: dict[JausAddress, tuple[Service, ...]] = field(default_factory=dict)
    #: what discovery asked and learned (configuration, answers, retries)
    discovery: ServiceDiscovery = field(default_factory=ServiceDiscovery)
    services_known: bool = False
    next_services_query: float | None = None
    online: bool = False
    last_seen: float | None = None
    next_liveness: float | None = None
    statuses: dict[JausAddress, int] = field(default_factory=dict)
    controls: dict[JausAddress, ComponentControl] = field(default_factory=dict)
    subscriptions: dict[tuple[JausAddress, str], Subscription] = field(default_factory=dict)
    commands: dict[str, CommandSlot] = field(default_factory=dict)
    arbitration: Arbitration = field(default_factory=Arbitration)
    #: IOP hand-off requests to the holder (:mod:`edge_vis.engine.handoff_requests`)
    handoffs: Handoffs = field(default_factory=Handoffs)
    #: the hand-off and re-assert timeouts its EnhancedAccessControl reports (s; None:
    #: not known), and ``times_lost`` when they were asked since found
    handoff_timeouts: tuple[float | None, float | None] = (None, None)
    handoff_round: int = -1
    event_timeout_asked: set[JausAddress] = field(default_factory=set)
    request_counter: int = 0
    times_lost: int = 0
    #: component -> who controls it, as it last reported (ReportControl, ReportAuthority)
    holders: dict[JausAddress, HolderView] = field(default_factory=dict)
    next_holder_query: float | None = None
    #: ``times_lost`` when every component was last asked (a new round after found)
    holders_round: int = -1
    #: per component, (controlled, authority) of the relay when it was last asked
    holders_asked_for: dict[JausAddress, tuple[bool, int]] = field(default_factory=dict)
    #: the latest clock reading, when a QueryTime went out to which component
    clock: ClockView | None = None
    time_asked: dict[JausAddress, float] = field(default_factory=dict)
    next_time_query: float | None = None
    #: ``times_lost`` when the clock was first asked since found; QueryTime sent since
    time_round: int = -1
    time_attempts: int = 0
    #: ``times_lost`` when the clock was first read since found (SetTime is decided then)
    clock_epoch: int = -1
    #: components the relay holds control of for an errand of its own (SetTime)
    errands: set[JausAddress] = field(default_factory=set)
    set_time_sent: int = 0
    #: the discovery profile that declared it from its hello or first message, if any
    announced_by: VehicleProfile | None = None
    #: the emergency stop set through the relay, until cleared (:mod:`edge_vis.engine.estop`)
    estop: Estop | None = None
    #: this relay serves it (events, control, commands, samples); with one relay, always
    #: (:mod:`edge_vis.engine.duty` decides when several relays share a DDS domain)
    serving: bool = False
    #: one bit per liveness period, newest lowest: heard from in that period
    heard: int = 0
    probes: int = 0
    last_probe_at: float | None = None
    #: when commands for it arrived while another relay served it (newest last, bounded)
    not_sent_at: list[float] = field(default_factory=list)
    #: (services, the dialects they were recognised as): recognised once per change
    dialect_cache: tuple[tuple[Service, ...], tuple[str, ...]] | None = None

    def __post_init__(self) -> None:
        self.discovery.label = self.vehicle_id

    def silence_timeout(self, default: float) -> float:
        """Seconds of silence before it is lost: its discovery profile's, or ``default``."""
        found = self.announced_by.discovery if self.announced_by is not None else None
        return found.silence_timeout if found is not None and found.silence_timeout \
            else default

    def next_request_id(self) -> int:
        """A fresh CreateEvent/CancelEvent request ID (u8, wraps)."""
        self.request_counter = (self.request_counter + 1) % 256
        return self.request_counter

    def set_services(self, address: JausAddress, services: list[Service]) -> bool:
        """Record ``address``'s services; True when something changed."""
        merged = with_inherited([*self.components.get(address, ()), *services])
        changed = self.components.get(address) != merged
        self.components[address] = merged
        return changed

    def providers(self, uri: str) -> list[JausAddress]:
        """Components offering service ``uri`` (listed or inherited), lowest address first."""
        return sorted(a for a, services in self.components.items()
                      if any(u == uri for u, _ in services))

    def offers(self, address: JausAddress, uri: str) -> bool:
        """True when component ``address`` offers ``uri``."""
        return any(u == uri for u, _ in self.components.get(address, ()))

    def all_services(self) -> tuple[Service, ...]:
        """Distinct services over all components."""
        seen: dict[str, str] = {}
        for services in self.components.values():
            for uri, version in services:
                seen.setdefault(uri, version)
        return tuple(sorted(seen.items()))

    def state_name(self) -> str:
        """OFFLINE, the most severe component status, or UNKNOWN."""
        if not self.online:
            return "OFFLINE"
        present = set(self.statuses.values())
        for code in _SEVERITY:
            if code in present:
                return STATUS_NAMES[code]
        return "UNKNOWN"

    def in_emergency(self) -> bool:
        """True when an emergency stop set through the relay is in force (until every
        component confirmed its clearing) or any component reports EMERGENCY or FAILURE."""
        return self.estop is not None or any(s in (4, 5) for s in self.statuses.values())

    def drop_motion(self) -> int:
        """Drop every queued motion command (nothing queued may move a vehicle in
        emergency); returns how many were dropped."""
        return sum(slot.clear() for slot in self.commands.values()
                   if slot.pending is not None and slot.pending.command.stop is not None)
