"""The relay's decision core: discovery, per-vehicle state, translation. No I/O, no clock.

Theory of operation
-------------------
The :class:`Engine` is driven like aioquic's ``QuicConnection``: the runtime hands it
decoded JAUS messages (:meth:`Engine.receive_message`), DDS samples
(:meth:`Engine.receive_sample`) and timer wake-ups (:meth:`Engine.on_timer`), each with the
current time ``now`` in seconds; the engine never reads a clock and never sleeps. After
each call the runtime collects :meth:`Engine.drain_actions` (messages to send, samples to
publish) and re-arms its timer at :meth:`Engine.next_deadline`::

    engine = Engine(profile)
    loop:   receive_message(src, msg, now) | receive_sample(topic, sample, now) | on_timer(now)
            for action in engine.drain_actions(): carry it out
            arm timer at engine.next_deadline()
    shutdown(now) ... on_timer(now) ... until ShutdownComplete is drained

Per vehicle (one JAUS subsystem) the engine keeps, once for all translators: the
component/service tree (:mod:`~edge_vis.engine.discovery`), liveness and the silence timer,
JAUS access control and readiness of the commanded components
(:mod:`~edge_vis.engine.control`), event subscriptions with polling fallback
(:mod:`~edge_vis.engine.subscriptions`), command throttles and the dead-man
(:mod:`~edge_vis.engine.command_slots`) and operator arbitration
(:mod:`~edge_vis.engine.arbitration`).

A vehicle silent for ``discovery.lost_after`` liveness periods is *lost*: its events,
control and queued commands are dropped and ``VehicleStatus`` says offline. Any message
from it later makes it *found* again; events and control are re-established by themselves.

Messages are decoded values (anything with ``name`` and ``fields``, e.g. the catalogue's
``Message``). Only two payloads are bytes: the query inside CreateEvent and the report
inside Event; the engine encodes/decodes those through the catalogue it was given.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from edge_vis.bandwidth.demands import FleetPlanner, VehicleWants
from edge_vis.config import RelayProfile
from edge_vis.engine.command_slots import CommandSlot
from edge_vis.engine.control import ComponentControl, ControlState, Outgoing
from edge_vis.engine.discovery import (
    CORE,
    IDENTIFICATION_TYPES,
    Component,
    Query,
    components_from_configuration,
    pick,
    services_from_report,
)
from edge_vis.engine.manager import TranslationManager
from edge_vis.engine.subscriptions import Request, Subscription, SubscriptionState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.kit.actions import (
    Action,
    Command,
    DeclareVehicle,
    Publish,
    SendMessage,
    ShutdownComplete,
)
from edge_vis.kit.contract import Translator, TranslatorContext, VehicleView, derive_vehicle_id

log = logging.getLogger(__name__)

LIVENESS = CORE + "Liveness"
MANAGEMENT = CORE + "Management"
#: Status is also queried every this many liveness periods on components with Liveness.
STATUS_EVERY = 5


class InnerCodec(Protocol):
    """What the engine needs from the catalogue: the payloads nested in events."""

    def encode(self, name_or_code: str | int, fields: Mapping[str, Any]) -> bytes: ...

    def decode(self, payload: bytes) -> Any: ...


@dataclass(frozen=True, slots=True)
class SubscriptionView:
    """Status of one report subscription, for status displays."""

    provider: JausAddress
    report: str
    state: str
    rate: float
    event_id: int | None
    events_received: int
    reason: str
    events_missed: int = 0


@dataclass(frozen=True, slots=True)
class VehicleSnapshot:
    """A vehicle with its subscriptions and per-component control states."""

    view: VehicleView
    subscriptions: tuple[SubscriptionView, ...]
    controls: Mapping[JausAddress, str]


@dataclass(frozen=True, slots=True)
class EngineSnapshot:
    """Read-only status of the whole engine."""

    vehicles: tuple[VehicleSnapshot, ...]
    counters: Mapping[str, int] = field(default_factory=dict)
    shutting_down: bool = False


class Engine:
    """The sans-I/O relay core (see the module docstring for the call protocol).

    ``translators`` defaults to the installed ones the profile enables. ``catalogue``
    (default: :func:`edge_vis.catalogue.default_catalogue`) encodes the query inside
    CreateEvent and decodes the report inside Event. ``wall_offset`` is added to ``now``
    to stamp samples with wall-clock time (``time.time() - loop.time()`` for a monotonic
    runtime clock; 0 when ``now`` already is POSIX time).
    """

    def __init__(
        self,
        profile: RelayProfile,
        translators: Sequence[Translator] | TranslationManager | None = None,
        *,
        catalogue: InnerCodec | None = None,
        wall_offset: float = 0.0,
        planner: FleetPlanner | None = None,
    ) -> None:
        self.profile = profile
        #: plans report rates to fit the links' budgets (None: the profiles' rates as is)
        self.planner = planner
        self._plan_dirty = False
        if isinstance(translators, TranslationManager):
            self.manager = translators
        elif translators is not None:
            self.manager = TranslationManager(translators)
        else:
            self.manager = TranslationManager.from_selection(profile.translators)
        self._catalogue = catalogue
        self.wall_offset = wall_offset
        self.counters: Counter[str] = Counter()
        self.vehicles: dict[int, Vehicle] = {}
        self._by_id: dict[str, Vehicle] = {}
        self._actions: list[Action] = []
        self._started = False
        self._next_discovery: float | None = None
        self._probed: dict[int, float] = {}
        self._shutting_down = False
        self._shutdown_deadline: float | None = None
        self._done = False
        self._controlled_services = self.manager.controlled_services()
        self._dropped: set[tuple[str, str]] = set()
        # The timer pass visits every vehicle; an input only changes the vehicles it
        # touches, so between deadlines only those are visited (see _run).
        #: the name of the link a JAUS address is reached over (the runtime asks its
        #: router); vehicle profiles that name their link take precedence
        self.link_of: Callable[[JausAddress], str] = lambda _address: ""
        self._touched: dict[int, Vehicle] = {}
        self._vehicle_due: float | None = None
        self._due_valid = False
        self._vehicle_count = 0

    # == public API =======================================================================

    def receive_message(self, source: JausAddress, message: Any, now: float) -> None:
        """A decoded JAUS message from ``source`` arrived at ``now``."""
        self._start(now)
        if self._done or source == self.profile.jaus_id:
            return
        name = getattr(message, "name", None)
        fields = getattr(message, "fields", None) or {}
        if name is None:
            self.counters["messages_unknown"] += 1
            return
        self.counters["messages_received"] += 1
        if name == "ReportIdentification":
            vehicle = self._on_identification(source, fields, now)
        else:
            vehicle = self.vehicles.get(source.subsystem)
        if vehicle is None:
            # a custom hello: a translator may declare the vehicle from it
            if self.manager.handles(name):
                ctx = self._context(None, now, source)
                self._apply(self.manager.on_message(name, fields, ctx), now)
                if source.subsystem in self.vehicles:
                    self._seen(self.vehicles[source.subsystem], now)
                    self._run(now)
                    return
            self._probe_unknown(source, now)
            self._run(now)
            return
        self._seen(vehicle, now)
        if name == "Event":
            self._on_event(vehicle, source, fields, now)
        else:
            self._handle(vehicle, source, name, fields, now)
        self._run(now)

    def receive_sample(self, topic: str, sample: Mapping[str, Any], now: float) -> None:
        """A DDS sample (as a dict) of ``topic`` arrived at ``now``."""
        self._start(now)
        if self._done:
            return
        self.counters["samples_received"] += 1
        if topic == "ControlRequest":
            self._on_control_request(sample, now)
        else:
            vehicle = self._by_id.get(str(sample.get("vehicle_id", "")))
            ctx = self._context(vehicle, now)
            self._apply(self.manager.on_sample(topic, sample, ctx), now)
        self._run(now)

    def on_timer(self, now: float) -> None:
        """The timer armed at :meth:`next_deadline` fired (early or late calls are fine)."""
        self._start(now)
        self._run(now)

    def next_deadline(self) -> float | None:
        """When :meth:`on_timer` must next be called; None when nothing is scheduled."""
        if self._done:
            return None
        if not self._started:
            return 0.0
        times: list[float | None] = [self._shutdown_deadline]
        if not self._shutting_down:
            times.append(self._next_discovery)
        if not self._due_valid:
            self._vehicle_due = self._earliest(self.vehicles.values())
            self._due_valid = True
        times.append(self._vehicle_due)
        real = [t for t in times if t is not None]
        return min(real) if real else None

    def _earliest(self, vehicles: Iterable[Vehicle]) -> float | None:
        """The earliest deadline of any of ``vehicles``."""
        times: list[float | None] = []
        silence = self.profile.discovery.silence_timeout
        for v in vehicles:
            if not self._shutting_down:
                times.append(v.next_liveness)
                times.append(v.next_services_query)
                if v.online and v.last_seen is not None:
                    times.append(v.last_seen + silence + 1e-6)
                for key, slot in v.commands.items():
                    times.append(slot.next_deadline(self._can_send(v, key)))
            times.extend(c.next_deadline() for c in v.controls.values())
            times.extend(s.next_deadline() for s in v.subscriptions.values())
        real = [t for t in times if t is not None]
        return min(real) if real else None

    def drain_actions(self) -> list[Action]:
        """Everything the engine wants done since the last call, in order."""
        actions, self._actions = self._actions, []
        return actions

    def shutdown(self, now: float) -> None:
        """Say goodbye: cancel events and release control, then report ShutdownComplete.

        Completion is reported once every CancelEvent and ReleaseControl is answered, or
        after the response timeout.
        """
        self._start(now)
        if self._shutting_down:
            return
        self._shutting_down = True
        for vehicle in self.vehicles.values():
            for sub in vehicle.subscriptions.values():
                self._send_requests(sub.provider, sub.cancel(now))
            for address, ctl in vehicle.controls.items():
                self._send_outgoing(address, ctl.want(False, now))
            for slot in vehicle.commands.values():
                slot.clear()
        self._shutdown_deadline = now + max(self.profile.control.response_timeout,
                                            self.profile.events.response_timeout)
        self._run(now)

    @property
    def is_shut_down(self) -> bool:
        """True once ShutdownComplete has been emitted."""
        return self._done

    def snapshot(self, now: float | None = None) -> EngineSnapshot:
        """Read-only status of every vehicle, subscription and counter."""
        vehicles = []
        for v in self.vehicles.values():
            subs = tuple(
                SubscriptionView(s.provider, s.report, s.state.value, s.rate, s.event_id,
                                 s.events_received, s.reason, s.events_missed)
                for s in v.subscriptions.values()
            )
            controls = {a: c.state.value for a, c in v.controls.items()}
            vehicles.append(VehicleSnapshot(self._view(v), subs, controls))
        return EngineSnapshot(tuple(vehicles), dict(self.counters), self._shutting_down)

    def vehicle(self, vehicle_id: str) -> Vehicle | None:
        """The live state of ``vehicle_id`` (for tests and diagnostics; do not mutate)."""
        return self._by_id.get(vehicle_id)

    def apply_profile(self, profile: RelayProfile, now: float) -> list[str]:
        """Take a reloaded profile while vehicles run; return what could not be applied.

        Report rates, event/command/control timing, authority and vehicle profiles reach
        running vehicles: a subscription whose rate changes asks its provider again
        (CreateEvent for the same query updates the event; a polled report is polled at
        the new rate); control and command settings hold from the next request. The
        caller keeps the relay's id, links, DDS and translators unchanged (see
        :func:`edge_vis.shell.reload.effective_profile`). A vehicle profile that would rename a
        running vehicle is not applied (its DDS key would change under the operators).
        """
        self.profile = profile
        not_applied: list[str] = []
        defaults = {spec.report: spec.rate for _tr, spec in self.manager.wanted_reports()}
        for vehicle in self.vehicles.values():
            vp = profile.vehicle_by_subsystem(vehicle.subsystem)
            if vp is not None and vp.vehicle_id != vehicle.vehicle_id:
                not_applied.append(f"vehicle {vehicle.vehicle_id}: the profile now calls "
                                   f"subsystem {vehicle.subsystem} {vp.vehicle_id!r}")
            else:
                vehicle.profile = vp
            for sub in vehicle.subscriptions.values():
                sub.profile = profile.events
                if self.planner is not None:
                    continue  # the planner decides the rates (below)
                rate = min(profile.report_rate(sub.report, defaults.get(sub.report, sub.rate),
                                               vehicle.profile), 1092.0)
                if rate != sub.rate:
                    log.info("vehicle %s: %s at %g Hz (was %g)", vehicle.vehicle_id,
                             sub.report, rate, sub.rate)
                    self._send_requests(sub.provider, sub.set_rate(rate, now))
            for slot in vehicle.commands.values():
                slot.profile = profile.commands
            for ctl in vehicle.controls.values():
                ctl.profile = profile.control
                ctl.authority = profile.authority
        if self.planner is not None:
            self.planner.relay = profile
            self.replan(now)
        return not_applied

    # == bandwidth plan =====================================================================

    def replan(self, now: float) -> None:
        """Plan report rates again and update the events whose rate changed."""
        planner = self.planner
        if planner is None:
            return
        self._plan_dirty = False
        specs = {spec.report: spec for _tr, spec in self.manager.wanted_reports()}
        wants = []
        links: dict[str, str] = {}
        for vehicle in self.vehicles.values():
            if not vehicle.online or not vehicle.subscriptions:
                continue
            vp = vehicle.profile
            link = planner.link_for(vp.link if vp else "", vehicle.address)
            if not link:
                continue
            links[vehicle.vehicle_id] = link
            reports = tuple(
                (specs[sub.report], sub.polls)
                for sub in vehicle.subscriptions.values()
                if sub.report in specs and sub.state is not SubscriptionState.CANCELLING
            )
            live = sum(1 for address in vehicle.components
                       if vehicle.offers(address, LIVENESS)
                       or vehicle.offers(address, MANAGEMENT))
            wants.append(VehicleWants(vehicle.vehicle_id, link, vp, reports, max(live, 1)))
        # vehicles the profile puts on a planned link but not heard yet get a share now
        # (the reports their link-mates deliver), so the first one to answer is not given
        # the whole link and then slowed down behind its own backlog
        for vp in self.profile.vehicles:
            known = self.vehicles.get(vp.subsystem) if vp.subsystem is not None else None
            if not vp.link or (known is not None and (
                    known.times_lost or (known.online and known.subscriptions))):
                continue
            link = planner.link_for(vp.link, None)
            mates = [w for w in wants if w.link == link]
            expected = {spec.report: spec for w in mates for spec, _polled in w.reports}
            if link and expected:
                wants.append(VehicleWants(vp.vehicle_id, link, vp,
                                          tuple((spec, False) for spec in expected.values()),
                                          max(w.liveness_components for w in mates)))
        planner.plan(wants)
        for vehicle in self.vehicles.values():
            link = links.get(vehicle.vehicle_id)
            if link is None:
                continue
            for sub in vehicle.subscriptions.values():
                rate = planner.rate(link, vehicle.vehicle_id, sub.report)
                if rate is None:
                    continue
                self._apply_rate(vehicle, sub, rate, now)

    def set_link_rate(self, link: str, bit_rate: float, now: float) -> None:
        """The measured rate of ``link`` changed: plan again."""
        if self.planner is not None and self.planner.set_link_rate(link, bit_rate):
            self.replan(now)

    def _apply_rate(self, vehicle: Vehicle, sub: Subscription, rate: float, now: float) -> None:
        key = (vehicle.vehicle_id, sub.report)
        if rate <= 0:
            if key not in self._dropped:
                self._dropped.add(key)
                log.warning("vehicle %s: %s dropped: the link cannot carry even its minimum",
                            vehicle.vehicle_id, sub.report)
                if sub.state is not SubscriptionState.NEW:
                    self._send_requests(sub.provider, sub.cancel(now))
                sub.reason = "dropped by the bandwidth plan"
            return
        if key in self._dropped:
            self._dropped.discard(key)
            sub.rate = rate
            self._send_requests(sub.provider, sub.resume(now))
            self._touch(vehicle)
            return
        if abs(rate - sub.rate) > 1e-9:
            log.info("vehicle %s: %s planned at %.2f Hz (was %.2f)", vehicle.vehicle_id,
                     sub.report, rate, sub.rate)
            self._send_requests(sub.provider, sub.update_rate(rate, now))
            self._touch(vehicle)

    # == start-up, discovery and identification ========================================

    def _start(self, now: float) -> None:
        if self._started:
            return
        self._started = True
        self._next_discovery = now
        for vp in self.profile.vehicles:
            if vp.is_static:
                components = {c.address: tuple((s.uri, s.version) for s in c.services)
                              for c in vp.components}
                self._declare(vp.vehicle_id, components, vp.name, vp.vehicle_type, now,
                              seen=False)

    def _declare(self, vehicle_id: str, components: Mapping[JausAddress, Sequence[tuple[str, str]]],
                 name: str, vehicle_type: str, now: float, *, seen: bool) -> Vehicle | None:
        if not components:
            return None
        subsystem = next(iter(components)).subsystem
        if subsystem == self.profile.jaus_id.subsystem:
            log.warning("vehicle %s declared in the relay's own subsystem: ignored", vehicle_id)
            return None
        vehicle = self.vehicles.get(subsystem)
        if vehicle is None and len(self.vehicles) >= self.profile.limits.max_vehicles:
            self.counters["vehicles_refused_table_full"] += 1
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
            self._seen(vehicle, now)
        self._setup(vehicle, now)
        return vehicle

    def _add_vehicle(self, subsystem: int, vehicle_id: str, now: float) -> Vehicle:
        profile = self.profile.vehicle_by_subsystem(subsystem)
        if profile is not None:
            vehicle_id = profile.vehicle_id
        if vehicle_id in self._by_id:  # two subsystems reporting the same name
            vehicle_id = f"{vehicle_id}-{subsystem}"
        vehicle = Vehicle(subsystem, vehicle_id, profile)
        if profile is not None:
            vehicle.name = profile.name
            vehicle.vehicle_type = profile.vehicle_type
        vehicle.next_liveness = now + self.profile.discovery.liveness_period
        self.vehicles[subsystem] = vehicle
        self._by_id[vehicle_id] = vehicle
        log.info("vehicle %s (subsystem %d) discovered", vehicle_id, subsystem)
        return vehicle

    def _on_identification(self, source: JausAddress, fields: Mapping[str, Any],
                           now: float) -> Vehicle | None:
        if source.subsystem == self.profile.jaus_id.subsystem:
            return None
        ident = str(fields.get("identification", "") or "")
        vehicle = self.vehicles.get(source.subsystem)
        if vehicle is None and len(self.vehicles) >= self.profile.limits.max_vehicles:
            self.counters["vehicles_refused_table_full"] += 1
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
        vehicle.discovery.on_identification(ident, self.counters)
        if vehicle.address is None:
            vehicle.address = source
            changed = True
        if not vehicle.services_known and vehicle.next_services_query is None:
            vehicle.next_services_query = vehicle.discovery.start(now)
        if changed:
            self._changed(vehicle, "identified", now)
        return vehicle

    def _probe_unknown(self, source: JausAddress, now: float) -> None:
        """A message from an unidentified subsystem: ask who it is (rate-limited)."""
        self.counters["messages_unidentified"] += 1
        if source.subsystem == self.profile.jaus_id.subsystem or self._shutting_down:
            return
        due = self._probed.get(source.subsystem, 0.0)
        if now >= due and source.subsystem not in self._probed and (
                len(self._probed) >= self.profile.limits.max_unidentified):
            # bounded: forget expired probes first, else ignore this stranger (counted)
            self._probed = {k: v for k, v in self._probed.items() if v > now}
            if len(self._probed) >= self.profile.limits.max_unidentified:
                self.counters["probes_skipped_table_full"] += 1
                return
        if now >= due:
            self._probed[source.subsystem] = now + self.profile.discovery.response_timeout
            self._send(source, "QueryIdentification", {"query_type": 2})

    def _query_services(self, vehicle: Vehicle, now: float) -> None:
        """A discovery round is due (see :class:`~edge_vis.engine.discovery.ServiceDiscovery`)."""
        if vehicle.address is None:
            vehicle.next_services_query = None
            return
        self._discovery_sends(vehicle, vehicle.discovery.next_round(
            _component(vehicle.address), now, self.profile.discovery, self.counters))

    def _discovery_sends(self, vehicle: Vehicle, queries: Sequence[Query]) -> None:
        """Send discovery's queries to the component that identified the vehicle."""
        if vehicle.address is not None:
            for name, fields in queries:
                self._send(vehicle.address, name, fields)
        vehicle.next_services_query = vehicle.discovery.next_at

    # == liveness ===========================================================================

    def _seen(self, vehicle: Vehicle, now: float) -> None:
        self._touch(vehicle)
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
            self._send_outgoing(address, ctl.on_found(now))
        self._setup(vehicle, now)

    def _lose(self, vehicle: Vehicle, now: float) -> None:
        log.warning("vehicle %s lost: silent for %.1f s", vehicle.vehicle_id,
                    now - (vehicle.last_seen or now))
        vehicle.online = False
        vehicle.times_lost += 1
        vehicle.statuses.clear()
        vehicle.event_timeout_asked.clear()
        for ctl in vehicle.controls.values():
            ctl.on_lost()
        for sub in vehicle.subscriptions.values():
            sub.on_lost()
        for slot in vehicle.commands.values():
            self.counters["commands_dropped"] += slot.clear()
        self.counters["vehicles_lost"] += 1
        self._plan_dirty = True
        self._changed(vehicle, "offline", now)

    def _liveness(self, vehicle: Vehicle, now: float) -> None:
        # a lost vehicle is still probed, but only once per discovery period: the radio
        # link's capacity belongs to the vehicles that answer
        period = self.profile.discovery.liveness_period
        vehicle.next_liveness = now + (period if vehicle.online
                                       else max(period, self.profile.discovery.period))
        tick = int(now / period) if period > 0 else 0
        sent = False
        if vehicle.services_known:
            for address in sorted(vehicle.components):
                if vehicle.offers(address, LIVENESS):
                    self._send(address, "QueryHeartbeatPulse", {})
                    sent = True
                    if vehicle.offers(address, MANAGEMENT) and tick % STATUS_EVERY == 0:
                        self._send(address, "QueryStatus", {})
                elif vehicle.offers(address, MANAGEMENT):
                    self._send(address, "QueryStatus", {})
                    sent = True
        if not sent and vehicle.address is not None:
            self._send(vehicle.address, "QueryIdentification", {"query_type": 2})

    # == per-vehicle set-up: subscriptions and control =====================================

    def _setup(self, vehicle: Vehicle, now: float) -> None:
        if self._shutting_down or not vehicle.online or not vehicle.services_known:
            return
        starting = []
        for _tr, spec in self.manager.wanted_reports():
            providers = vehicle.providers(spec.service)
            if not providers:
                continue
            key = (providers[0], spec.report)
            sub = vehicle.subscriptions.get(key)
            if sub is None:
                rate = self.profile.report_rate(spec.report, spec.rate, vehicle.profile)
                sub = Subscription(providers[0], spec.report, spec.query, spec.query_fields,
                                   min(rate, 1092.0), spec.on_change, self.profile.events,
                                   self._encode_query, vehicle.next_request_id)
                vehicle.subscriptions[key] = sub
            if sub.state is SubscriptionState.NEW:
                starting.append(sub)
        if starting and self.planner is not None:
            self.replan(now)  # a vehicle joined: rates for it (and its link's others) first
        for sub in starting:
            if sub.state is SubscriptionState.NEW \
                    and (vehicle.vehicle_id, sub.report) not in self._dropped:
                self._send_requests(sub.provider, sub.start(now))
        self._update_control(vehicle, now)

    def _update_control(self, vehicle: Vehicle, now: float) -> None:
        wanted = (vehicle.arbitration.holder is not None and vehicle.online
                  and vehicle.services_known and not self._shutting_down)
        if wanted:
            for uri in sorted(self._controlled_services):
                for address in vehicle.providers(uri):
                    if address not in vehicle.controls:
                        vehicle.controls[address] = ComponentControl(
                            self.profile.control, self.profile.authority,
                            vehicle.offers(address, MANAGEMENT))
        before = self._jaus_control(vehicle)
        for address, ctl in vehicle.controls.items():
            self._send_outgoing(address, ctl.want(wanted, now))
        if self._jaus_control(vehicle) != before:
            self._changed(vehicle, "control", now)

    # == handling messages =================================================================

    def _handle(self, vehicle: Vehicle, source: JausAddress, name: str,
                fields: Mapping[str, Any], now: float) -> None:
        handler = _HANDLERS.get(name)
        if handler is not None:
            handler(self, vehicle, source, fields, now)
        if self.manager.handles(name):
            ctx = self._context(vehicle, now, source)
            self._apply(self.manager.on_message(name, fields, ctx), now)

    def _on_services(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                     now: float) -> None:
        changed = False
        report = services_from_report(fields)
        for (node, comp), services in report.items():
            address = JausAddress(vehicle.subsystem, node, comp)
            changed |= vehicle.set_services(address, services)
        if not vehicle.static and vehicle.address is not None:
            self._discovery_sends(vehicle, vehicle.discovery.on_services(
                report, _component(vehicle.address), now, self.profile.discovery,
                self.counters))
        # an empty answer proves nothing (JAUS++ reads the wildcards literally)
        first = not vehicle.services_known and (vehicle.static or vehicle.discovery.known)
        vehicle.services_known = vehicle.services_known or first
        if changed or first:
            self._changed(vehicle, "identified", now)
        self._setup(vehicle, now)

    def _on_configuration(self, vehicle: Vehicle, source: JausAddress,
                          fields: Mapping[str, Any], now: float) -> None:
        if not vehicle.static and vehicle.address is not None:
            self._discovery_sends(vehicle, vehicle.discovery.on_configuration(
                components_from_configuration(fields), _component(vehicle.address), now,
                self.profile.discovery, self.counters))

    def _on_confirm_control(self, vehicle: Vehicle, source: JausAddress,
                            fields: Mapping[str, Any], now: float) -> None:
        ctl = vehicle.controls.get(source)
        if ctl is None:
            return
        code = int(pick(fields, "response_code", 0))
        before = ctl.state
        self._send_outgoing(source, ctl.on_confirm(code, now))
        if ctl.state is not before:
            if code != 0:
                log.warning("vehicle %s component %s refused control (code %d)",
                            vehicle.vehicle_id, source, code)
            self._changed(vehicle, "control", now)

    def _on_reject_control(self, vehicle: Vehicle, source: JausAddress,
                           fields: Mapping[str, Any], now: float) -> None:
        ctl = vehicle.controls.get(source)
        if ctl is None:
            return
        before = ctl.state
        self._send_outgoing(source, ctl.on_reject(int(pick(fields, "response_code", 0)), now))
        if ctl.state is not before:
            self._changed(vehicle, "control", now)

    def _on_timeout(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                    now: float) -> None:
        ctl = vehicle.controls.get(source)
        if ctl is not None:
            ctl.on_timeout_report(int(pick(fields, "timeout", 0)), now)

    def _on_status(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        status = int(pick(fields, "status", 0))
        before = vehicle.state_name()
        vehicle.statuses[source] = status
        ctl = vehicle.controls.get(source)
        if ctl is not None:
            self._send_outgoing(source, ctl.on_status(status, now))
        if vehicle.in_emergency():
            for slot in vehicle.commands.values():
                if slot.pending is not None and slot.pending.command.stop is not None:
                    self.counters["commands_dropped"] += slot.clear()
        if vehicle.state_name() != before:
            self._changed(vehicle, "status", now)

    def _on_confirm_event(self, vehicle: Vehicle, source: JausAddress,
                          fields: Mapping[str, Any], now: float) -> None:
        request_id = pick(fields, "request_id")
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.request_id == request_id:
                self._send_requests(source, sub.on_confirm(
                    int(pick(fields, "event_id", 0)),
                    float(pick(fields, "confirmed_periodic_rate", 0.0)), now))
                if (sub.state is SubscriptionState.ACTIVE
                        and source not in vehicle.event_timeout_asked):
                    vehicle.event_timeout_asked.add(source)
                    self._send(source, "QueryEventTimeout", {})
                return
        self.counters["event_confirms_unmatched"] += 1

    def _on_reject_event(self, vehicle: Vehicle, source: JausAddress,
                         fields: Mapping[str, Any], now: float) -> None:
        request_id = pick(fields, "request_id")
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.request_id == request_id:
                polled = sub.polls
                self._send_requests(source, sub.on_reject(pick(fields, "response_code"), now))
                if polled != sub.polls:
                    self._plan_dirty = True
                return

    def _on_event_timeout(self, vehicle: Vehicle, source: JausAddress,
                          fields: Mapping[str, Any], now: float) -> None:
        minutes = int(pick(fields, "timeout", 0))
        for sub in vehicle.subscriptions.values():
            if sub.provider == source:
                sub.set_event_timeout(minutes, now)

    def _on_event(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                  now: float) -> None:
        inner = self._unwrap(fields)
        if inner is None:
            self.counters["events_undecodable"] += 1
            return
        name, inner_fields = inner
        event_id = int(pick(fields, "event_id", -1))
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.matches_event(event_id, name):
                missed = sub.on_event(int(pick(fields, "sequence_number", 0)), now)
                if missed:
                    self.counters["events_missed"] += missed
                break
        else:
            # data is data: deliver it, but count it (another client's event, or a burst
            # that raced our confirm)
            self.counters["events_unmatched"] += 1
        self.counters["events_received"] += 1
        self._handle(vehicle, source, name, inner_fields, now)

    def _unwrap(self, fields: Mapping[str, Any]) -> tuple[str, Mapping[str, Any]] | None:
        payload = fields.get("report_message")
        if hasattr(payload, "name"):
            name, inner = payload.name, payload.fields
        elif isinstance(payload, bytes | bytearray):
            try:
                message = self.catalogue.decode(bytes(payload))
            except Exception as exc:  # a DecodeError from the remote: count and drop
                log.debug("undecodable report in Event: %s", exc)
                return None
            name, inner = message.name, message.fields
        else:
            return None
        if name is None:
            return None
        return name, inner or {}

    # == operators and commands ===========================================================

    def _on_control_request(self, sample: Mapping[str, Any], now: float) -> None:
        vehicle = self._by_id.get(str(sample.get("vehicle_id", "")))
        if vehicle is None:
            self.counters["control_requests_unknown_vehicle"] += 1
            return
        self._touch(vehicle)
        operator = str(sample.get("operator_id", ""))
        raw = sample.get("action", "request")
        # the enum's name ("REQUEST"/"RELEASE"), or its value (0/1)
        action = {0: "request", 1: "release"}.get(raw, str(raw)) if isinstance(raw, int) \
            else str(getattr(raw, "name", raw)).lower()
        arb = vehicle.arbitration
        previous = arb.holder
        if action == "release":
            decision = arb.release(operator)
        elif action == "request" and (refusal := self.profile.operators.refusal(
                operator, int(sample.get("authority", 0)))):
            # not in the profile's allowlist (edge_vis.config.operators): counted, logged, reported
            self.counters["control_requests_refused"] += 1
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
                self.counters["commands_dropped"] += slot.clear()
        self._update_control(vehicle, now)
        self._changed(vehicle, "control", now)

    def _offer_command(self, command: Command, now: float) -> None:
        vehicle = self._by_id.get(command.vehicle_id)
        if vehicle is None:
            self.counters["commands_unknown_vehicle"] += 1
            return
        self._touch(vehicle)
        arb = vehicle.arbitration
        reason = ""
        if not arb.allows(command.operator_id):
            holder = arb.holder.operator_id if arb.holder else "nobody"
            reason = (f"{command.name} from {command.operator_id} refused: control held by "
                      f"{holder}")
        elif command.stop is not None and vehicle.in_emergency():
            reason = f"{command.name} refused: vehicle in {vehicle.state_name()}"
        elif not vehicle.providers(command.service):
            reason = f"{command.name} refused: no component offers {command.service}"
        if reason:
            arb.reject(reason)
            self.counters["commands_rejected"] += 1
            self._changed(vehicle, "control", now)
            return
        slot = vehicle.commands.get(command.kind)
        if slot is None:
            slot = vehicle.commands[command.kind] = CommandSlot(self.profile.commands)
        slot.offer(command, now)

    def _can_send(self, vehicle: Vehicle, kind: str) -> bool:
        slot = vehicle.commands[kind]
        command = slot.pending.command if slot.pending else slot.last_command
        if command is None or not vehicle.online:
            return False
        providers = vehicle.providers(command.service)
        if not providers:
            return False
        ctl = vehicle.controls.get(providers[0])
        if ctl is None or not ctl.ready:
            return False
        return command.stop is None or not vehicle.in_emergency()

    def _pump_commands(self, vehicle: Vehicle, now: float) -> None:
        for kind, slot in vehicle.commands.items():
            if vehicle.online and not self._shutting_down:
                slot.arm_deadman(now)
            if not self._can_send(vehicle, kind):
                before = slot.expired
                slot.expire(now)
                self.counters["commands_expired"] += slot.expired - before
                continue
            before = slot.expired
            command = slot.take(now)
            self.counters["commands_expired"] += slot.expired - before
            if command is None:
                continue
            destination = vehicle.providers(command.service)[0]
            self._actions.append(SendMessage(destination, command.name, dict(command.fields),
                                             command.priority, command.service_set, "command"))
            self.counters["commands_sent"] += 1

    # == the timer pass ===================================================================

    def _run(self, now: float) -> None:
        """The pass that sends whatever is due.

        Every vehicle is visited when one of their deadlines has come (or the set of
        vehicles changed, or the engine is shutting down); otherwise only the vehicles the
        current input touched are, which keeps the cost of a report independent of the
        size of the fleet. The cached earliest deadline is kept exact or early, never late.
        """
        if self._done:
            return
        disc = self.profile.discovery
        if not self._shutting_down and self._next_discovery is not None and (
            now >= self._next_discovery
        ):
            self._next_discovery = now + disc.period
            self._send(BROADCAST, "QueryIdentification", {"query_type": 2})
        full = (
            self._shutting_down
            or not self._due_valid
            or len(self.vehicles) != self._vehicle_count
            or (self._vehicle_due is not None and now >= self._vehicle_due)
        )
        visit = list(self.vehicles.values()) if full else list(self._touched.values())
        self._touched = {}
        for vehicle in visit:
            self._visit(vehicle, now)
        if full:
            self._vehicle_count = len(self.vehicles)
            self._vehicle_due = self._earliest(self.vehicles.values())
            self._due_valid = True
        elif visit:
            due = self._earliest(visit)
            if due is not None and (self._vehicle_due is None or due < self._vehicle_due):
                self._vehicle_due = due
        if self._touched:  # a visit touched another vehicle: settle it at the next pass
            self._due_valid = False
        if self._plan_dirty and self.planner is not None and not self._shutting_down:
            self.replan(now)
        if self._shutting_down:
            self._check_shutdown(now)

    def _visit(self, vehicle: Vehicle, now: float) -> None:
        disc = self.profile.discovery
        if not self._shutting_down:
            if (vehicle.online and vehicle.last_seen is not None
                    and now > vehicle.last_seen + disc.silence_timeout):
                self._lose(vehicle, now)
            if vehicle.next_services_query is not None and now >= vehicle.next_services_query:
                self._query_services(vehicle, now)
            if vehicle.next_liveness is not None and now >= vehicle.next_liveness:
                self._liveness(vehicle, now)
        before = self._jaus_control(vehicle)
        for address, ctl in vehicle.controls.items():
            self._send_outgoing(address, ctl.poll(now))
        if self._jaus_control(vehicle) != before:
            self._changed(vehicle, "control", now)
        for sub in vehicle.subscriptions.values():
            polled = sub.polls
            self._send_requests(sub.provider, sub.poll(now))
            if polled != sub.polls:
                self._plan_dirty = True  # a poll costs a query too: plan again
        if not self._shutting_down:
            self._pump_commands(vehicle, now)

    def _touch(self, vehicle: Vehicle) -> None:
        """``vehicle``'s state changed: the next pass must visit it."""
        self._touched[id(vehicle)] = vehicle

    def _check_shutdown(self, now: float) -> None:
        pending = sum(
            1 for v in self.vehicles.values() for s in v.subscriptions.values()
            if s.state is SubscriptionState.CANCELLING
        ) + sum(
            1 for v in self.vehicles.values() for c in v.controls.values()
            if c.state is ControlState.RELEASING
        )
        expired = self._shutdown_deadline is not None and now >= self._shutdown_deadline
        if pending == 0 or expired:
            timed_out = sum(
                1 for v in self.vehicles.values()
                for item in (*v.subscriptions.values(), *v.controls.values()) if item.unanswered
            )
            self._done = True
            self._shutdown_deadline = None
            self._actions.append(ShutdownComplete(pending + timed_out))

    # == helpers ============================================================================

    @property
    def catalogue(self) -> InnerCodec:
        """The catalogue used for payloads nested in CreateEvent and Event."""
        if self._catalogue is None:
            from edge_vis.catalogue import default_catalogue

            self._catalogue = default_catalogue()
        return self._catalogue

    def _encode_query(self, name: str, fields: Mapping[str, Any]) -> bytes:
        return self.catalogue.encode(name, fields)

    def _send(self, destination: JausAddress, name: str, fields: Mapping[str, Any],
              traffic_class: str = "liveness") -> None:
        self._actions.append(SendMessage(destination, name, dict(fields),
                                         traffic_class=traffic_class))

    def _send_outgoing(self, destination: JausAddress, items: Sequence[Outgoing]) -> None:
        for item in items:
            self._send(destination, item.name, item.fields, "control")

    def _send_requests(self, destination: JausAddress, items: Sequence[Request]) -> None:
        for item in items:
            self._send(destination, item.name, item.fields, "telemetry")

    def _apply(self, actions: Sequence[Action], now: float) -> None:
        for action in actions:
            if isinstance(action, Command):
                self._offer_command(action, now)
            elif isinstance(action, DeclareVehicle):
                self._declare(action.vehicle_id, action.components, action.name,
                              action.vehicle_type, now, seen=True)
            elif isinstance(action, Publish | SendMessage):
                self._actions.append(action)
            else:
                raise TypeError(f"translators may not return {type(action).__name__}")

    def _changed(self, vehicle: Vehicle, change: str, now: float) -> None:
        self._touch(vehicle)
        self._apply(self.manager.on_vehicle(change, self._context(vehicle, now)), now)

    def _jaus_control(self, vehicle: Vehicle) -> str:
        states = {c.state for c in vehicle.controls.values() if c.wanted
                  or c.state is not ControlState.IDLE}
        if not states:
            return "none"
        for state in (ControlState.REFUSED, ControlState.REQUESTING, ControlState.RELEASING):
            if state in states:
                return state.value
        return "controlled" if states == {ControlState.CONTROLLED} else "none"

    def _view(self, vehicle: Vehicle) -> VehicleView:
        holder = vehicle.arbitration.holder
        notes = tuple(f"{a}: {c.note}" for a, c in sorted(vehicle.controls.items()) if c.note)
        last_ms = (int((vehicle.last_seen + self.wall_offset) * 1000)
                   if vehicle.last_seen is not None else 0)
        return VehicleView(
            vehicle_id=vehicle.vehicle_id,
            subsystem=vehicle.subsystem,
            name=vehicle.name,
            vehicle_type=vehicle.vehicle_type,
            address=vehicle.address,
            services=vehicle.all_services(),
            components=dict(vehicle.components),
            online=vehicle.online,
            state=vehicle.state_name(),
            link=(vehicle.profile.link if vehicle.profile and vehicle.profile.link
                  else self.link_of(vehicle.address) if vehicle.address is not None else ""),
            last_seen=vehicle.last_seen,
            last_seen_ms=last_ms,
            controller=holder.operator_id if holder else "",
            controller_authority=holder.authority if holder else 0,
            jaus_control=self._jaus_control(vehicle),
            rejected_commands=vehicle.arbitration.rejected_commands,
            last_rejection=vehicle.arbitration.last_rejection,
            notes=notes,
        )

    def _context(self, vehicle: Vehicle | None, now: float,
                 source: JausAddress | None = None) -> TranslatorContext:
        return TranslatorContext(
            now=now,
            timestamp_ms=int((now + self.wall_offset) * 1000),
            relay_id=self.profile.jaus_id,
            vehicle=self._view(vehicle) if vehicle is not None else None,
            vehicles=_LazyViews(self),
            source=source,
            catalogue=self.catalogue,
        )


class _LazyViews(Mapping[str, VehicleView]):
    """``vehicle_id -> VehicleView`` built on access, so contexts stay cheap."""

    def __init__(self, engine: Engine) -> None:
        self._engine = engine

    def __getitem__(self, key: str) -> VehicleView:
        vehicle = self._engine._by_id[key]
        return self._engine._view(vehicle)

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self._engine._by_id)

    def __len__(self) -> int:
        return len(self._engine._by_id)


def _component(address: JausAddress) -> Component:
    return address.node, address.component


_HANDLERS = {
    "ReportServices": Engine._on_services,
    "ReportConfiguration": Engine._on_configuration,
    "ConfirmControl": Engine._on_confirm_control,
    "RejectControl": Engine._on_reject_control,
    "ReportTimeout": Engine._on_timeout,
    "ReportStatus": Engine._on_status,
    "ConfirmEventRequest": Engine._on_confirm_event,
    "RejectEventRequest": Engine._on_reject_event,
    "ReportEventTimeout": Engine._on_event_timeout,
}
