"""The node-manager role: where each JAUS packet goes. No I/O, no clock.

Every method takes ``now`` (seconds, any monotonic origin) and returns *actions* for the
I/O shell to carry out: :class:`SendPackets` (write to a link), :class:`Deliver` (hand a
whole message to a local component) and :class:`DeliveryFailed` (an ACK-requested send
got no answer). The shell calls :meth:`Router.on_timer` at :meth:`Router.next_deadline`.

Theory of operation
-------------------
*Address book.* Every packet received teaches the router that its source component lives
behind ``(link, peer)``; a component not heard from yet is looked for where another
component of its subsystem was heard. Learned entries expire after ``peer_timeout`` s of silence.
Static entries (profile seeds, wildcards allowed, e.g. ``5.*.*`` → radio) answer when no
learned entry exists; the most specific pattern wins.

*Local components* are the relay's own JAUS ids. A packet addressed to one (or a
broadcast matching one) is delivered up, after large-message reassembly.

*Forwarding* between links happens only where the relay switch for that (from, to) link
pair is on (off by default, as ``AllowRelay=0`` in the JAUS Toolset): a unicast goes to
the link where its destination lives, an unknown unicast or a broadcast is fanned out to
every relay-enabled link. Nothing is ever sent back out of the link it came from.

*Sending* from a local component (:meth:`Router.send`) numbers the packet from that
component's own counter (starting at 1), fragments it to the link MTU, and routes it:
known destination → unicast; wildcard → broadcast on every link; unknown destination →
broadcast with ACK requested (JTS behaviour: the owner's ACK teaches the route).

*Pass-through.* :meth:`Router.forward` takes datagrams that only pass through as their
bytes (one general transport message each, as received) and decides for them without
building a :class:`~edge_vis.jaus.transport.Packet`: the header fields it needs are read
from the bytes, the duplicate check is the same table's, and the route comes from a
cache of the full path's decisions per ``(link, peer, source, destination)``, emptied
whenever anything those decisions read changes (the address book, static routes, relay
switches, local components, links). It takes a batch only if the full path would have
forwarded every message of it unchanged (no ACK/NAK, no local or broadcast address, a
route already learned, the source's route unchanged, no duplicate), else none of it
(:meth:`Router.receive` then handles the batch); counters, the duplicate table and the
links' budgets and queues come out as on the full path, and what leaves is
:class:`ForwardWires`, the same bytes in the same order.

*Duplicates* (redundant paths, radio retries) are dropped when ``(source, destination,
sequence, data flags, payload)`` was seen within ``duplicate_window`` s; a duplicate that asks
for an ACK is ACKed again, since our first ACK was evidently lost. The table keeps one
64-bit hash of those fields per packet, taken over the packet's bytes from the destination
on, plus the data flags (two different packets sharing it within the window is a chance
of about 1 in 10^10 at 65,536 entries; the hash of bytes is salted per process, so it
cannot be provoked from outside). After a burst, once the table is down to an eighth
of its size, it is rebuilt small (:attr:`Router.compactions` counts it, so that the shell
can hand the freed memory back to the system).

*ACK/NAK.* ACK requests addressed to a local component are answered (empty payload, same
sequence number and priority, ACK/NAK = 3). Our own ACK-requested sends are repeated
after ``ack_timeout`` s up to ``ack_retries`` times, then reported as
:class:`DeliveryFailed`. ACK and NAK packets are never delivered up.

*Queues.* Each link has four FIFO queues, one per header priority. A link with a known
bandwidth is paced by a byte budget refilled at that rate (cost = data size + the link's
framing overhead); a link reported busy (:meth:`Router.set_busy`) holds everything.
Queued packets leave highest priority first; when a link's queue exceeds its byte limit
the oldest packet of the lowest non-empty priority is dropped and counted. On a link added
with ``latest_wins`` a report, Event or query waiting at a low priority is replaced by a
newer one of the same kind (:func:`edge_vis.routing.traffic.latest_wins_key`).

*Urgent path.* A message sent with ``urgent=True`` (the ``emergency`` traffic class: an
emergency stop) never enters the queues: it leaves at once as its own
:class:`SendPackets` with ``urgent`` set, ahead of everything queued, even on a link that
is backlogged, paced below zero, full or reported busy; it is never dropped for the queue
limit, and its bytes are charged to the link's budget so the pacing of the rest stays
honest. The link carries it ahead of its own write buffer (:meth:`Link.send_urgent
<edge_vis.routing.link.Link.send_urgent>`).

State per link:   ``idle`` ─(budget spent / busy)→ ``backlogged`` ─(queue empty)→ ``idle``
"""

from __future__ import annotations

import logging
from collections import Counter, deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

from edge_vis.errors import EncodeError, LocalProtocolError
from edge_vis.jaus.address import ADDRESSES, JausAddress, address_from_id
from edge_vis.jaus.transport import (
    HEADER,
    JTS_MAX_PAYLOAD,
    MIN_DATA_SIZE,
    AckNak,
    Broadcast,
    DataFlags,
    Packet,
    encode_packet,
    packet_from_wire,
)
from edge_vis.routing.link import Peer, format_peer
from edge_vis.routing.traffic import LATEST_WINS_MAX_PRIORITY, QueueDrop, latest_wins_key

try:  # large-message support lives in its own module; routing works without it
    from edge_vis.jaus.fragments import Reassembler, fragment
except ImportError:  # pragma: no cover - seam for builds without edge_vis.jaus.fragments
    Reassembler = None  # type: ignore[assignment,misc]
    fragment = None  # type: ignore[assignment]

log = logging.getLogger(__name__)

_ACKS = (AckNak.ACK, AckNak.NAK)


# -- actions ---------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class SendPackets:
    """Write ``packets`` on link ``link`` to ``peer`` (``None``: broadcast on that link)."""

    link: str
    peer: Peer | None
    packets: tuple[Packet, ...]
    #: jump the link's own write buffer too (the urgent path, see the module docstring)
    urgent: bool = False


@dataclass(frozen=True, slots=True)
class Deliver:
    """Hand a whole message to the local component ``packet.destination`` (or, for a
    broadcast, to every local component it matches). ``link``/``peer`` say where it came
    from (``None`` for a message between two local components)."""

    packet: Packet
    link: str | None
    peer: Peer | None


@dataclass(frozen=True, slots=True)
class DeliveryFailed:
    """An ACK-requested packet got no ACK after every retry."""

    packet: Packet
    reason: str


@dataclass(frozen=True, slots=True)
class ForwardWires:
    """Write general transport messages given as their bytes (as they were received, see
    :meth:`Router.forward`) on link ``link`` to ``peer``."""

    link: str
    peer: Peer | None
    wires: tuple[bytes, ...]


Action = SendPackets | Deliver | DeliveryFailed | ForwardWires
#: a pass-through decision: the source's route, the target link and peer
_Decision = tuple["Route", str, Peer | None]

#: a decision not made yet (see :meth:`Router.forward`)
_UNDECIDED = object()
#: ACK/NAK bits of the flags byte
_ACK_BITS = 0x30


class _NewSend:
    """Builds a :class:`SendPackets` without the frozen dataclass's ``object.__setattr__``
    per field (one per batch of every relayed packet): same slots, then ``__class__``
    becomes ``SendPackets`` (as :class:`edge_vis.jaus.transport._Decoded` does)."""

    __slots__ = SendPackets.__slots__  # type: ignore[attr-defined]

    def __init__(self, link: str, peer: Peer | None, packets: tuple[Packet, ...],
                 urgent: bool) -> None:
        self.link = link
        self.peer = peer
        self.packets = packets
        self.urgent = urgent
        self.__class__ = SendPackets  # type: ignore[assignment]


def _send_packets(link: str, peer: Peer | None, packets: tuple[Packet, ...],
                  urgent: bool = False) -> SendPackets:
    return _NewSend(link, peer, packets, urgent)  # type: ignore[return-value]


class _NewWires:
    """:class:`ForwardWires` built as :class:`_NewSend` builds :class:`SendPackets`."""

    __slots__ = ForwardWires.__slots__  # type: ignore[attr-defined]

    def __init__(self, link: str, peer: Peer | None, wires: tuple[bytes, ...]) -> None:
        self.link = link
        self.peer = peer
        self.wires = wires
        self.__class__ = ForwardWires  # type: ignore[assignment]


def _forward_wires(link: str, peer: Peer | None, wires: tuple[bytes, ...]) -> ForwardWires:
    return _NewWires(link, peer, wires)  # type: ignore[return-value]


# -- configuration and state -----------------------------------------------------------
@dataclass(frozen=True, slots=True)
class RouterConfig:
    """Timers and bounds of the router (seconds / bytes)."""

    duplicate_window: float = 2.0
    ack_timeout: float = 0.1
    ack_retries: int = 3
    peer_timeout: float = 120.0
    sweep_interval: float = 1.0
    reassembly_timeout: float = 5.0
    max_duplicates: int = 65536
    #: learned addresses kept; past it the earliest learned is forgotten (counted)
    max_routes: int = 4096


@dataclass(slots=True)
class Route:
    """Where a JAUS address lives: ``link`` and the ``peer`` on it."""

    link: str
    peer: Peer | None
    static: bool = False
    seen: float = 0.0


@dataclass(slots=True)
class _LinkState:
    name: str
    mtu: int
    bandwidth_bps: float | None
    overhead: int
    queue_limit: int
    burst: float
    tokens: float = 0.0
    refilled: float | None = None
    busy: bool = False
    queued_bytes: int = 0
    queues: tuple[deque[tuple[Peer | None, Packet, int]], ...] = field(
        default_factory=lambda: tuple(deque() for _ in range(4))
    )
    drops: Counter[QueueDrop] = field(default_factory=Counter)
    sent: int = 0
    latest_wins: bool = False

    @property
    def depth(self) -> int:
        return sum(len(q) for q in self.queues)

    def cost(self, packet: Packet) -> int:
        """Budget bytes ``packet`` takes: data size (payload + 14 header bytes) + framing."""
        return len(packet.payload) + 14 + self.overhead

    def refill(self, now: float, rate: float) -> None:
        """Add the budget earned at ``rate`` bit/s since the last refill."""
        if self.refilled is not None:
            self.tokens = min(self.burst, self.tokens + (now - self.refilled) * rate / 8)
        self.refilled = now


@dataclass(slots=True)
class _Pending:
    packet: Packet
    link: str | None  # None: not yet routed (sent as broadcast on every link)
    peer: Peer | None
    deadline: float
    tries: int = 0


@dataclass(frozen=True, slots=True)
class LinkQueueStats:
    """Queue state of one link as the router sees it."""

    depth: int
    queued_bytes: int
    busy: bool
    sent: int
    drops: dict[QueueDrop, int]


@dataclass(frozen=True, slots=True)
class RouterStats:
    """Counters of routing decisions (totals since start)."""

    counters: dict[str, int]
    links: dict[str, LinkQueueStats]
    routes: int
    pending_acks: int


# -- the router ------------------------------------------------------------------------
class Router:
    """Sans-I/O JAUS node manager: address book, local delivery, relay, ACKs, queues."""

    def __init__(
        self, local: Iterable[JausAddress] = (), *, config: RouterConfig | None = None
    ) -> None:
        self.config = config or RouterConfig()
        self._local: set[JausAddress] = set(local)
        self._seq: dict[JausAddress, int] = {}
        self._links: dict[str, _LinkState] = {}
        self._relay: set[tuple[str, str]] = set()
        self._learned: dict[JausAddress, Route] = {}
        self._static: list[tuple[JausAddress, Route]] = []
        self._seen: dict[int, float] = {}
        # the keys each call added, with their common expiry, oldest first
        self._seen_order: deque[tuple[float, list[int]]] = deque()
        self._seen_peak = 0
        #: times the duplicate table was rebuilt small after a burst
        self.compactions = 0
        # static routes matched per destination (cleared when the static routes change)
        self._static_hits: dict[JausAddress, Route] = {}
        self._pending: dict[tuple[int, int], _Pending] = {}
        # the pass-through path's decisions: (link, peer) -> (source id, destination id)
        # -> (source's route, target link, target peer), or None: not for that path
        self._decisions: dict[tuple[str, Peer], dict[tuple[int, int], _Decision | None]] = {}
        self._next_sweep: float | None = None
        self._reassembler = (
            Reassembler(timeout=self.config.reassembly_timeout) if Reassembler is not None else None
        )
        self.counters: Counter[str] = Counter()

    # -- configuration -----------------------------------------------------------------
    def add_local(self, address: JausAddress) -> None:
        """Make ``address`` one of ours: messages to it are delivered up."""
        if address.is_broadcast:
            raise ValueError(f"a local component needs a concrete address, not {address}")
        self._local.add(address)
        self._decisions.clear()

    def remove_local(self, address: JausAddress) -> None:
        """Stop delivering to ``address``."""
        self._local.discard(address)
        self._decisions.clear()

    @property
    def local(self) -> frozenset[JausAddress]:
        """The local component addresses."""
        return frozenset(self._local)

    def add_link(
        self,
        name: str,
        *,
        mtu: int = JTS_MAX_PAYLOAD,
        bandwidth_bps: float | None = None,
        overhead: int = 29,
        queue_limit: int = 32768,
        latest_wins: bool = False,
    ) -> None:
        """Register a link. ``overhead``: framing bytes added per packet on the medium
        (29 for UDP/IP + version byte, about 18 for serial); ``queue_limit``: bytes held
        while the link is backlogged before the lowest priority is dropped;
        ``latest_wins``: a newer report or query replaces a queued older one."""
        # a budget that may go negative: one packet of any size can always leave, and the
        # burst stays small (50 ms of the link) so a slow radio is not flooded at once
        burst = max(64.0, (bandwidth_bps or 0.0) / 8 * 0.05)
        self._links[name] = _LinkState(
            name, mtu, bandwidth_bps, overhead, queue_limit, burst, tokens=burst,
            latest_wins=latest_wins,
        )
        self._decisions.clear()

    def remove_link(self, name: str) -> None:
        """Forget a link, its routes, relay switches and queue."""
        self._links.pop(name, None)
        self._relay = {pair for pair in self._relay if name not in pair}
        self._learned = {a: r for a, r in self._learned.items() if r.link != name}
        self._static = [(a, r) for a, r in self._static if r.link != name]
        self._static_hits.clear()
        self._decisions.clear()

    def set_relay(self, source: str, target: str, enabled: bool = True, *,
                  both_ways: bool = True) -> None:
        """Switch forwarding from link ``source`` to link ``target`` (and back) on or off."""
        for pair in ((source, target), (target, source)) if both_ways else ((source, target),):
            if enabled:
                self._relay.add(pair)
            else:
                self._relay.discard(pair)
        self._decisions.clear()

    def add_route(self, pattern: JausAddress, link: str, peer: Peer | None) -> None:
        """Seed the address book: ``pattern`` (wildcards allowed) lives at ``(link, peer)``."""
        self._static.append((pattern, Route(link, peer, static=True)))
        self._static.sort(key=lambda item: _wildcards(item[0]))
        self._static_hits.clear()
        self._decisions.clear()

    def lookup(self, address: JausAddress) -> Route | None:
        """Where ``address`` lives: a learned route, else the most specific static one."""
        route = self._learned.get(address)
        if route is not None:
            return route
        route = self._static_hits.get(address)
        if route is not None:
            return route
        for pattern, static in self._static:
            if pattern.matches(address):
                if len(self._static_hits) >= self.config.max_routes:
                    self._static_hits.clear()
                self._static_hits[address] = static
                return static
        # a subsystem is one vehicle behind one link: another of its components we heard
        # from says where this one lives (no broadcast with ACK over a slow radio)
        for known, learned in self._learned.items():
            if known.subsystem == address.subsystem and not address.is_broadcast:
                return learned
        return None

    def routes(self) -> list[tuple[JausAddress, Route]]:
        """Learned then static entries of the address book."""
        return [*sorted(self._learned.items()), *self._static]

    # -- input from links ----------------------------------------------------------------
    def receive(self, link: str, peer: Peer, packets: Sequence[Packet], now: float
                ) -> list[Action]:
        """Route packets that arrived on ``link`` from ``peer``.

        Never raises: packets from a link that was not added are counted and dropped.
        """
        if link not in self._links:
            self.counters["dropped: unknown link"] += len(packets)
            return []
        actions: list[Action] = []
        out: dict[tuple[str, Peer | None], list[Packet]] = {}
        counters = self.counters
        learned = self._learned
        local = self._local
        seen = self._seen
        expiry = now + self.config.duplicate_window
        seen_order = self._seen_order
        max_duplicates = self.config.max_duplicates
        if seen_order and seen_order[0][0] <= now:
            self._expire_duplicates(now, 64)  # a little per call: no stall after a burst
        if self._next_sweep is None:
            self._next_sweep = now + self.config.sweep_interval
        counters["received"] += len(packets)
        relay = self._relay
        # the fast path: a packet of the same stream (same source and destination objects;
        # decoded addresses are shared) as the last one forwarded in this call takes that
        # one's decision; anything that changes the address book ends it
        fast_source: JausAddress | None = None
        fast_dest: JausAddress | None = None
        fast_batch: list[Packet] = []
        added: list[int] = []  # keys entered in the duplicate table
        for packet in packets:
            source = packet.source
            dest = packet.destination
            if source is fast_source and dest is fast_dest and not packet.ack_nak:
                wire = packet.wire
                key = hash(wire[4:]) + (wire[3] >> 6) if wire is not None else \
                    _duplicate_key(packet)
                until = seen.get(key)
                if until is None or until <= now:
                    if len(seen) < max_duplicates:
                        seen[key] = expiry
                        added.append(key)
                    else:
                        counters["duplicate table full"] += 1
                    fast_batch.append(packet)
                    continue
            if source in local:
                counters["dropped: own source"] += 1
                continue
            wire = packet.wire
            key = hash(wire[4:]) + (wire[3] >> 6) if wire is not None else \
                _duplicate_key(packet)
            route = learned.get(source)
            until = seen.get(key)
            if until is not None and until > now:
                counters["dropped: duplicate"] += 1
                if route is not None and route.link == link and route.peer == peer:
                    route.seen = now
                if packet.ack_nak == AckNak.REQUEST and dest in local:
                    self._queue(actions, link, peer, [_ack(packet)], now)
                    counters["acks sent"] += 1
                continue
            if len(seen) < max_duplicates:
                seen[key] = expiry
                added.append(key)
            else:
                counters["duplicate table full"] += 1
            if not source.is_broadcast:
                if route is None or route.link != link or route.peer != peer:
                    if route is None and len(learned) >= self.config.max_routes:
                        del learned[next(iter(learned))]  # re-learned on its next packet
                        counters["routes forgotten: table full"] += 1
                    learned[source] = Route(link, peer, seen=now)
                    self._decisions.clear()
                    fast_source = None
                else:
                    route.seen = now
            if packet.ack_nak in _ACKS:
                counters["acks received"] += 1
                if dest in local:
                    self._acknowledged(packet)
                    continue
            elif dest in local:
                if packet.ack_nak == AckNak.REQUEST:
                    self._queue(actions, link, peer, [_ack(packet)], now)
                    counters["acks sent"] += 1
                self._deliver_up(actions, packet, link, peer, now)
                continue
            elif dest.is_broadcast and any(dest.matches(a) for a in local):
                self._deliver_up(actions, packet, link, peer, now)
            # forwarding to other links
            if not dest.is_broadcast:
                route = learned.get(dest) or self._static_hits.get(dest) or self.lookup(dest)
                if route is not None:
                    if route.link == link:
                        counters["dropped: destination on arrival link"] += 1
                    elif (link, route.link) in relay:
                        batch = out.setdefault((route.link, route.peer), [])
                        batch.append(packet)
                        if not packet.ack_nak:
                            fast_source, fast_dest = source, dest
                            fast_batch = batch
                    else:
                        counters["dropped: relay off"] += 1
                    continue
            targets = [t for (s, t) in self._relay if s == link and t in self._links]
            if not targets and not dest.is_broadcast:
                counters["dropped: no route"] += 1
            for target in targets:
                out.setdefault((target, None), []).append(packet)
        if added:
            seen_order.append((expiry, added))
        for (target, target_peer), batch in out.items():
            counters["forwarded"] += len(batch)
            self._queue(actions, target, target_peer, batch, now)
        return actions

    def forward(self, link: str, peer: Peer, wires: Sequence[bytes], now: float
                ) -> tuple[int, list[Action], bool]:
        """The pass-through path (see the module docstring): route ``wires`` (general
        transport messages as received on ``link`` from ``peer``, one each) without
        decoding them, if every one of them only passes through.

        Returns how many it took: all or none (then the caller hands them, decoded, to
        :meth:`receive`, which decides exactly as if this had not been called); the
        actions (:class:`ForwardWires`, or what the queues of a busy or paced link let
        out); and whether :meth:`next_deadline` may have moved (something was queued).
        Never raises.
        """
        if self._next_sweep is None or link not in self._links or not wires or \
                min(map(len, wires)) < MIN_DATA_SIZE:
            return 0, [], False  # the full path sets the sweep up, or counts the drop
        decisions = self._decisions.get((link, peer))
        if decisions is None:
            decisions = self._decisions[(link, peer)] = {}
        seen = self._seen
        if len(seen) + len(wires) > self.config.max_duplicates:
            return 0, [], False  # the full path counts what the table cannot hold
        seen_order = self._seen_order
        if seen_order and seen_order[0][0] <= now:
            self._expire_duplicates(now, 64)  # as receive(): a little per call
        expiry = now + self.config.duplicate_window
        unpack = HEADER.unpack_from
        added: list[int] = []  # the duplicate table's new keys, one per message taken
        target: tuple[str, Peer | None] | None = None  # where the first message goes
        several = False  # the messages go to several (link, peer)
        last_src = last_dst = last_flags = priority = -1
        one_priority = True
        for wire in wires:
            type_hc, length, flags, dst, src = unpack(wire)
            if length != len(wire) or type_hc & 0xC0:
                break  # header compression, malformed: the full path
            if src != last_src or dst != last_dst or flags != last_flags:
                if flags & _ACK_BITS:
                    break  # ACK/NAK: the full path
                if priority < 0:
                    priority = flags & 3
                elif flags & 3 != priority:
                    one_priority = False
                found = decisions.get((src, dst), _UNDECIDED)
                if found is _UNDECIDED:
                    found = decisions[(src, dst)] = self._decide(link, peer, src, dst)
                if found is None:
                    break
                decision: _Decision = found  # type: ignore[assignment]
                decision[0].seen = now  # the source's route, as receive() does
                if target is None:
                    target = decision[1:]
                elif decision[1:] != target:
                    several = True
                last_src, last_dst, last_flags = src, dst, flags
            key = hash(wire[4:]) + (flags >> 6)  # as receive()
            until = seen.get(key)
            if until is not None and until > now:
                break  # a duplicate: the full path counts it
            seen[key] = expiry
            added.append(key)
        taken = len(added)
        if taken != len(wires):
            # all or nothing: the full path batches by destination over the whole call,
            # which a split would reorder on a shared medium; what was entered goes
            for key in added:
                del seen[key]
            return 0, [], False
        seen_order.append((expiry, added))
        assert target is not None
        groups: dict[tuple[str, Peer | None], Sequence[bytes]] = {target: wires}
        if several:  # one batch per (link, peer), in order, as receive() makes them
            groups = {}
            for wire in wires:
                _, _, _, dst, src = unpack(wire)
                found = decisions[(src, dst)]
                assert found is not None
                groups.setdefault(found[1:], []).append(wire)  # type: ignore[attr-defined]
        counters = self.counters
        counters["received"] += taken
        counters["forwarded"] += taken
        actions: list[Action] = []
        queued = False
        links = self._links
        for (target_link, target_peer), batch in groups.items():
            state = links[target_link]
            if not state.busy and not state.queued_bytes and not state.latest_wins and \
                    max(map(len, batch)) - MIN_DATA_SIZE <= state.mtu:
                rate = state.bandwidth_bps
                if rate is None:
                    state.sent += len(batch)
                    actions.append(_forward_wires(target_link, target_peer, tuple(batch)))
                    continue
                if one_priority and self._within_budget(
                        state, [priority], [len(w) - MIN_DATA_SIZE for w in batch], now, rate):
                    state.sent += len(batch)
                    actions.append(_forward_wires(target_link, target_peer, tuple(batch)))
                    continue
            # what the queues decide: exactly as for the same packets on the full path
            self._queue(actions, target_link, target_peer, list(map(packet_from_wire, batch)),
                        now)
            queued = True
        return taken, actions, queued

    def _decide(self, link: str, peer: Peer, src: int, dst: int
                ) -> _Decision | None:
        """Where :meth:`receive` sends a packet from ``src`` to ``dst`` that arrived on
        ``link`` from ``peer``, if all it does is forward it unchanged and learn nothing
        new (the source's route is already this one); else None."""
        source = ADDRESSES.get(src) or address_from_id(src)
        dest = ADDRESSES.get(dst) or address_from_id(dst)
        local = self._local
        if source in local or dest in local or source.is_broadcast or dest.is_broadcast:
            return None
        source_route = self._learned.get(source)
        if source_route is None or source_route.link != link or source_route.peer != peer:
            return None
        route = self._learned.get(dest) or self._static_hits.get(dest) or self.lookup(dest)
        if route is None or route.link == link or route.link not in self._links or \
                (link, route.link) not in self._relay:
            return None
        return source_route, route.link, route.peer

    # -- input from local components -----------------------------------------------------
    def send(self, packet: Packet, now: float, *, ack: bool = False,
             urgent: bool = False) -> list[Action]:
        """Send a message from a local component; numbers, fragments and routes it.

        ``packet.sequence`` is replaced by the source component's next number. With
        ``ack`` the destination is asked to acknowledge each packet, which is retried and
        finally reported as :class:`DeliveryFailed`. ``urgent`` takes the urgent path
        (see the module docstring). Raises
        :class:`~edge_vis.errors.LocalProtocolError` for a source that is not local or a
        broadcast larger than one packet.
        """
        source = packet.source
        if source not in self._local:
            raise LocalProtocolError(f"{source} is not a local component of this relay")
        if self._next_sweep is None:
            self._next_sweep = now + self.config.sweep_interval
        actions: list[Action] = []
        dest = packet.destination
        self.counters["sent"] += 1
        if dest.is_broadcast:
            if len(packet.payload) > self._smallest_mtu():
                raise LocalProtocolError(
                    f"broadcast of {len(packet.payload)} bytes exceeds one packet "
                    f"(MTU {self._smallest_mtu()}); broadcasts cannot be fragmented"
                )
            packet = replace(packet, sequence=self._next_seq(source), ack_nak=AckNak.NONE,
                             broadcast=packet.broadcast or Broadcast.GLOBAL)
            for other in self._local:
                if other != source and dest.matches(other):
                    actions.append(Deliver(packet, None, None))
                    break
            for name in self._links:
                self._queue(actions, name, None, [packet], now)
            return actions
        if dest in self._local:
            actions.append(Deliver(replace(packet, sequence=self._next_seq(source)), None, None))
            return actions
        route = self.lookup(dest)
        if route is None:  # JTS: broadcast it, ask for an ACK, learn from the answer
            ack = True
            packet = replace(packet, broadcast=Broadcast.GLOBAL)
            mtu = self._smallest_mtu()
        else:
            mtu = self._links[route.link].mtu if route.link in self._links else JTS_MAX_PAYLOAD
        packets = self._split(packet, mtu, ack)
        queue = self._urgent if urgent else self._queue
        if route is None:
            for name in self._links:
                queue(actions, name, None, packets, now)
        else:
            queue(actions, route.link, route.peer, packets, now)
        if ack:
            for p in packets:
                self._pending[(p.destination.id, p.sequence)] = _Pending(
                    p, route.link if route else None, route.peer if route else None,
                    now + self.config.ack_timeout,
                )
        return actions

    def set_busy(self, link: str, busy: bool, now: float) -> list[Action]:
        """A link reports it cannot take more (``True``) or is ready again (``False``)."""
        state = self._links[link]
        state.busy = busy
        actions: list[Action] = []
        if not busy:
            self._drain(state, now, actions)
        return actions

    # -- time ------------------------------------------------------------------------------
    def next_deadline(self) -> float | None:
        """When :meth:`on_timer` has work next, or ``None``."""
        best: float | None = None
        if self._pending:
            best = min(p.deadline for p in self._pending.values())
        sweep = self._next_sweep
        if sweep is not None and (best is None or sweep < best) and (
            self._learned or self._seen
            or (self._reassembler is not None and self._reassembler.bytes_held)
        ):
            best = sweep
        for state in self._links.values():
            if state.queued_bytes and not state.busy and state.bandwidth_bps:
                deficit = -state.tokens if state.tokens < 0 else 0.0
                base = state.refilled if state.refilled is not None else 0.0
                due = base + deficit * 8 / state.bandwidth_bps
                if best is None or due < best:
                    best = due
        return best

    def on_timer(self, now: float) -> list[Action]:
        """Retries, queue draining, expiry of peers, duplicates and partial messages."""
        actions: list[Action] = []
        for key, pending in list(self._pending.items()):
            if pending.deadline > now:
                continue
            if pending.tries >= self.config.ack_retries:
                del self._pending[key]
                self.counters["delivery failed"] += 1
                actions.append(DeliveryFailed(
                    pending.packet,
                    f"no ACK from {pending.packet.destination} after "
                    f"{pending.tries + 1} attempts",
                ))
                continue
            pending.tries += 1
            pending.deadline = now + self.config.ack_timeout
            self.counters["retries"] += 1
            route = self.lookup(pending.packet.destination)
            if route is not None:
                self._queue(actions, route.link, route.peer, [pending.packet], now)
            else:
                for name in self._links:
                    self._queue(actions, name, None, [pending.packet], now)
        for state in self._links.values():
            if state.queued_bytes:
                self._drain(state, now, actions)
        if self._next_sweep is not None and now >= self._next_sweep:
            self._seen_peak = max(self._seen_peak, len(self._seen))
            more = self._expire_duplicates(now, 4096)
            self._compact_duplicates()
            self._next_sweep = now + (0.01 if more else self.config.sweep_interval)
            limit = now - self.config.peer_timeout
            stale = [a for a, r in self._learned.items() if r.seen < limit]
            if stale:
                self._decisions.clear()
            for address in stale:
                del self._learned[address]
                log.info("forgot %s: silent for %.0f s", address, self.config.peer_timeout)
            self.counters["routes expired"] += len(stale)
            if self._reassembler is not None:
                self.counters["reassembly expired"] += self._reassembler.expire(now)
        return actions

    def stats(self) -> RouterStats:
        """A snapshot of counters, queues and the address book size."""
        return RouterStats(
            counters=dict(self.counters),
            links={
                name: LinkQueueStats(s.depth, s.queued_bytes, s.busy, s.sent, dict(s.drops))
                for name, s in self._links.items()
            },
            routes=len(self._learned) + len(self._static),
            pending_acks=len(self._pending),
        )

    # -- internals -------------------------------------------------------------------------
    def _next_seq(self, source: JausAddress) -> int:
        seq = self._seq.get(source, 1)
        self._seq[source] = (seq + 1) & 0xFFFF
        return seq

    def _smallest_mtu(self) -> int:
        return min((s.mtu for s in self._links.values()), default=JTS_MAX_PAYLOAD)

    def _split(self, packet: Packet, mtu: int, ack: bool) -> list[Packet]:
        flags = AckNak.REQUEST if ack else packet.ack_nak
        first = self._seq.get(packet.source, 1)
        packet = replace(packet, sequence=first, ack_nak=flags)
        if len(packet.payload) <= mtu:
            parts = [packet]
        elif fragment is None:  # pragma: no cover - see the import seam above
            raise LocalProtocolError(
                f"message of {len(packet.payload)} bytes exceeds the MTU {mtu} and "
                "large-message support is not installed"
            )
        else:
            try:
                parts = fragment(packet, mtu)
            except EncodeError as exc:
                raise LocalProtocolError(str(exc)) from exc
        self._seq[packet.source] = (first + len(parts)) & 0xFFFF
        return parts

    def _deliver_up(self, actions: list[Action], packet: Packet, link: str, peer: Peer,
                    now: float) -> None:
        if packet.data_flags != DataFlags.SINGLE:
            if self._reassembler is None:  # pragma: no cover - see the import seam
                self.counters["dropped: fragment (no reassembly)"] += 1
                return
            whole = self._reassembler.feed(packet, now)
            if whole is None:
                return
            packet = whole
        self.counters["delivered"] += 1
        actions.append(Deliver(packet, link, peer))

    def _acknowledged(self, packet: Packet) -> None:
        pending = self._pending.pop((packet.source.id, packet.sequence), None)
        if pending is None:
            self.counters["acks unexpected"] += 1
        elif packet.ack_nak == AckNak.NAK:
            self.counters["naks received"] += 1

    def _expire_duplicates(self, now: float, limit: int) -> bool:
        """Forget about ``limit`` expired entries (those of whole calls, oldest first);
        True when more are due.

        Entries are also checked against ``now`` when looked up, so forgetting late
        is harmless; it only bounds memory.
        """
        order = self._seen_order
        seen = self._seen
        get = seen.get
        while limit > 0 and order and order[0][0] <= now:
            expiry, keys = order.popleft()
            for key in keys:
                if get(key) == expiry:
                    del seen[key]
            limit -= len(keys)
        return bool(order) and order[0][0] <= now

    def _compact_duplicates(self) -> None:
        """Rebuild the duplicate table once a burst has passed.

        A dict never shrinks as entries are deleted: the 20,000 slots a burst needed would
        stay allocated (and the memory around them fragmented) for as long as the relay runs.
        (The deque of expiries needs no rebuild: it frees its blocks as they empty.)
        """
        seen = self._seen
        if self._seen_peak >= 4096 and len(seen) <= self._seen_peak // 8:
            self._seen = dict(seen)
            self._seen_peak = len(seen)
            self.compactions += 1

    def _queue(self, actions: list[Action], link: str, peer: Peer | None,
               packets: Sequence[Packet], now: float) -> None:
        state = self._links.get(link)
        if state is None:
            self.counters["dropped: unknown link"] += len(packets)
            return
        mtu = state.mtu
        sizes = [len(p.payload) for p in packets]
        if max(sizes) > mtu:
            fits = [p for p in packets if len(p.payload) <= mtu]
            dropped = len(packets) - len(fits)
            state.drops[QueueDrop("exceeds MTU")] += dropped
            self.counters["dropped: exceeds MTU"] += dropped
            packets = fits
            sizes = [len(p.payload) for p in packets]
        if not packets:
            return
        if not state.busy and not state.queued_bytes:
            rate = state.bandwidth_bps
            if rate is None:
                state.sent += len(packets)
                actions.append(_send_packets(link, peer, tuple(packets)))
                return
            if not state.latest_wins and self._within_budget(
                    state, [p.priority & 3 for p in packets], sizes, now, rate):
                state.sent += len(packets)
                actions.append(_send_packets(link, peer, tuple(packets)))
                return
        queues = state.queues
        for p in packets:
            cost = state.cost(p)
            if state.latest_wins and (p.priority & 3) <= LATEST_WINS_MAX_PRIORITY:
                self._supersede(state, peer, p)
            queues[p.priority & 3].append((peer, p, cost))
            state.queued_bytes += cost
        while state.queued_bytes > state.queue_limit:
            level = next(i for i in range(4) if queues[i])
            _, _victim, cost = queues[level].popleft()
            state.queued_bytes -= cost
            reason = QueueDrop("queue full", level)
            state.drops[reason] += 1
            self.counters[f"dropped: {reason}"] += 1
        self._drain(state, now, actions)

    @staticmethod
    def _within_budget(state: _LinkState, priorities: list[int], sizes: list[int],
                       now: float, rate: float) -> bool:
        """Charge ``packets`` to an idle paced link's budget if the queue would let them
        all leave now, in this order (one priority, the budget not spent before the
        last, no more than the queue holds): then they skip the queue, which would change
        nothing but the cost."""
        state.refill(now, rate)
        if priorities.count(priorities[0]) != len(priorities):
            return False
        overhead = 14 + state.overhead
        total = sum(sizes) + overhead * len(sizes)
        last = sizes[-1] + overhead
        if total > state.queue_limit or state.tokens - (total - last) < -1e-9:
            return False
        state.tokens -= total
        return True

    def _urgent(self, actions: list[Action], link: str, peer: Peer | None,
                packets: Sequence[Packet], now: float) -> None:
        """The urgent path: out at once, ahead of the queues; charged to the budget."""
        state = self._links.get(link)
        if state is None:
            self.counters["dropped: unknown link"] += len(packets)
            return
        if state.bandwidth_bps is not None:
            state.refill(now, state.bandwidth_bps)
            state.tokens -= sum(state.cost(p) for p in packets)
        state.sent += len(packets)
        self.counters["sent urgently"] += len(packets)
        actions.append(_send_packets(link, peer, tuple(packets), urgent=True))

    def _supersede(self, state: _LinkState, peer: Peer | None, packet: Packet) -> None:
        """Remove the queued older copy of what ``packet`` replaces (latest wins)."""
        key = latest_wins_key(packet)
        if key is None:
            return
        queue = state.queues[packet.priority & 3]
        for index, (queued_peer, queued, cost) in enumerate(queue):
            if queued_peer == peer and latest_wins_key(queued) == key:
                del queue[index]
                state.queued_bytes -= cost
                reason = QueueDrop("superseded", packet.priority & 3)
                state.drops[reason] += 1
                self.counters[f"dropped: {reason}"] += 1
                return

    def _drain(self, state: _LinkState, now: float, actions: list[Action]) -> None:
        if state.busy:
            return
        rate = state.bandwidth_bps
        if rate is not None:
            state.refill(now, rate)
        batch: list[Packet] = []
        batch_peer: Peer | None = None
        queues = state.queues
        while state.queued_bytes:
            if rate is not None and state.tokens < -1e-9:  # due at 0: see next_deadline
                break
            level = next(i for i in (3, 2, 1, 0) if queues[i])
            peer, packet, cost = queues[level].popleft()
            state.queued_bytes -= cost
            if rate is not None:
                state.tokens -= cost
            if batch and peer != batch_peer:
                actions.append(_send_packets(state.name, batch_peer, tuple(batch)))
                batch = []
            batch_peer = peer
            batch.append(packet)
            state.sent += 1
        if batch:
            actions.append(_send_packets(state.name, batch_peer, tuple(batch)))


def _ack(packet: Packet) -> Packet:
    """The ACK answering ``packet`` (JTS: empty payload, same sequence and priority)."""
    return Packet(
        destination=packet.source, source=packet.destination, payload=b"",
        sequence=packet.sequence, priority=packet.priority, ack_nak=AckNak.ACK,
    )


def _duplicate_key(packet: Packet) -> int:
    """The duplicate table's key of a packet not decoded from the wire (the key of one
    that was is the same, computed inline from ``packet.wire``): its data flags and its
    message bytes from the destination on (addresses, payload, sequence number)."""
    try:
        wire = encode_packet(packet)
    except EncodeError:
        return hash((packet.data_flags, packet.destination.id, packet.source.id,
                     packet.sequence, packet.payload))
    return hash(wire[4:]) + (wire[3] >> 6)


def _wildcards(address: JausAddress) -> int:
    return sum((address.subsystem == 0xFFFF, address.node == 0xFF, address.component == 0xFF))


def describe_route(address: JausAddress, route: Route) -> str:
    """``126.1.199 → udp 127.0.0.2:3794 (learned)`` for logs and status output."""
    kind = "static" if route.static else "learned"
    return f"{address} → {route.link} {format_peer(route.peer)} ({kind})"
