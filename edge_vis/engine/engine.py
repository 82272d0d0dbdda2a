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
component/service tree (:mod:`~edge_vis.engine.finder`; vehicles found by a hello or their
messages: :mod:`~edge_vis.engine.announcements`), liveness and the silence timer
(:mod:`~edge_vis.engine.liveness`), JAUS access control and readiness of the commanded
components (:mod:`~edge_vis.engine.access`), who else holds them (:mod:`~edge_vis.engine.holders`),
the vehicles' clocks (:mod:`~edge_vis.engine.clocks`), event subscriptions with polling fallback
(:mod:`~edge_vis.engine.reports`), command throttles and the dead-man
(:mod:`~edge_vis.engine.commands`), operator arbitration
(:mod:`~edge_vis.engine.control_requests`), hand-offs between operators
(:mod:`~edge_vis.engine.handoff_requests`) and the emergency stop
(:mod:`~edge_vis.engine.estop`). Report rates follow the bandwidth plan
(:mod:`~edge_vis.engine.rates`); the timer pass is :mod:`~edge_vis.engine.timer_pass`; what
translators see is built by :mod:`~edge_vis.engine.views`. Those parts share one
:class:`~edge_vis.engine.state.EngineState`; this class wires them together, routes each
input to its part and routes translators' actions back.

A vehicle silent for ``discovery.lost_after`` liveness periods is *lost*: its events,
control and queued commands are dropped and ``VehicleStatus`` says offline. Any message
from it later makes it *found* again; events and control are re-established by themselves.

Messages are decoded values (anything with ``name`` and ``fields``, e.g. the catalogue's
``Message``). Only two payloads are bytes: the query inside CreateEvent and the report
inside Event; the engine encodes/decodes those through the catalogue it was given.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from edge_vis.bandwidth.demands import FleetPlanner
from edge_vis.config import RelayProfile
from edge_vis.engine.access import Access
from edge_vis.engine.announcements import Announcements
from edge_vis.engine.clocks import Clocks
from edge_vis.engine.commands import Commands
from edge_vis.engine.control_requests import ControlRequests
from edge_vis.engine.duty import Duty
from edge_vis.engine.estop import EmergencyStops
from edge_vis.engine.finder import Finder
from edge_vis.engine.handoff_requests import TOPICS as HANDOFF_TOPICS
from edge_vis.engine.handoff_requests import HandoffRequests
from edge_vis.engine.holders import Holders
from edge_vis.engine.liveness import LIVENESS, MANAGEMENT, STATUS_EVERY, Liveness
from edge_vis.engine.manager import TranslationManager
from edge_vis.engine.rates import Rates
from edge_vis.engine.reports import Reports, set_of
from edge_vis.engine.state import EngineState, Handler, InnerCodec
from edge_vis.engine.timer_pass import TimerPass
from edge_vis.engine.vehicle import Vehicle
from edge_vis.engine.views import EngineSnapshot, SubscriptionView, VehicleSnapshot, Views
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import (
    Action,
    Command,
    DeclareVehicle,
    EmergencyRequest,
    Publish,
    SendMessage,
)
from edge_vis.kit.contract import Translator

__all__ = [
    "LIVENESS", "MANAGEMENT", "STATUS_EVERY", "Engine", "EngineSnapshot", "InnerCodec",
    "SubscriptionView", "VehicleSnapshot",
]


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
        arbitrate: bool = False,
    ) -> None:
        if isinstance(translators, TranslationManager):
            self.manager = translators
        elif translators is not None:
            self.manager = TranslationManager(translators)
        else:
            self.manager = TranslationManager.from_selection(profile.translators)
        self._state = state = EngineState(profile, catalogue, wall_offset, planner)
        state.arbitrated = arbitrate
        self._views = Views(state)
        self._rates = Rates(state, self.manager)
        self._access = Access(state, self.manager.controlled_services(), self._changed)
        self._reports = Reports(state, self.manager, self._rates, self._handle)
        self._liveness = Liveness(state, self._changed, self._access, self._reports)
        self._finder = Finder(state, self._changed, self._liveness)
        self._announcements = Announcements(state, self._finder, self._changed)
        self._commands = Commands(state, self._changed)
        self._control_requests = ControlRequests(state, self._access, self._changed)
        self._estop = EmergencyStops(state, self._changed)
        self._holders = Holders(state, self._changed)
        self._handoffs = HandoffRequests(state, self._access, self._changed)
        self._clocks = Clocks(state, self._access, self._changed)
        self._duty = Duty(state, self._access, self._reports, self._liveness.setup,
                          self._changed)
        self._timer_pass = TimerPass(state, self._finder, self._liveness, self._access,
                                    self._reports, self._commands, self._rates, self._estop,
                                    (self._holders.poll, self._clocks.poll,
                                     self._handoffs.poll),
                                    duty=self._duty if arbitrate else None)
        #: the JAUS messages the engine itself handles, by name
        self._handlers: dict[str, Handler] = {
            "ReportServices": self._finder.on_services,
            "ReportConfiguration": self._finder.on_configuration,
            "ConfirmControl": self._access.on_confirm,
            "RejectControl": self._access.on_reject,
            "ReportTimeout": self._access.on_timeout,
            "ReportStatus": self._on_status,
            "ReportControl": self._holders.on_control,
            "ReportAuthority": self._holders.on_authority,
            "ReportTime": self._clocks.on_time,
            "ConfirmEventRequest": self._reports.on_confirm,
            "RejectEventRequest": self._reports.on_reject,
            "ReportEventTimeout": self._reports.on_event_timeout,
            "RequestReleaseControl": self._handoffs.on_release_request,
            "ConfirmHandoffRequest": self._handoffs.on_confirm_handoff,
            "ReportHandoffTimeout": lambda v, _s, f, now: self._handoffs.on_timeouts(
                v, "ReportHandoffTimeout", f, now),
            "ReportEnhancedTimeout": lambda v, _s, f, now: self._handoffs.on_timeouts(
                v, "ReportEnhancedTimeout", f, now),
        }

    # == shared state, as attributes ======================================================

    @property
    def profile(self) -> RelayProfile:
        """The profile in force (replaced by :meth:`apply_profile`)."""
        return self._state.profile

    @profile.setter
    def profile(self, value: RelayProfile) -> None:
        self._state.profile = value

    @property
    def planner(self) -> FleetPlanner | None:
        """Plans report rates to fit the links' budgets (None: the profiles' rates as is)."""
        return self._state.planner

    @planner.setter
    def planner(self, value: FleetPlanner | None) -> None:
        self._state.planner = value

    @property
    def wall_offset(self) -> float:
        """Added to ``now`` to stamp samples with wall-clock time."""
        return self._state.wall_offset

    @wall_offset.setter
    def wall_offset(self, value: float) -> None:
        self._state.wall_offset = value

    @property
    def counters(self) -> Counter[str]:
        """What happened, counted (messages, events, commands, losses...)."""
        return self._state.counters

    @property
    def vehicles(self) -> dict[int, Vehicle]:
        """Subsystem -> the live state of that vehicle (do not mutate)."""
        return self._state.vehicles

    @property
    def link_of(self) -> Callable[[JausAddress], str]:
        """The name of the link a JAUS address is reached over (set by the runtime)."""
        return self._state.link_of

    @link_of.setter
    def link_of(self, value: Callable[[JausAddress], str]) -> None:
        self._state.link_of = value

    @property
    def catalogue(self) -> InnerCodec:
        """The catalogue used for payloads nested in CreateEvent and Event."""
        return self._state.catalogue

    @property
    def _probed(self) -> dict[int, float]:
        """Unidentified subsystems probed recently (the bounded table)."""
        return self._finder.probed

    # == public API =======================================================================

    def receive_message(self, source: JausAddress, message: Any, now: float) -> None:
        """A decoded JAUS message from ``source`` arrived at ``now``."""
        state = self._state
        if not self._finder.started:
            self._finder.start(now)
        if state.done or source == state.profile.jaus_id:
            return
        name = getattr(message, "name", None)
        fields = getattr(message, "fields", None) or {}
        if name is None:
            state.counters["messages_unknown"] += 1
            return
        state.counters["messages_received"] += 1
        if name == "ReportIdentification":
            vehicle = self._finder.on_identification(source, fields, now)
        else:
            vehicle = state.vehicles.get(source.subsystem)
            if vehicle is None or vehicle.announced_by is not None:
                # a hello or passive discovery profile may declare (or update) it
                vehicle = self._announcements.on_message(source, name, fields, vehicle, now)
        if vehicle is None:
            # a custom hello: a translator may declare the vehicle from it
            if self.manager.handles(name):
                ctx = self._views.context(None, now, source, set_of(message))
                self._apply(self.manager.on_message(name, fields, ctx), now)
                if source.subsystem in state.vehicles:
                    self._liveness.seen(state.vehicles[source.subsystem], now)
                    self._timer_pass.run(now)
                    return
            self._finder.probe_unknown(source, now)
            self._timer_pass.run(now)
            return
        self._liveness.seen(vehicle, now)
        if name == "Event":
            self._reports.on_event(vehicle, source, fields, now)
        else:
            self._handle(vehicle, source, name, fields, now, set_of(message))
        self._timer_pass.run(now)

    def dialects_of(self, address: JausAddress) -> tuple[str, ...]:
        """The message dialects the vehicle of ``address`` speaks (its profile's, or
        recognised from its services; none for an unknown subsystem): decode what it sends
        and encode what goes to it with these."""
        vehicle = self._state.vehicles.get(address.subsystem)
        return () if vehicle is None else self._state.dialects(vehicle)

    def receive_sample(self, topic: str, sample: Mapping[str, Any], now: float) -> None:
        """A DDS sample (as a dict) of ``topic`` arrived at ``now``."""
        state = self._state
        if not self._finder.started:
            self._finder.start(now)
        if state.done:
            return
        state.counters["samples_received"] += 1
        if topic == "ControlRequest":
            self._control_requests.on_sample(sample, now)
            vehicle = state.by_id.get(str(sample.get("vehicle_id", "")))
            if vehicle is not None:
                self._handoffs.settle(vehicle, now)
        elif topic in HANDOFF_TOPICS:
            self._handoffs.on_sample(topic, sample, now)
        else:
            vehicle = state.by_id.get(str(sample.get("vehicle_id", "")))
            ctx = self._views.context(vehicle, now)
            self._apply(self.manager.on_sample(topic, sample, ctx), now)
        self._timer_pass.run(now)

    def receive_relay_status(self, sample: Mapping[str, Any], now: float) -> None:
        """A ``RelayStatus`` sample of a relay on the domain (this one's own included)
        arrived at ``now``: who serves which vehicle is decided again
        (:mod:`~edge_vis.engine.duty`)."""
        state = self._state
        if not self._finder.started:
            self._finder.start(now)
        if state.done or not state.arbitrated:
            return
        self._duty.start(now)
        self._duty.on_status(sample, now)
        self._timer_pass.run(now)

    @property
    def duty(self) -> Duty:
        """Which vehicles this relay serves, and its peers (with ``arbitrate``)."""
        return self._duty

    def refuse_sample(self, topic: str, sample: Mapping[str, Any], reason: str,
                      now: float) -> None:
        """A DDS command the shell refused before it reached the rules (its claimed
        ``operator_id`` is not the sender DDS Security proved): counted, and kept as the
        vehicle's ``last_rejection`` in ``ControlStatus`` so the operators see it."""
        if not self._finder.started:
            self._finder.start(now)
        state = self._state
        if state.done:
            return
        state.counters["samples_refused_sender"] += 1
        vehicle = state.by_id.get(str(sample.get("vehicle_id", "")))
        if vehicle is not None:
            arbitration = vehicle.arbitration
            new = arbitration.last_rejection != f"{topic}: {reason}"
            arbitration.reject(f"{topic}: {reason}")
            if new:  # a flood of refusals must not become a flood of ControlStatus
                self._changed(vehicle, "control", now)
        self._timer_pass.run(now)

    def operator_lost(self, operator_id: str, now: float) -> None:
        """Every DDS writer of ``operator_id`` is gone (its station vanished): with the
        profile's ``emergency.on_operator_lost`` the vehicles it held are stopped."""
        if not self._finder.started:
            self._finder.start(now)
        if self._state.done:
            return
        self._estop.on_operator_lost(operator_id, now)
        self._timer_pass.run(now)

    def on_timer(self, now: float) -> None:
        """The timer armed at :meth:`next_deadline` fired (early or late calls are fine)."""
        if not self._finder.started:
            self._finder.start(now)
        self._timer_pass.run(now)

    def next_deadline(self) -> float | None:
        """When :meth:`on_timer` must next be called; None when nothing is scheduled."""
        if self._state.done:
            return None
        if not self._finder.started:
            return 0.0
        return self._timer_pass.next_deadline()

    def drain_actions(self) -> list[Action]:
        """Everything the engine wants done since the last call, in order."""
        state = self._state
        actions, state.actions = state.actions, []
        if state.arbitrated:  # nothing is published for a vehicle another relay serves
            by_id = state.by_id
            kept = [a for a in actions if not isinstance(a, Publish)
                    or (v := by_id.get(str(a.sample.get("vehicle_id", "")))) is None
                    or v.serving]
            if len(kept) != len(actions):
                state.counters["samples_other_relay"] += len(actions) - len(kept)
            return kept
        return actions

    def shutdown(self, now: float) -> None:
        """Say goodbye: cancel events and release control, then report ShutdownComplete.

        Completion is reported once every CancelEvent and ReleaseControl is answered, or
        after the response timeout.
        """
        if not self._finder.started:
            self._finder.start(now)
        if self._state.arbitrated and not self._state.shutting_down:
            self._duty.shutdown(now)
        self._timer_pass.shutdown(now)

    @property
    def is_shut_down(self) -> bool:
        """True once ShutdownComplete has been emitted."""
        return self._state.done

    def snapshot(self, now: float | None = None) -> EngineSnapshot:
        """Read-only status of every vehicle, subscription and counter."""
        return self._views.snapshot()

    def vehicle(self, vehicle_id: str) -> Vehicle | None:
        """The live state of ``vehicle_id`` (for tests and diagnostics; do not mutate)."""
        return self._state.by_id.get(vehicle_id)

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
        return self._rates.apply_profile(profile, now)

    def replan(self, now: float) -> None:
        """Plan report rates again and update the events whose rate changed."""
        self._rates.replan(now)

    def set_link_rate(self, link: str, bit_rate: float, now: float) -> None:
        """The measured rate of ``link`` changed: plan again."""
        self._rates.set_link_rate(link, bit_rate, now)

    # == routing between translators and the parts ========================================

    def _handle(self, vehicle: Vehicle, source: JausAddress, name: str,
                fields: Mapping[str, Any], now: float, service_set: str = "") -> None:
        """A message of a known vehicle: to the part that handles it, then to translators
        (the one taking ``name`` of ``service_set`` from ``source``)."""
        handler = self._handlers.get(name)
        if handler is not None:
            handler(vehicle, source, fields, now)
        if self.manager.handles(name):
            ctx = self._views.context(vehicle, now, source, service_set)
            self._apply(self.manager.on_message(name, fields, ctx), now)

    def _on_status(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ReportStatus: readiness for commands, and confirmation of an emergency stop."""
        self._access.on_status(vehicle, source, fields, now)
        self._estop.on_status(vehicle, source, vehicle.statuses.get(source, 0), now)

    def _changed(self, vehicle: Vehicle, change: str, now: float) -> None:
        """Tell translators ``vehicle`` changed; the next pass visits it."""
        self._state.touch(vehicle)
        if change == "online":
            self._estop.on_found(vehicle, now)
        elif change == "identified":
            self._estop.on_identified(vehicle, now)
        self._apply(self.manager.on_vehicle(change, self._views.context(vehicle, now)), now)

    def _merged(self, action: Publish) -> Publish:
        """``action``'s sample over the latest of its instance (see ``Publish.merge``)."""
        key = (action.topic, tuple(action.sample.get(k) for k in action.merge))
        merged = self._state.merged.setdefault(key, {})
        merged.update({k: v for k, v in action.sample.items()
                       if k not in merged or not (v is None or v != v)})
        return Publish(action.topic, dict(merged))

    def _apply(self, actions: Sequence[Action], now: float) -> None:
        """Translators' actions: commands are admitted, vehicles declared, the rest queued."""
        for action in actions:
            if isinstance(action, Command):
                self._commands.offer(action, now)
            elif isinstance(action, DeclareVehicle):
                self._finder.declare(action.vehicle_id, action.components, action.name,
                                     action.vehicle_type, now, seen=True)
            elif isinstance(action, EmergencyRequest):
                self._estop.request(action, now)
            elif isinstance(action, Publish) and action.merge:
                self._state.actions.append(self._merged(action))
            elif isinstance(action, Publish | SendMessage):
                self._state.actions.append(action)
            else:
                raise TypeError(f"translators may not return {type(action).__name__}")
