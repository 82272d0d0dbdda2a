"""JUDP: JAUS over UDP (AS5669A). I/O: a UDP socket read and written from the asyncio loop.

URL::

    udp://HOST:PORT?multicast=239.255.0.1&ttl=16&peers=10.0.0.5:3794,10.0.0.6&pack=1

* ``HOST:PORT`` is the local bind address (default ``0.0.0.0:3794``). Several JAUS
  nodes can share one host by binding ``127.0.0.2:3794``, ``127.0.0.3:3794``, ...
* ``multicast``: group that carries JAUS broadcasts; ``off`` disables it. Default
  ``239.255.0.1`` when bound to all interfaces (as the JAUS Toolset), else ``off``
  (a socket bound to one address cannot receive multicast).
* ``ttl`` (default 16) and ``loop`` (default 0) are the multicast TTL and loopback;
  ``interface`` (an IPv4 address of this host) picks the interface that joins the group
  and sends to it, for a relay with several networks (default: the kernel's choice).
* ``peers``: configured peers (``host[:port]``, comma separated) that always receive
  broadcasts; unicast goes to wherever the router says a component lives.
* ``broadcast``: where a broadcast goes, a comma list of ``multicast``, ``peers``,
  ``learned`` (every peer heard from recently) and literal IPv4 broadcast addresses
  (``10.0.0.255``). Default ``multicast,peers``, or ``peers,learned`` without multicast.
* ``pack=1`` packs several packets bound for the same peer into one datagram, up to
  ``1 + 14 + mtu`` bytes (the JAUS Toolset reads such datagrams; it never sends them).
* ``cycle`` (seconds, default 0 = off, at most 0.1): read the socket at most once per
  cycle while traffic flows, as the JAUS Toolset's node manager does with its 1 ms
  cycle. The first datagram after a quiet cycle is read at once; while datagrams keep
  coming the link stops waiting for the socket and drains it on a timer every
  ``cycle`` s, so one wake-up handles every datagram of the cycle instead of one each
  (CPU per message at moderate rates falls several times, see the README's Footprint
  figures). The price is receive latency: up to one cycle for a datagram that arrives
  while traffic flows, an emergency stop from the network included (it cannot be told
  apart before it is read). Sending is never delayed: ``send`` and ``send_urgent``
  write at once, whatever the cycle.
* ``thread=1``: read the socket on a thread of the link's own instead of the asyncio
  loop. The thread waits for the first datagram after a quiet cycle, then reads a
  cycle's datagrams at a time and hands them to the runtime right there (which routes,
  forwards and writes them on that thread), and sleeps the ``cycle`` with a plain
  blocking call, which costs the process a fraction of a turn of the event loop (see the
  README's Footprint figures). The relay's event loop and the link threads share one
  lock (:mod:`edge_vis.shell.sharedloop`), so the router, the engine and the links are
  used by one thread at a time: duplicate filtering, pacing, the urgent path and the
  counters behave as without the thread. Needs the relay's event loop (``edge-vis run``,
  or ``sharedloop.run``); the latency cost is the cycle's, as above.

The protocol logic (datagram layout) is :mod:`edge_vis.jaus.transport`; this module only
moves bytes. A datagram that does not decode is counted as malformed and dropped whole.
The socket is served with ``loop.add_reader`` and read until empty (up to ``READ_BATCH``
datagrams per wake-up) rather than through an asyncio datagram transport, which reads
one datagram per wake-up: at tens of thousands of messages per second the difference
is a factor of two.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import os
import select
import socket
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

from edge_vis.errors import DecodeError, LinkError
from edge_vis.jaus.transport import (
    JUDP_VERSION,
    MIN_DATA_SIZE,
    Packet,
    encode_packet,
    packet_from_wire,
    unpack_datagram,
)
from edge_vis.routing.link import Link, LinkOptions, LinkUrl, Peer, parse_peers
from edge_vis.schema import setting
from edge_vis.shell.sharedloop import on_loop_thread, shared_lock

log = logging.getLogger(__name__)

JUDP_PORT = 3794
JTS_MULTICAST = "239.255.0.1"
#: bytes held while the socket refuses more (EAGAIN) before further sends are dropped
MAX_WRITE_BUFFER = 1 << 20
#: datagrams read per readiness callback before yielding to the loop
READ_BATCH = 64
#: peers remembered for ``broadcast=learned``
MAX_LEARNED = 256
#: the largest UDP payload: the receive buffer every datagram is read into
MAX_DATAGRAM = 65535
#: ``multicast=`` values that disable multicast
MULTICAST_OFF = frozenset({"off", "0", "none", "no"})


def _group(text: str) -> str | None:
    if text.lower() in MULTICAST_OFF or _is_multicast(text):
        return None
    return f"{text!r} is not a multicast group (or off)"


def _interface(text: str) -> str | None:
    return None if _is_ip(text) else f"interface {text!r} is not an IPv4 address"


def _peers(text: str) -> str | None:
    try:
        parse_peers(text, JUDP_PORT)
    except ValueError as exc:
        return str(exc)
    return None


def _broadcast(text: str) -> str | None:
    for target in (t.strip() for t in text.split(",") if t.strip()):
        if target not in ("multicast", "peers", "learned") and not _is_ip(target):
            return (f"broadcast target {target!r} is not multicast/peers/learned or an IPv4 "
                    "address")
    return None


@dataclass(frozen=True, slots=True)
class UdpOptions(LinkOptions):
    """The query options of a ``udp://`` URL (see the module docstring)."""

    #: the group carrying broadcasts; "" = 239.255.0.1 when bound to all interfaces
    multicast: str = setting("", check=_group)
    ttl: int = setting(16, ge=0, le=255)
    loop: bool = False
    interface: str = setting("0.0.0.0", check=_interface)
    peers: str = setting("", check=_peers)
    #: "" = multicast,peers, or peers,learned without multicast
    broadcast: str = setting("", check=_broadcast)
    pack: bool = False
    #: seconds between reads while traffic flows; 0: read each datagram as it arrives
    cycle: float = setting(0.0, ge=0, le=0.1, unit="s")
    #: receive (and forward) on a thread of the link's own, sleeping ``cycle`` between reads
    thread: bool = False


class UdpLink(Link):
    """JAUS over UDP: unicast to peers, broadcasts to a multicast group and/or peers."""

    scheme: ClassVar[str] = "udp"
    options_type: ClassVar[type[LinkOptions]] = UdpOptions
    overhead: ClassVar[int] = 29  # IPv4 20 + UDP 8 + JUDP version byte 1
    config: UdpOptions

    def __init__(self, url: str | LinkUrl, *, name: str | None = None) -> None:
        super().__init__(url, name=name)
        opts = self.config
        self.bind_host = self.url.host or "0.0.0.0"
        self.bind_port = self.url.port if self.url.port is not None else JUDP_PORT
        group = opts.multicast
        if group.lower() in MULTICAST_OFF:
            group = ""
        elif not group and self.bind_host == "0.0.0.0":
            group = JTS_MULTICAST
        self.multicast = group
        self.ttl = opts.ttl
        self.multicast_loop = opts.loop
        self.interface = opts.interface
        self.peers: list[tuple[str, int]] = parse_peers(opts.peers, JUDP_PORT)
        default = "multicast,peers" if group else "peers,learned"
        self.broadcast_to = [b.strip() for b in (opts.broadcast or default).split(",")
                             if b.strip()]
        if "multicast" in self.broadcast_to and not group:
            self.broadcast_to.remove("multicast")
        self.pack = opts.pack
        self.cycle = opts.cycle
        #: the read timer while traffic flows (``cycle`` > 0); None: waiting on the socket
        self._tick: asyncio.TimerHandle | None = None
        self._sock: socket.socket | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        # datagrams the kernel would not take yet (EAGAIN): (data, target, messages)
        self._backlog: deque[tuple[bytes, Peer, int]] = deque()
        self._backlog_bytes = 0
        self._learned: OrderedDict[Peer, None] = OrderedDict()
        # one receive buffer, reused: ``recvfrom(65535)`` would allocate 64 KiB per datagram
        # and shrink it, and the shrunk datagrams that stay alive fragment the C heap (the
        # relay's resident memory then creeps up for hours)
        self._buffer = memoryview(bytearray(MAX_DATAGRAM))
        self.local_address: tuple[str, int] | None = None
        self.threaded = opts.thread
        self._thread: threading.Thread | None = None
        self._thread_done: asyncio.Future[None] | None = None
        self._stopping = False
        self._wake: tuple[int, int] | None = None  # pipe that ends the thread's wait

    # -- life cycle ------------------------------------------------------------------
    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
            if any(_is_ip(t) for t in self.broadcast_to):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.bind((self.bind_host, self.bind_port))
            if self.multicast:
                interface = socket.inet_aton(self.interface)
                membership = socket.inet_aton(self.multicast) + interface
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
                if self.interface != "0.0.0.0":
                    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, interface)
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, self.ttl)
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP,
                                int(self.multicast_loop))
        except OSError as exc:
            sock.close()
            raise LinkError(f"{self.name}: cannot bind {self.bind_host}:{self.bind_port}: "
                            f"{exc.strerror or exc}") from exc
        self.local_address = sock.getsockname()
        self._sock = sock
        self._loop = loop
        if not self.threaded:
            loop.add_reader(sock.fileno(), self._readable)
            return
        lock = shared_lock(loop)
        if lock is None:
            sock.close()
            self._sock = None
            raise LinkError(f"{self.name}: thread=1 needs the relay's event loop "
                            "(edge_vis.shell.sharedloop.run), not a plain asyncio loop")
        self._wake = os.pipe()
        self._thread_done = loop.create_future()
        self._thread = threading.Thread(target=self._serve, args=(lock,), daemon=True,
                                        name=f"edge-vis link {self.name}")
        self._thread.start()

    async def _close(self) -> None:
        sock = self._sock
        if self._thread is not None and self._wake is not None:
            self._stopping = True
            os.write(self._wake[1], b"x")
            if self._thread_done is not None:
                await self._thread_done  # the loop lets go of the lock while it waits
            self._thread.join(1.0)  # past its last use of the lock: it only returns
            self._thread = None
            for fd in self._wake:
                os.close(fd)
            self._wake = None
        elif sock is not None and self._loop is not None:
            if self._tick is not None:
                self._tick.cancel()
                self._tick = None
            else:
                self._loop.remove_reader(sock.fileno())
        if sock is not None and self._loop is not None:
            if self._backlog:
                self._loop.remove_writer(sock.fileno())
                self.counters.dropped("link closed", len(self._backlog))
                self._backlog.clear()
                self._backlog_bytes = 0
            sock.close()
        self._sock = None

    @property
    def queue_depth(self) -> int:
        return self._backlog_bytes

    # -- sending ---------------------------------------------------------------------
    def _send(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        if self._sock is None:
            self.counters.dropped("link down", len(packets))
            return
        self._transmit(self._datagrams(packets), peer)

    def _send_wires(self, wires: Sequence[bytes], peer: Peer | None) -> None:
        if self._sock is None:
            self.counters.dropped("link down", len(wires))
            return
        if self.pack and len(wires) > 1:
            self._send([packet_from_wire(w) for w in wires], peer)
            return
        version = bytes((JUDP_VERSION,))
        self._transmit([(version + w, 1) for w in wires], peer)

    def _transmit(self, datagrams: list[tuple[bytes, int]], peer: Peer | None) -> None:
        sock = self._sock
        assert sock is not None
        targets = [peer] if peer is not None else self._broadcast_targets()
        counters = self.counters
        for target in targets:
            for data, count in datagrams:
                if self._backlog:
                    self._hold(data, target, count)
                    continue
                try:
                    sock.sendto(data, target)  # type: ignore[arg-type]
                except BlockingIOError:
                    self._hold(data, target, count)
                    continue
                except (OSError, ValueError, TypeError) as exc:
                    counters.dropped("send error", count)
                    counters.last_error = f"send to {target}: {exc}"
                    continue
                counters.sent(target, len(data), count)

    def _send_urgent(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        """Straight to the socket, ahead of any backlog; if the kernel refuses it, first
        in the backlog, whatever its size."""
        sock = self._sock
        if sock is None:
            self.counters.dropped("link down", len(packets))
            return
        targets = [peer] if peer is not None else self._broadcast_targets()
        held: list[tuple[bytes, Peer, int]] = []
        for target in targets:
            for data, count in self._datagrams(packets):
                try:
                    sock.sendto(data, target)  # type: ignore[arg-type]
                except BlockingIOError:
                    held.append((data, target, count))
                except (OSError, ValueError, TypeError) as exc:
                    self.counters.dropped("send error", count)
                    self.counters.last_error = f"send to {target}: {exc}"
                else:
                    self.counters.sent(target, len(data), count)
        if held:
            if not self._backlog:
                self._arm_writer()
            for item in reversed(held):
                self._backlog.appendleft(item)
                self._backlog_bytes += len(item[0])

    def _hold(self, data: bytes, target: Peer, count: int) -> None:
        """Keep a datagram the kernel refused for now; bounded."""
        if self._backlog_bytes + len(data) > MAX_WRITE_BUFFER:
            self.counters.dropped("send buffer full", count)
            return
        if not self._backlog:
            self._arm_writer()
        self._backlog.append((data, target, count))
        self._backlog_bytes += len(data)

    def _arm_writer(self) -> None:
        """Wait until the socket takes more (the loop does; a link thread asks it to)."""
        loop, sock = self._loop, self._sock
        if loop is None or sock is None:
            return
        if on_loop_thread(loop):
            loop.add_writer(sock.fileno(), self._writable)
        else:
            loop.call_soon_threadsafe(self._arm_writer)

    def _writable(self) -> None:
        sock = self._sock
        backlog = self._backlog
        while backlog and sock is not None:
            data, target, count = backlog[0]
            try:
                sock.sendto(data, target)  # type: ignore[arg-type]
            except BlockingIOError:
                return
            except (OSError, ValueError, TypeError) as exc:
                self.counters.dropped("send error", count)
                self.counters.last_error = f"send to {target}: {exc}"
            else:
                self.counters.sent(target, len(data), count)
            backlog.popleft()
            self._backlog_bytes -= len(data)
        if sock is not None and self._loop is not None:
            self._loop.remove_writer(sock.fileno())

    def _datagrams(self, packets: Sequence[Packet]) -> list[tuple[bytes, int]]:
        version = bytes((JUDP_VERSION,))
        if not self.pack or len(packets) == 1:
            return [(version + encode_packet(p), 1) for p in packets]
        limit = self.mtu + 14
        out: list[tuple[bytes, int]] = []
        parts: list[bytes] = []
        size = 0
        for p in packets:
            encoded = encode_packet(p)
            if parts and size + len(encoded) > limit:
                out.append((version + b"".join(parts), len(parts)))
                parts, size = [], 0
            parts.append(encoded)
            size += len(encoded)
        if parts:
            out.append((version + b"".join(parts), len(parts)))
        return out

    def _broadcast_targets(self) -> list[Peer]:
        targets: list[Peer] = []
        for kind in self.broadcast_to:
            if kind == "multicast":
                targets.append((self.multicast, self.bind_port))
            elif kind == "peers":
                targets.extend(self.peers)
            elif kind == "learned":
                targets.extend(self._learned)
            else:
                targets.append((kind, self.bind_port))
        own = self.local_address
        unique: dict[Peer, None] = {}
        for t in targets:
            if t != own:
                unique[t] = None
        return list(unique)

    # -- receiving -------------------------------------------------------------------
    def _readable(self) -> None:
        """The socket has data: read it; with a ``cycle``, stop waiting on the socket and
        read it on the cycle's timer from now on."""
        if self._drain() and self.cycle and self._sock is not None and self._loop is not None:
            self._loop.remove_reader(self._sock.fileno())
            self._tick = self._loop.call_later(self.cycle, self._on_cycle)

    def _on_cycle(self) -> None:
        """One cycle: read what came meanwhile; after a quiet cycle wait on the socket
        again (an idle link costs nothing)."""
        self._tick = None
        sock, loop = self._sock, self._loop
        if sock is None or loop is None:
            return
        count = self._drain()
        if self._sock is None:  # closed by what the packets caused
            return
        if count >= READ_BATCH:  # more is waiting: go on at the loop's next turn
            self._tick = loop.call_later(0, self._on_cycle)
        elif count:
            self._tick = loop.call_later(self.cycle, self._on_cycle)
        else:
            loop.add_reader(sock.fileno(), self._readable)

    def _serve(self, lock: threading.Lock) -> None:
        """The link thread (``thread=1``): wait for a datagram, then read, route and send
        a cycle's worth at a time, holding the relay's lock only while doing so."""
        assert self._sock is not None and self._wake is not None and self._loop is not None
        poller = select.poll()
        poller.register(self._sock.fileno(), select.POLLIN)
        poller.register(self._wake[0], select.POLLIN)
        cycle = self.cycle
        try:
            while not self._stopping:
                poller.poll()  # until the first datagram after a quiet cycle (or close)
                while True:
                    with lock:
                        if self._stopping or self._sock is None:
                            return
                        try:
                            count = self._drain()
                        except Exception as exc:  # the thread must survive what it carries
                            log.exception("%s: error while forwarding", self.name)
                            self.counters.dropped("receive error")
                            self.counters.last_error = f"forwarding: {exc}"
                            count = 0
                    if not count:
                        break
                    if cycle and count < READ_BATCH:
                        time.sleep(cycle)
        finally:
            done = self._thread_done
            if done is not None:
                with contextlib.suppress(RuntimeError):  # the loop is already closed
                    self._loop.call_soon_threadsafe(_set_done, done)

    def _drain(self) -> int:
        """Read every datagram waiting (up to ``READ_BATCH``), deliver them; return how
        many were read.

        Consecutive datagrams from one peer are delivered in one call: the router then
        handles a burst in one pass and sends one batch per destination. With the
        runtime's pass-through path (and no tap), a run of datagrams of the usual form
        (version 2, at least one message) is offered to it as bytes first
        (:meth:`Link._received_wires`); the rest is decoded as below.
        """
        if self._pass_through is None or self._taps:
            return self._drain_packets()
        sock = self._sock
        buffer = self._buffer
        wires: list[bytes] = []
        peer: tuple[str, int] | None = None
        version = JUDP_VERSION
        count = 0
        if sock is None:
            return 0
        while count < READ_BATCH:
            try:
                size, addr = sock.recvfrom_into(buffer)
            except BlockingIOError:
                break
            except OSError as exc:  # e.g. ICMP errors surfacing on the socket: keep going
                count += 1
                self.counters.dropped("receive error")
                self.counters.last_error = str(exc)
                continue
            count += 1
            if addr != peer or size <= MIN_DATA_SIZE or buffer[0] != version:
                if wires:
                    self._offer(peer, wires)  # type: ignore[arg-type]
                    wires = []
                    if self._sock is None:  # closed by what the datagrams caused
                        return count
                peer = addr
                if size <= MIN_DATA_SIZE or buffer[0] != version:  # the full path says why
                    self._one(addr, buffer, size)
                    if self._sock is None:
                        return count
                    continue
            wires.append(bytes(buffer[1:size]))
        if wires:
            self._offer(peer, wires)  # type: ignore[arg-type]
        return count

    def _offer(self, peer: tuple[str, int], wires: list[bytes]) -> None:
        """One peer's run of datagrams of the usual form (without the version byte)."""
        self._learn(peer)
        self._received_wires(peer, wires, 1)

    def _one(self, addr: tuple[str, int], buffer: memoryview, size: int) -> None:
        """One datagram of another form: decoded (multi-message) or refused whole."""
        try:
            packets = unpack_datagram(buffer, size)
        except DecodeError as exc:
            self._malformed(addr, str(exc), buffer[:size].tobytes())
            return
        self._learn(addr)
        self._received(addr, packets, size)

    def _drain_packets(self) -> int:
        """:meth:`_drain` without the pass-through path: every datagram decoded."""
        sock = self._sock
        buffer = self._buffer
        batch: list[Packet] = []
        batch_peer: tuple[str, int] | None = None
        batch_bytes = 0
        count = 0
        while count < READ_BATCH:
            if sock is None or self._sock is None:
                break
            try:
                size, addr = sock.recvfrom_into(buffer)
            except BlockingIOError:
                break
            except OSError as exc:  # e.g. ICMP errors surfacing on the socket: keep going
                count += 1
                self.counters.dropped("receive error")
                self.counters.last_error = str(exc)
                continue
            count += 1
            try:  # each packet copies its own bytes out of the buffer
                packets = unpack_datagram(buffer, size)
            except DecodeError as exc:
                self._malformed(addr, str(exc), buffer[:size].tobytes())
                continue
            if addr != batch_peer:
                if batch:
                    self._received(batch_peer, batch, batch_bytes, tapped=True)
                    batch, batch_bytes = [], 0
                self._learn(addr)
            if self._taps:
                self._tap_in(addr, packets)
            batch_peer = addr
            batch += packets
            batch_bytes += size
        if batch:
            self._received(batch_peer, batch, batch_bytes, tapped=True)
        return count

    def _learn(self, addr: tuple[str, int]) -> None:
        learned = self._learned
        if addr not in learned:
            learned[addr] = None
            if len(learned) > MAX_LEARNED:
                learned.popitem(last=False)
                self.counters.dropped("learned peers forgotten: table full")


def _set_done(done: asyncio.Future[None]) -> None:
    if not done.done():
        done.set_result(None)


def _is_multicast(text: str) -> bool:
    try:
        return ipaddress.IPv4Address(text).is_multicast
    except ValueError:
        return False


def _is_ip(text: str) -> bool:
    try:
        ipaddress.IPv4Address(text)
    except ValueError:
        return False
    return True
