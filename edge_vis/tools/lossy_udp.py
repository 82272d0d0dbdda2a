"""A userspace UDP proxy that loses, delays and rate-limits datagrams: an emulated radio for
tests, benches and ``edge-vis demo`` (its UDT image fetches go through one).

Real sockets on loopback only. Clients send to ``proxy.address``; each client gets its own
upstream socket, so replies find their way back (UDT, JUDP and anything else on UDP work
through it unchanged). Impairments apply to both directions independently:

* ``loss``: probability (0..1) that a datagram is dropped, from a seeded RNG, so a run
  is repeatable;
* ``rate_bps``: the link's bit rate; datagrams are serialised one after another;
* ``queue_bytes``: bytes waiting for the link; beyond it datagrams are tail-dropped
  (a bounded router queue, not an infinite buffer);
* ``delay`` (+ uniform ``jitter``): one-way propagation delay in seconds;
* ``blackout(seconds)``: drop everything for a while (a radio fade).

With ``timeline`` (and a ``rate_bps``) each direction keeps a :class:`Timeline` of when its
link was busy and idle, which a bench reads to say where a transfer's time went (waiting
before the data, idle while it flowed, after it).

The proxy runs one thread and stops by itself after ``lifetime`` seconds, so a test that
forgets it cannot leave it running. Counters say what happened to each datagram.

Usage::

    with LossyProxy(("127.0.0.1", server_port), loss=0.02, delay=0.02, rate_bps=10e6) as p:
        client.connect(p.address)
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import multiprocessing
import random
import selectors
import socket
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

MAX_CLIENTS = 256
MAX_SCHEDULED = 20000


FULL_BYTES = 1000
"""Datagrams of at least this many bytes are the data; smaller ones are control (UDT's
ACK, ACK2 and NAK, the bulk protocol's manifests and answers)."""


@dataclass
class Timeline:
    """When one direction's link was busy, on the monotonic clock (which the benches' own
    ``time.perf_counter`` and ``time.monotonic`` read too)."""

    #: idle periods of the link between busy ones: (from, to)
    gaps: list[tuple[float, float]] = field(default_factory=list)
    #: when the first datagram of ``FULL_BYTES`` or more went onto the link, and when the
    #: last one had left it
    first_full: float | None = None
    last_full: float | None = None
    #: seconds the link spent sending datagrams of ``FULL_BYTES`` or more, and smaller ones
    busy_full: float = 0.0
    busy_small: float = 0.0
    #: how many smaller datagrams of each size the link sent (which kinds of control
    #: packet its control time went to)
    small_sizes: Counter[int] = field(default_factory=Counter)
    _free: float | None = None

    def carried(self, start: float, end: float, size: int) -> None:
        """The link sends a datagram of ``size`` bytes from ``start`` to ``end``."""
        if self._free is not None and start > self._free:
            self.gaps.append((self._free, start))
        self._free = end if self._free is None else max(self._free, end)
        if size >= FULL_BYTES:
            self.busy_full += end - start
            self.first_full = start if self.first_full is None else self.first_full
            self.last_full = end
        else:
            self.busy_small += end - start
            self.small_sizes[size] += 1

    def idle(self, since: float, until: float) -> float:
        """Seconds the link was idle between ``since`` and ``until`` (from its first
        datagram on)."""
        return sum(max(0.0, min(b, until) - max(a, since)) for a, b in self.gaps)


@dataclass
class _Direction:
    name: str
    link_free: float = 0.0
    timeline: Timeline | None = None


@dataclass(order=True)
class _Scheduled:
    when: float
    seq: int
    sock: socket.socket = field(compare=False)
    data: bytes = field(compare=False)
    addr: tuple[str, int] = field(compare=False)


class LossyProxy:
    """Impairing UDP relay between clients and one ``upstream`` address (see module doc)."""

    def __init__(
        self,
        upstream: tuple[str, int],
        *,
        listen: tuple[str, int] = ("127.0.0.1", 0),
        loss: float = 0.0,
        delay: float = 0.0,
        jitter: float = 0.0,
        rate_bps: float | None = None,
        queue_bytes: int = 64 * 1024,
        seed: int = 1,
        lifetime: float = 120.0,
        timeline: bool = False,
    ) -> None:
        if not 0.0 <= loss <= 1.0:
            raise ValueError("loss is a probability 0..1")
        self.upstream = upstream
        self.loss = loss
        self.delay = delay
        self.jitter = jitter
        self.rate_bps = rate_bps
        self.queue_bytes = queue_bytes
        self.lifetime = lifetime
        self.counters: Counter[str] = Counter()
        self._rng = random.Random(seed)
        self._front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._front.bind(listen)
        self._front.setblocking(False)
        self._clients: dict[tuple[str, int], socket.socket] = {}
        self._back_owner: dict[socket.socket, tuple[str, int]] = {}
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._front, selectors.EVENT_READ)
        self._heap: list[_Scheduled] = []
        self._seq = itertools.count()
        self._up = _Direction("up", timeline=Timeline() if timeline else None)
        self._down = _Direction("down", timeline=Timeline() if timeline else None)
        self._blackout_until = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lossy-proxy", daemon=True)

    @property
    def address(self) -> tuple[str, int]:
        return self._front.getsockname()  # type: ignore[no-any-return]

    def start(self) -> LossyProxy:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self._sel.close()
        for s in [self._front, *self._clients.values()]:
            s.close()

    def __enter__(self) -> LossyProxy:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def timelines(self) -> dict[str, Timeline]:
        """Each direction's :class:`Timeline` ("up": from the clients; "down": to them),
        when made with ``timeline``."""
        return {d.name: d.timeline for d in (self._up, self._down) if d.timeline is not None}

    def blackout(self, seconds: float) -> None:
        """Drop every datagram, both ways, for ``seconds`` from now."""
        self._blackout_until = time.monotonic() + seconds

    # ------------------------------------------------------------------ internals

    def _back_for(self, client: tuple[str, int]) -> socket.socket | None:
        back = self._clients.get(client)
        if back is None:
            if len(self._clients) >= MAX_CLIENTS:
                self.counters["dropped_clients"] += 1
                return None
            self.counters["clients"] += 1  # addresses seen sending: one per flow
            back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            back.bind((self._front.getsockname()[0], 0))
            back.setblocking(False)
            self._clients[client] = back
            self._back_owner[back] = client
            self._sel.register(back, selectors.EVENT_READ)
        return back

    def _admit(self, direction: _Direction, data: bytes, now: float) -> float | None:
        """When the datagram arrives at the far end, or None if it is dropped."""
        if now < self._blackout_until:
            self.counters[f"{direction.name}_blackout"] += 1
            return None
        if self.loss and self._rng.random() < self.loss:
            self.counters[f"{direction.name}_lost"] += 1
            return None
        start = max(now, direction.link_free)
        if self.rate_bps:
            backlog = (start - now) * self.rate_bps / 8.0
            if backlog + len(data) > self.queue_bytes:
                self.counters[f"{direction.name}_queue_drop"] += 1
                return None
            direction.link_free = start + len(data) * 8.0 / self.rate_bps
            if direction.timeline is not None:
                direction.timeline.carried(start, direction.link_free, len(data))
        else:
            direction.link_free = start
        if len(self._heap) >= MAX_SCHEDULED:
            self.counters[f"{direction.name}_queue_drop"] += 1
            return None
        extra = self._rng.uniform(0.0, self.jitter) if self.jitter else 0.0
        return direction.link_free + self.delay + extra

    def _run(self) -> None:
        deadline = time.monotonic() + self.lifetime
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= deadline:
                self.counters["lifetime_expired"] += 1
                return
            while self._heap and self._heap[0].when <= now:
                item = heapq.heappop(self._heap)
                try:
                    item.sock.sendto(item.data, item.addr)
                    self.counters["delivered"] += 1
                except OSError:
                    self.counters["send_errors"] += 1
            timeout = 0.05
            if self._heap:
                timeout = max(0.0, min(timeout, self._heap[0].when - now))
            for key, _ in self._sel.select(timeout):
                sock: socket.socket = key.fileobj  # type: ignore[assignment]
                for _ in range(64):
                    try:
                        data, addr = sock.recvfrom(65536)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        self.counters["recv_errors"] += 1
                        break
                    now = time.monotonic()
                    if sock is self._front:
                        back = self._back_for(addr)
                        if back is None:
                            continue
                        when = self._admit(self._up, data, now)
                        target_sock, target = back, self.upstream
                    else:
                        when = self._admit(self._down, data, now)
                        target_sock, target = self._front, self._back_owner[sock]
                    if when is not None:
                        heapq.heappush(
                            self._heap, _Scheduled(when, next(self._seq), target_sock, data, target)
                        )


def _serve_elsewhere(upstream: tuple[str, int], options: dict, pipe: Any) -> None:
    with LossyProxy(upstream, **options) as proxy:
        pipe.send(proxy.address)
        pipe.recv()
        pipe.send((dict(proxy.counters), proxy.timelines()))


@contextlib.contextmanager
def separate_process(upstream: tuple[str, int], **options: Any
                     ) -> Iterator[tuple[tuple[str, int], dict[str, Any]]]:
    """A :class:`LossyProxy` in a process of its own, for benches: the emulated radio
    then keeps its timing however busy the measured sender and receiver keep their
    interpreter. Yields its address and a dict filled with its counters on exit (with
    ``timeline=True``, also each direction's :class:`Timeline` as ``"up_timeline"`` and
    ``"down_timeline"``)."""
    ours, theirs = multiprocessing.Pipe()
    proc = multiprocessing.get_context("fork").Process(
        target=_serve_elsewhere, args=(upstream, options, theirs), daemon=True)
    proc.start()
    address = ours.recv()
    counters: dict[str, Any] = {}
    try:
        yield address, counters
    finally:
        ours.send("stop")
        counted, timelines = ours.recv()
        counters.update(counted)
        counters.update({f"{name}_timeline": line for name, line in timelines.items()})
        proc.join(5)
