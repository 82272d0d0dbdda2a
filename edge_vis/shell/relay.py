"""The asyncio shell of the relay: the only place where links, DDS, the clock and the
sans-I/O core meet. Performs I/O.

One event loop drives everything::

    link deliver(name, peer, packets) ─► Router.receive ─► SendPackets ─► Link.send
                                                        └► Deliver ─► Catalogue.decode
                                                                       ─► Engine.receive_message
    DDS sample (bridge thread → loop)  ─────────────────────────────► Engine.receive_sample
    timer at min(router, engine deadlines) ─► Router.on_timer / Engine.on_timer
    Engine actions: SendMessage ─► Catalogue.encode ─► Router.send ─► Link.send
                    Publish     ─► DdsBridge.publish

Every input is handled to completion (router, engine, actions) before the next one, so
the core never sees concurrency. A link with its own I/O thread (``thread=1``) calls
``deliver`` from that thread while holding the loop's lock
(:mod:`edge_vis.shell.sharedloop`), so that input too is handled to completion (router,
engine, sends, DDS writes) with nothing else running; only what needs the loop itself (a
timer wanted earlier than the one armed, the end of a shutdown) is handed to it. Bad bytes
are counted and logged (rate-limited), never raised; a failing link is reported and the
relay keeps running.
"""

from __future__ import annotations

import asyncio
import functools
import json
import logging
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

from edge_vis import plugins
from edge_vis.bandwidth.demands import FleetPlanner
from edge_vis.bandwidth.linkspec import DEFAULT_PRIORITIES, LinkSpec
from edge_vis.catalogue import Catalogue
from edge_vis.config import BulkProfile, LinkProfile, RelayProfile, RoutingProfile
from edge_vis.config.deployment import operator_partition
from edge_vis.engine.announcements import verify_discovery
from edge_vis.engine.engine import Engine
from edge_vis.errors import CodecError, ConfigError, EdgeVisError, EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Broadcast, Packet
from edge_vis.kit.actions import (
    EMERGENCY_CLASS,
    Publish,
    SendMessage,
    ShutdownComplete,
    Withdraw,
)
from edge_vis.routing.accounting import Kind, LogLimiter, Tally, losses, tallies_of, totals
from edge_vis.routing.link import Link, Peer, create_link
from edge_vis.routing.router import (
    Deliver,
    DeliveryFailed,
    ForwardWires,
    Router,
    RouterConfig,
    SendPackets,
)
from edge_vis.routing.traffic import priority_for
from edge_vis.shell.memory import release_memory
from edge_vis.shell.sharedloop import on_loop_thread

if TYPE_CHECKING:  # the mirror is imported only by a relay that is given one
    from edge_vis.shell.mirror import Mirror

log = logging.getLogger(__name__)

#: how often LinkStatus samples are published (seconds)
LINK_STATUS_PERIOD = 1.0
#: seconds between two ``totals:`` log lines
TOTALS_PERIOD = 600.0


class Runtime:
    """Run one relay: links + router + engine + DDS, from a :class:`RelayProfile`.

    ``publisher_factory`` builds the DDS side once the loop runs (default: a
    :class:`~edge_vis.dds.bridge.DdsBridge` on the profile's domain and partitions);
    pass ``None`` for a JAUS-only relay. Use as::

        runtime = Runtime(profile)
        await runtime.start()
        await runtime.wait_stopped()    # until request_stop() (signal handler)
    """

    def __init__(
        self,
        profile: RelayProfile,
        *,
        catalogue: Catalogue | None = None,
        publisher_factory: Callable[[Runtime], Any] | str | None = "dds",
        mirror: Mirror | None = None,
        shutdown_timeout: float = 3.0,
    ) -> None:
        self.profile = profile
        self.catalogue = catalogue or _catalogue_for(profile)
        limits = profile.limits
        self.router = Router([profile.jaus_id], config=RouterConfig(
            max_routes=limits.max_routes, max_duplicates=limits.max_duplicates))
        self.engine: Engine | None = None
        self.links: dict[str, Link] = {}
        self.counters: Counter[str] = Counter()
        #: DDS samples published, per topic
        self.published: Counter[str] = Counter()
        self._publisher_factory = publisher_factory
        self.publisher: Any = None
        self._mirror = mirror
        self._shutdown_timeout = shutdown_timeout
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        #: a link thread asked the loop to arm its timer earlier (not yet done)
        self._rearm_posted = False
        self._stopped: asyncio.Event | None = None
        self._shutdown_done: asyncio.Event | None = None
        self._status_task: asyncio.Task[None] | None = None
        self._log = LogLimiter(log)
        self.first_discovery_at: float | None = None
        self.images: Any = None  # the UDT image service, when the profile has [bulk]
        self.jaus_bps = 0.0  # JAUS traffic on all links now (bit/s): the bulk budget's share
        #: the bandwidth planner, when a link has a link profile (see edge_vis.bandwidth)
        self.planner: FleetPlanner | None = None
        #: (from link, to link) pairs the router forwards between ([routing] forward)
        self.forwarding: frozenset[tuple[str, str]] = frozenset()

    # -- life cycle ------------------------------------------------------------------------
    async def start(self) -> None:
        """Open links and DDS, start the engine; raises EdgeVisError on a bad set-up."""
        loop = self._loop = asyncio.get_running_loop()
        self._stopped = asyncio.Event()
        self._shutdown_done = asyncio.Event()
        specs = {lp.name: lp.spec for lp in self.profile.links if lp.spec is not None}
        self.planner = (FleetPlanner(self.profile, specs, self.catalogue, self._link_of)
                        if specs else None)
        self.engine = Engine(
            self.profile, catalogue=self.catalogue, wall_offset=time.time() - loop.time(),
            planner=self.planner,
            # on a DDS domain other relays may reach the same vehicles: one serves each
            arbitrate=self._publisher_factory == "dds",
        )
        self.engine.link_of = self._link_of
        # what the translators' options name must exist (edge-vis check does the same)
        self.engine.manager.verify(self.catalogue, self.profile.source)
        verify_discovery(self.profile.vehicles, self.catalogue, self.profile.source)
        if self._publisher_factory == "dds":
            self.publisher = self._open_dds()
        elif callable(self._publisher_factory):
            self.publisher = self._publisher_factory(self)
        if self.profile.bulk is not None:
            self._start_bulk(self.profile.bulk)
        for link_profile in self.profile.links:
            await self._open_link(link_profile)
        for note in self._apply_routing(self.profile.routing):
            log.warning("%s", note)
        log.info(
            "relay %s (%s%s) running: links %s, translators %s",
            self.profile.jaus_id, self.profile.name,
            f", named {self.profile.relay_name} on DDS"
            if self.profile.relay_name != str(self.profile.jaus_id) else "",
            ", ".join(self.links) or "none",
            ", ".join(t.name for t in self.engine.manager.translators) or "none",
        )
        if self.profile.operators.closed:
            log.warning("no [[operators]] in the profile and access.any_operator is false: "
                        "every control request will be refused")
        self._pump_engine(loop.time())
        self._status_task = loop.create_task(self._publish_link_status())

    async def _open_link(self, link_profile: LinkProfile) -> None:
        # the URL and the plugin edge-vis check validates (LinkProfile.link_url)
        name, url = link_profile.name, link_profile.link_url
        link: Link = create_link(url, name=name)
        if self._mirror is not None:
            self._mirror.attach(link)
        await link.open(self._on_packets, self._on_link_state, pass_through=self._pass_through)
        self.links[name] = link
        spec = self._spec(name)
        if spec is not None and spec.limited:
            # paced at the plan's budget, fragmented to the radio's MTU, stale telemetry
            # replaced by newer (edge_vis.routing.traffic)
            self.router.add_link(name, mtu=min(link.mtu, spec.mtu),
                                 bandwidth_bps=spec.budget_bps, overhead=spec.overhead,
                                 latest_wins=True)
            log.info("link %s open: %s (mtu %d, budget %.0f B/s)", name, url,
                     min(link.mtu, spec.mtu), spec.budget_bytes)
            return
        self.router.add_link(name, mtu=link.mtu, bandwidth_bps=link.bandwidth_bps,
                             overhead=link.overhead)
        log.info("link %s open: %s (mtu %d)", name, url, link.mtu)

    def _apply_routing(self, routing: RoutingProfile) -> list[str]:
        """Switch the router's forwarding between the open links to ``routing``; returns
        what it could not apply (a link that is not open)."""
        wanted = {pair for pair in routing.pairs()
                  if pair[0] in self.links and pair[1] in self.links}
        missing = sorted({name for pair in routing.pairs() for name in pair
                          if name not in self.links})
        for source, target in self.forwarding - wanted:
            self.router.set_relay(source, target, False, both_ways=False)
        for source, target in wanted - self.forwarding:
            self.router.set_relay(source, target, both_ways=False)
        if wanted != self.forwarding:
            shown = sorted({tuple(sorted(pair)) for pair in wanted})
            log.info("forwarding JAUS traffic between links: %s",
                     ", ".join(f"{a} <-> {b}" for a, b in shown) or "none")
        self.forwarding = frozenset(wanted)
        return [f"routing.forward: link {name!r} is not open (links are opened at start)"
                for name in missing]

    def _spec(self, link: str) -> LinkSpec | None:
        for lp in self.profile.links:
            if lp.name == link:
                return lp.spec
        return None

    def _start_bulk(self, bulk: BulkProfile) -> None:
        """The UDT image receiver: spooled, verified, published here, forwarded on."""
        udt = plugins.load(plugins.BULK, "udt")  # checked against the group's BulkChannel contract
        loop = self._loop
        assert loop is not None

        def publish(topic: str, sample: dict[str, Any]) -> None:  # from UDT threads
            loop.call_soon_threadsafe(self._publish, topic, sample)

        self.images = udt.ImageService(
            bulk.directory, bulk.listen, spool_dir=bulk.spool, forward=bulk.forward,
            quota_bytes=bulk.quota_bytes, publish=publish, publish_data=bulk.publish_data,
            max_rate_bps=bulk.max_rate_bps, forward_lanes=bulk.forward_lanes,
            keys=udt.load_keys(bulk.keys) if bulk.keys is not None else None,
            sources=bulk.sources, fetch_priority=bulk.fetch_priority,
            fetch_budget_bps=bulk.fetch_budget or None, reserved_bps=lambda: self.jaus_bps,
        ).start()
        host, port = self.images.address
        log.info("receiving images over UDT on %s:%d into %s%s", host, port, bulk.directory,
                 f", forwarding to {', '.join(bulk.forward)}" if bulk.forward else "")

    def _open_dds(self) -> Any:
        from edge_vis.dds.bridge import DdsBridge  # imported lazily: cyclonedds is optional
        from edge_vis.dds.topics import TopicRegistry

        assert self.engine is not None
        registry = TopicRegistry.standard()
        for translator in self.engine.manager.translators:
            registry.register_all(translator.topic_types, owner=translator.name)
        dds = self.profile.dds
        if dds.security is not None and self.profile.operators.any_operator:
            raise ConfigError([(self.profile.source, "access.any_operator",
                                "with [dds.security] only the listed [[operators]] can be "
                                "authenticated: set access.any_operator = false")])
        bridge = DdsBridge(dds.domain, dds.partitions, registry,
                           max_products=self.profile.limits.max_products,
                           security=dds.security)
        published, subscribed = self.engine.manager.topics()
        bridge.open_writers([*published, "LinkStatus", "RelayStatus"])
        bridge.subscribe(["RelayStatus"], self._on_relay_status, loop=self._loop)
        subscribed = [t for t in dict.fromkeys(subscribed)]
        if subscribed:
            bridge.watch_writers(self._on_operator_lost, loop=self._loop)
            if dds.security is None:
                bridge.subscribe(subscribed, self._on_sample, loop=self._loop)
            else:  # each operator's own partition: where a command arrives proves its sender
                for operator in self.profile.operators.operators:
                    bridge.subscribe(subscribed, functools.partial(self._on_sample_from,
                                                                   operator),
                                     loop=self._loop, partition=operator_partition(operator))
        log.info("DDS domain %d, partitions %s%s: publishing %s; subscribed to %s",
                 dds.domain, list(dds.partitions) or ["(default)"],
                 ", DDS Security on, commands from each operator's partition"
                 if dds.security is not None else "",
                 ", ".join(published), ", ".join(subscribed))
        return bridge

    def apply_profile(self, profile: RelayProfile) -> list[str]:
        """Take a reloaded profile (SIGHUP, :mod:`edge_vis.shell.reload`) while running.

        ``profile`` must keep this relay's id, links, DDS and translators; forwarding
        between links changes at once; the engine applies rates, timing and vehicle
        profiles. Returns what it could not apply.
        """
        self.profile = profile
        if self.engine is None or self._loop is None:
            return []
        now = self._loop.time()
        not_applied = self._apply_routing(profile.routing)
        not_applied += self.engine.apply_profile(profile, now)
        self._pump_engine(now)
        return not_applied

    def set_link_rate(self, link: str, bit_rate: float) -> None:
        """A new measured rate of ``link`` (a radio that changed modulation, say): plan the
        report rates again and update the vehicles' events."""
        if self.engine is None or self._loop is None:
            return
        now = self._loop.time()
        self.engine.set_link_rate(link, bit_rate, now)
        self._pump_engine(now)

    def _link_of(self, address: JausAddress) -> str:
        route = self.router.lookup(address)
        return route.link if route is not None else ""

    def request_stop(self) -> None:
        """Ask the relay to stop (signal handlers call this)."""
        if self._stopped is not None and not self._stopped.is_set():
            log.info("stopping: cancelling events and releasing control")
            self._stopped.set()

    async def wait_stopped(self) -> None:
        """Run until :meth:`request_stop`, then shut down cleanly."""
        assert self._stopped is not None
        await self._stopped.wait()
        await self.stop()

    async def stop(self) -> None:
        """Cancel events, release control, wait for the goodbyes (bounded), close all."""
        loop = asyncio.get_running_loop()
        engine = self.engine
        if engine is not None and not engine.is_shut_down:
            engine.shutdown(loop.time())
            self._pump_engine(loop.time())
            assert self._shutdown_done is not None
            try:
                await asyncio.wait_for(self._shutdown_done.wait(), self._shutdown_timeout)
            except TimeoutError:
                log.warning("shutdown: vehicles did not answer within %.1f s",
                            self._shutdown_timeout)
            # let the last queued packets leave
            self._on_timer()
            await asyncio.sleep(0.05)
        if self.images is not None:
            self.images.stop()  # what was received stays in the spool for the next start
            self.images = None
        if self._status_task is not None:
            self._status_task.cancel()
        if self._timer is not None:
            self._timer.cancel()
        for link in self.links.values():
            await link.close()
        if self.publisher is not None:
            self.publisher.close()
            self.publisher = None
        if self._mirror is not None:
            self._mirror.close()
        self.log_totals()
        log.info("stopped")

    # -- inputs ------------------------------------------------------------------------------
    def _on_packets(self, link: str, peer: Peer, packets: list[Packet]) -> None:
        assert self._loop is not None
        now = self._loop.time()
        try:
            actions = self.router.receive(link, peer, packets, now)
        except EdgeVisError as exc:  # a router refusal is about this input only
            self.counters["router errors"] += 1
            self._log.warning("router", now, "router refused packets from %s: %s", link, exc)
            return
        self._carry_router(actions, now)
        self._pump_engine(now)

    def _pass_through(self, link: str, peer: Peer, wires: list[bytes]) -> int:
        """Messages that only pass through between forwarded links, as their bytes (see
        :meth:`Router.forward`); how many the router took (the rest go to _on_packets)."""
        if not self.forwarding:
            return 0
        assert self._loop is not None
        now = self._loop.time()
        taken, actions, queued = self.router.forward(link, peer, wires, now)
        if actions:
            self._carry_router(actions, now)
        if queued:
            self._rearm(now)
        return taken

    def _on_sample(self, topic: str, sample: dict[str, Any]) -> None:
        assert self._loop is not None and self.engine is not None
        now = self._loop.time()
        self.counters["samples in"] += 1
        self.engine.receive_sample(topic, sample, now)
        self._pump_engine(now)

    def _on_relay_status(self, topic: str, sample: dict[str, Any]) -> None:
        """A relay on the domain (this one included) said what it reaches and serves."""
        assert self._loop is not None
        if self.engine is None:
            return
        now = self._loop.time()
        self.engine.receive_relay_status(sample, now)
        self._pump_engine(now)

    def _on_sample_from(self, sender: str, topic: str, sample: dict[str, Any]) -> None:
        """A command read in ``sender``'s partition, which only ``sender``'s signed
        permissions may write to: its ``operator_id`` must be ``sender``."""
        claimed = str(sample.get("operator_id", ""))
        if claimed == sender:
            self._on_sample(topic, sample)
            return
        assert self._loop is not None and self.engine is not None
        now = self._loop.time()
        action = sample.get("action", 0)  # the enum member, its name or its value
        if topic == "EmergencyCommand" and str(getattr(action, "name", action)).lower() in (
                "0", "set"):
            # a stop is never lost: it is obeyed as the operator who proved who it is
            self.counters["emergency stops taken as their sender"] += 1
            self._log.warning("impersonation", now, "EmergencyCommand SET claiming %r taken "
                              "as %s, its sender", claimed, sender)
            self._on_sample(topic, {**sample, "operator_id": sender})
            return
        self.counters["commands refused: operator_id is not the sender"] += 1
        reason = f"operator_id {claimed!r} refused: sent by {sender}"
        self._log.warning("impersonation", now, "%s %s", topic, reason)
        self.engine.refuse_sample(topic, sample, reason, now)
        self._pump_engine(now)

    def _on_operator_lost(self, operator_id: str) -> None:
        """Every DDS writer of ``operator_id`` is gone (see ``DdsBridge.watch_writers``)."""
        assert self._loop is not None
        if self.engine is None:
            return
        now = self._loop.time()
        self.counters["operators lost"] += 1
        self.engine.operator_lost(operator_id, now)
        self._pump_engine(now)

    def _on_link_state(self, link: str, state: str, reason: str) -> None:
        if state == "down":
            log.warning("link %s down: %s", link, reason)
        else:
            log.info("link %s %s%s", link, state, f": {reason}" if reason else "")

    def _on_timer(self) -> None:
        assert self._loop is not None
        self._timer = None
        self._timer_at = None
        now = self._loop.time()
        compactions = self.router.compactions
        self._carry_router(self.router.on_timer(now), now)
        if self.engine is not None:
            self.engine.on_timer(now)
        self._pump_engine(now)
        if self.router.compactions != compactions:  # a burst is over: give its memory back
            release_memory()

    # -- outputs -----------------------------------------------------------------------------
    def _carry_router(self, actions: Iterable[object], now: float) -> None:
        engine = self.engine
        for action in actions:
            if isinstance(action, SendPackets | ForwardWires):
                link = self.links.get(action.link)
                if link is None:
                    self.counters["send to unknown link"] += 1
                    continue
                if isinstance(action, ForwardWires):
                    link.send_wires(action.wires, action.peer)
                elif action.urgent:
                    link.send_urgent(list(action.packets), action.peer)
                else:
                    link.send(list(action.packets), action.peer)
            elif isinstance(action, Deliver):
                packet = action.packet
                if packet.message_code is None:
                    continue
                try:
                    dialects = engine.dialects_of(packet.source) if engine is not None \
                        else ()
                    message = self.catalogue.decode(packet.payload, dialects)
                except CodecError as exc:
                    self.counters["undecodable messages"] += 1
                    self._log.warning("decode", now, "undecodable message from %s: %s",
                                      packet.source, exc)
                    continue
                if engine is not None:
                    if self.first_discovery_at is None and message.name == "ReportIdentification":
                        self.first_discovery_at = now
                    engine.receive_message(packet.source, message, now)
            elif isinstance(action, DeliveryFailed):
                self.counters["delivery failed"] += 1
                log.debug("no acknowledgement from %s: %s", action.packet.destination,
                          action.reason)

    def _pump_engine(self, now: float) -> None:
        engine = self.engine
        if engine is None:
            return
        for _ in range(8):  # engine actions may produce more actions; bounded
            actions = engine.drain_actions()
            if not actions:
                break
            for action in actions:
                if isinstance(action, SendMessage):
                    self._send(action, now)
                elif isinstance(action, Publish):
                    self._publish(action.topic, action.sample)
                elif isinstance(action, Withdraw):
                    if self.publisher is not None and hasattr(self.publisher, "withdraw"):
                        self.publisher.withdraw(action.vehicle_id)
                elif isinstance(action, ShutdownComplete) and self._shutdown_done is not None:
                    if on_loop_thread(self._loop):
                        self._shutdown_done.set()
                    else:
                        assert self._loop is not None
                        self._loop.call_soon_threadsafe(self._shutdown_done.set)
        self._rearm(now)

    def _send(self, action: SendMessage, now: float) -> None:
        try:
            dialects = self.engine.dialects_of(action.destination) \
                if self.engine is not None and not action.destination.is_broadcast else ()
            payload = self.catalogue.encode(_code_of(self.catalogue, action), action.fields,
                                            dialects)
        except EdgeVisError as exc:
            self.counters["encode errors"] += 1
            log.error("cannot encode %s for %s: %s", action.name, action.destination, exc)
            return
        destination = action.destination
        packet = Packet(
            destination, self.profile.jaus_id, payload, priority=self._priority(action),
            broadcast=Broadcast.GLOBAL if destination.is_broadcast else Broadcast.NONE,
        )
        try:
            self._carry_router(self.router.send(
                packet, now, urgent=action.traffic_class == EMERGENCY_CLASS), now)
        except EdgeVisError as exc:
            self.counters["send errors"] += 1
            self._log.warning("send", now, "cannot send %s to %s: %s", action.name,
                              destination, exc)
        self.counters["messages sent"] += 1

    def _publish(self, topic: str, sample: Mapping[str, Any]) -> None:
        if topic == "ImageProduct" and self.images is not None \
                and not sample.get("transfer_id"):
            sample = self.images.announce(sample)  # one product per image; fetch it
        elif topic == "RelayStatus":  # the core knows the links by name; here by state
            sample = {**sample, "links": [{"link": name, "up": link.stats().state == "open"}
                                          for name, link in self.links.items()]}
        self.counters["samples out"] += 1
        if self.publisher is None:
            return
        try:
            self.publisher.publish(topic, sample)
        except (EdgeVisError, ValueError, KeyError, TypeError) as exc:
            self.counters["publish errors"] += 1
            log.error("cannot publish %s: %s", topic, exc)
            return
        self.published[topic] += 1

    def tallies(self) -> dict[Tally, int]:
        """Every count since start, as data: the relay's, the engine's, each translator's
        failures, each link's traffic and drops, the samples published per topic."""
        out: dict[Tally, int] = tallies_of(Kind.RELAY, self.counters)
        if self.engine is not None:
            out.update(tallies_of(Kind.ENGINE, {k.replace("_", " "): v for k, v in
                                                self.engine.counters.items()}))
            for name, count in self.engine.manager.errors.items():
                out[Tally(Kind.TRANSLATOR_ERROR, "errors", name)] = count
            for (name, reason), count in self.engine.manager.drops.items():
                out[Tally(Kind.TRANSLATOR_DROP, reason, name)] = count
        for sample in self.link_status():
            name = sample["link"]
            out.update(tallies_of(Kind.LINK_TRAFFIC, {
                "messages in": sample["messages_in"], "messages out": sample["messages_out"]},
                name))
            out.update(tallies_of(Kind.LINK_DROP, {d["traffic_class"]: d["count"]
                                                   for d in sample["drops"]}, name))
        for topic, count in self.published.items():
            out[Tally(Kind.PUBLISHED, "samples", topic)] = count
        return out

    def totals(self) -> dict[str, int]:
        """Every count since start, flat and sorted (:func:`accounting.totals`; logged
        every :data:`TOTALS_PERIOD` and on stop, so a journal shows where messages went)."""
        return totals(self.tallies())

    def losses(self) -> dict[str, int]:
        """What the relay accepted and then lost, by counter (empty when nothing)."""
        return losses(self.tallies())

    def log_totals(self) -> None:
        """One log line with :meth:`totals` as a JSON object (drop reasons hold commas)."""
        tallies = self.tallies()
        log.info("totals: %s", json.dumps(totals(tallies)))
        log.info("losses: %s", json.dumps(losses(tallies)))

    def _rearm(self, now: float) -> None:
        assert self._loop is not None
        deadlines = [d for d in (self.router.next_deadline(),
                                 self.engine.next_deadline() if self.engine else None)
                     if d is not None]
        if not deadlines:
            return
        when = max(min(deadlines), now)
        if self._timer_at is not None and self._timer_at <= when:
            return
        if not on_loop_thread(self._loop):  # a link thread: the loop arms its own timer
            if not self._rearm_posted:
                self._rearm_posted = True
                self._loop.call_soon_threadsafe(self._rearm_on_loop)
            return
        if self._timer is not None:
            self._timer.cancel()
        self._timer_at = when
        self._timer = self._loop.call_at(when, self._on_timer)

    def _rearm_on_loop(self) -> None:
        assert self._loop is not None
        self._rearm_posted = False
        self._rearm(self._loop.time())

    # -- health and mirror ----------------------------------------------------------------------
    def _priority(self, action: SendMessage) -> int:
        """The header priority of ``action``: its traffic class on its link's profile."""
        if not action.traffic_class:
            return action.priority
        destination = action.destination
        link = self._link_of(destination) if not destination.is_broadcast else None
        spec = self._spec(link) if link else None
        if spec is None:  # a link without a link profile: as the sender asked
            return action.priority
        return priority_for(action.traffic_class, action.priority, spec.priorities)

    def link_status(self) -> list[dict[str, Any]]:
        """One ``LinkStatus`` sample per link."""
        queues = self.router.stats().links
        samples = []
        wall_ms = int(time.time() * 1000)
        for name, link in self.links.items():
            stats = link.stats()
            queue = queues.get(name)
            drops = Counter(dict(stats.drops))
            spec = self._spec(name)
            if queue is not None:
                priorities = spec.priorities if spec else DEFAULT_PRIORITIES
                for drop, count in queue.drops.items():  # name the classes, not numbers
                    drops[drop.named(priorities)] += count
            samples.append({
                "link": name, "vehicle_id": "", "relay": self.profile.relay_name,
                "up": stats.state == "open",
                "budget_bps": (spec.budget_bps if spec is not None and spec.limited
                               else float(link.bandwidth_bps or 0.0)),
                "measured_bps": 0.0,
                "queue_depth": (queue.depth if queue else 0) + stats.queue_depth,
                "drops": [{"traffic_class": k, "count": v} for k, v in sorted(drops.items())],
                "bytes_in": stats.bytes_in, "bytes_out": stats.bytes_out,
                "messages_in": stats.messages_in, "messages_out": stats.messages_out,
                "timestamp_ms": wall_ms,
            })
        return samples

    async def _publish_link_status(self) -> None:
        previous: dict[str, tuple[float, int]] = {}
        next_totals = time.monotonic() + TOTALS_PERIOD
        while True:
            await asyncio.sleep(LINK_STATUS_PERIOD)
            now = time.monotonic()
            if now >= next_totals:
                next_totals = now + TOTALS_PERIOD
                self.log_totals()
            jaus_bps = 0.0
            for sample in self.link_status():
                total = sample["bytes_in"] + sample["bytes_out"]
                then, before = previous.get(sample["link"], (now, total))
                if now > then:
                    sample["measured_bps"] = (total - before) * 8 / (now - then)
                    jaus_bps += sample["measured_bps"]
                previous[sample["link"]] = (now, total)
                self._publish("LinkStatus", sample)
            self.jaus_bps = jaus_bps


def _code_of(catalogue: Catalogue, action: SendMessage) -> str | int:
    """What to encode ``action`` as: its name, or the code of the definition of that name
    in ``action.service_set`` (two sets may use one name; the code tells them apart)."""
    if action.service_set is None:
        return action.name
    try:
        return catalogue.by_name(action.name, action.service_set).code
    except KeyError:
        raise EncodeError(f"no message named {action.name!r} in service set "
                          f"{action.service_set!r}") from None


def _catalogue_for(profile: RelayProfile) -> Catalogue:
    from edge_vis.catalogue.jsidl import profile_catalogue

    return profile_catalogue(profile.jsidl)


__all__ = ["Runtime"]
