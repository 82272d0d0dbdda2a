"""One file on parallel UDT lanes: threads that take segments off a shared queue. Does I/O.

The decisions are :mod:`links.udt.lane_plan`'s (how many segments, the shared budget's
pacing, which stalled segment to send again) and :mod:`links.udt.rate_probe`'s (the rate
all lanes of an adaptive transfer keep to together); this module runs them: each lane is
a :class:`~links.udt.transfer.BulkSender` on its own connection that sends segment after
segment; a coordinating loop looks at the lanes every ``TICK`` seconds (and at once when
a lane finishes a segment), feeds the bytes the receiver acknowledged and the lanes'
smoothed round trips and packets sent again to the rate probe, gives each lane with data
still to leave an equal share of the rate (``UDT_MAXBW``, the lane's whole pace where
:mod:`links.udt.udt_cc` is built; a lane waiting for an answer, for acknowledgements of
data already sent, or for a receipt leaves its share to the others, and one that UDT's
own loss reaction holds below its share, without that library, leaves what it cannot
send; once every segment is handed out, a share in proportion to what the lane has
still to deliver, so that the last lanes finish together), starts lanes one per tick
(a connection opens with a window of packets sent before its cap applies: 16, or 2 for
a push's lane paced from its start by :mod:`links.udt.udt_cc`) and, once every segment
is handed out, takes a stalled one over on an idle lane (the receiver hands the segment
to the newest connection and resumes it at the bytes it holds).

:class:`SharedRate` is the pacing itself, shared with the image server, whose answers to
a fetcher's lanes are paced the same way from the side that sends the data.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

from links.udt.lane_plan import Pace, straggler
from links.udt.protocol import MAX_LANES, Manifest, segment_bounds
from links.udt.rate_probe import RateProbe, filled_shares, final_shares, lane_share

log = logging.getLogger(__name__)

K = TypeVar("K")

TICK = 0.05
"""Seconds between the coordinator's looks at the lanes."""
HEADROOM = 2.0
"""Each lane's share above an even one when a budget's pacer (which hands bytes to all
lanes together) holds them to it: two limits at the same rate would add their gaps."""

#: make_sender(progress, pace, stop) -> a BulkSender for one lane
SenderFactory = Callable[[Callable[[int, int], None], Callable[[int], float] | None,
                          threading.Event], Any]


@dataclass
class SharedRate:
    """All lanes of one transfer paced together at the rate a :class:`RateProbe` finds:
    each lane with data on its way gets an equal share (a lane waiting for an answer or a
    receipt leaves its share to the others, one held back by UDT's loss reaction what it
    cannot send: :meth:`caps`); a lane that joins is paced from its first
    packet. With a budget, its :class:`Pace` holds the total and the shares get
    ``HEADROOM``. Not thread-safe: the caller holds its own lock."""

    budget_bps: int | None = None
    control: RateProbe = field(init=False)
    pace: Pace | None = field(init=False)
    #: connection -> (data packets sent, of them sent again) when last looked at
    _counted: dict[Any, tuple[int, int]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        self.control = RateProbe(budget_bps=self.budget_bps)
        self.pace = Pace(self.budget_bps) if self.budget_bps else None

    def joining(self, lanes: int) -> float:
        """The share of a lane starting now, ``lanes`` lanes running with it."""
        return lane_share(self.control.rate_bps, lanes)

    def _count(self, senders: Sequence[Any]) -> None:
        """Feed the probe the data packets the lanes sent, and sent again, since the last
        look (each connection's own totals: a lane's reconnection starts again at 0)."""
        sent = resent = 0
        for sender in senders:
            seen = sender.packets()
            if seen is None:
                continue
            conn, total, again = seen
            before = self._counted.get(conn, (0, 0))
            sent += max(0, total - before[0])
            resent += max(0, again - before[1])
            self._counted[conn] = (total, again)
        if sent:
            self.control.sent(sent, resent)

    def caps(self, now: float, acknowledged: int, lanes: Iterable[K], sending: Mapping[K, Any],
             left: Sequence[int] | None = None) -> dict[K, float]:
        """Feed the bytes acknowledged so far, and the smoothed round trips and the
        packets sent (and sent again) of the lanes with data on its way (``sending``: lane
        -> its :class:`~links.udt.transfer.BulkSender`); return each of ``lanes``' cap
        (bit/s).
        The lanes share the radio's queue: the least of their round trips says it. A lane
        not sending gets an even share of the rate; a sending one its share with what
        lanes held back by UDT's loss reaction leave
        (:func:`~links.udt.rate_probe.filled_shares`), or, once every segment is handed
        out, a share by the bytes it has still to deliver (``left``, in ``sending``'s
        order: :func:`~links.udt.rate_probe.final_shares`)."""
        senders = list(sending.values())
        trips = [trip for sender in senders if (trip := sender.round_trip())]
        if trips:
            self.control.smoothed(min(trips))
        self._count(senders)
        rate = self.control.sample(now, acknowledged)
        # with a budget, its pacer holds the total
        headroom = HEADROOM if self.pace is not None and rate >= self.pace.rate_bps else 1.0
        caps = dict.fromkeys(lanes, lane_share(rate, len(senders)) * headroom)
        shares = filled_shares(rate, [sender.ceiling() for sender in senders]) \
            if left is None else final_shares(rate, left)
        caps.update(zip(sending, (share * headroom for share in shares), strict=True))
        return caps


def _length(manifest: Manifest, index: int, count: int) -> int:
    start, end = segment_bounds(manifest.size, index, count)
    return end - start


@dataclass
class LaneRun:
    """Send the ``count`` segments of ``manifest`` on ``lanes`` lanes (0: adapt).

    ``paced`` False: the far end paces the data (a fetcher's lanes, answered by an image
    server): lanes still start one per tick, but nothing is capped here."""

    make_sender: SenderFactory
    lanes: int
    budget_bps: int | None
    stop: threading.Event
    progress: Callable[[int, int], None] | None = None
    paced: bool = True
    control: RateProbe | None = None
    results: list[Any] = field(default_factory=list)
    #: lanes started (connections opened, reconnections aside)
    started: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def send(self, path: Path, manifest: Manifest, count: int) -> tuple[Any, list[Any]]:
        """Run every segment; return (the first failed result or None, the idle senders,
        whose open connections can carry the whole-file manifest)."""
        adaptive = self.lanes == 0
        shared = SharedRate(self.budget_bps) if adaptive and self.paced else None
        changed = threading.Event()  # a lane finished a segment: look again at once
        if shared is not None:
            self.control = shared.control
            pace = shared.pace
        else:
            pace = Pace(self.budget_bps) if self.budget_bps and self.paced else None
        todo = deque(i for i in range(count) if _length(manifest, i, count))
        running: dict[int, threading.Event] = {}
        started: dict[int, tuple[int, float]] = {}  # lane -> (segment, when)
        inflight: dict[int, int] = {}
        durations: list[float] = []
        stored: set[int] = set()
        failures: list[Any] = []
        idle: list[Any] = []
        wanted = MAX_LANES if adaptive else self.lanes
        senders: dict[int, Any] = {}
        shares: dict[int, float] = {}  # lane -> its share of the rate (bit/s)
        taken_over: set[int] = set()

        def paced(n: int) -> float:
            assert pace is not None
            with self._lock:
                return pace.delay(n, time.monotonic())

        def answered(seconds: float) -> None:
            assert shared is not None
            with self._lock:
                shared.control.round_trip(seconds)

        def run(lane: int, stop: threading.Event, first: int | None) -> None:
            def report(value: int, _total: int) -> None:
                with self._lock:
                    inflight[lane] = value

            sender = self.make_sender(report, paced if pace is not None else None, stop)
            if shared is not None:
                sender.on_round_trip = answered
            with self._lock:
                senders[lane] = sender
                if lane in shares:
                    sender.cap(shares[lane])
            try:
                while not stop.is_set():
                    with self._lock:
                        if first is not None:
                            index, first = first, None
                        elif failures or lane >= wanted or not todo:
                            return
                        else:
                            index = todo.popleft()
                        inflight[lane] = 0
                        started[lane] = (index, time.monotonic())
                    result = sender.send_file(path, replace(manifest, segment=(index, count)))
                    changed.set()
                    with self._lock:
                        inflight.pop(lane, None)
                        began = started.pop(lane, (index, time.monotonic()))[1]
                        self.results.append(result)
                        if result.ok:
                            if index not in stored:
                                stored.add(index)
                                durations.append(time.monotonic() - began)
                        elif stop.is_set() and not self.stop.is_set():
                            return  # another lane took this segment over
                        else:
                            todo.appendleft(index)
                            failures.append(result)
            finally:
                changed.set()
                with self._lock:
                    running.pop(lane, None)
                    senders.pop(lane, None)
                    started.pop(lane, None)
                    inflight.pop(lane, None)
                    keep = not idle  # one open connection carries the verdict; the
                    if keep:         # others go now, or the receiver's connection limit
                        idle.append(sender)  # could keep a taken-over segment out
                if not keep:
                    sender.close()

        def start(lane: int, first: int | None = None) -> None:
            stop = threading.Event()
            running[lane] = stop
            self.started += 1
            if shared is not None:  # paced from its first packet
                shares[lane] = shared.joining(len(running))
            threading.Thread(target=run, args=(lane, stop, first), name=f"udt-lane-{lane}",
                             daemon=True).start()

        while True:
            now = time.monotonic()
            with self._lock:
                busy = []  # lanes with data on its way
                for lane, sender in senders.items():
                    seen = sender.acknowledged()
                    if seen is not None and lane in started and lane in inflight \
                            and seen[0] == (started[lane][0], count):
                        inflight[lane] = max(inflight[lane], seen[1])
                        if seen[2]:
                            busy.append(lane)
                acknowledged = sum(_length(manifest, i, count) for i in stored) + sum(
                    inflight.values())
                if not running and (failures or not todo):
                    break
                if self.stop.is_set():
                    for stop in running.values():
                        stop.set()
                if shared is not None:
                    left = None if todo else [  # the last segments: finish together
                        _length(manifest, started[lane][0], count) - inflight[lane]
                        for lane in busy]
                    caps = shared.caps(now, acknowledged, running,
                                       {lane: senders[lane] for lane in busy}, left)
                    for lane, cap in caps.items():
                        if shares.get(lane) != cap:
                            shares[lane] = cap
                            if lane in senders:
                                senders[lane].cap(cap)
                for lane in range(min(wanted, len(todo) + len(running))):
                    if lane not in running and todo and not failures:
                        start(lane)
                        if adaptive:
                            break  # one new lane per tick
                if not todo and not failures and len(running) < max(2, wanted):
                    slow = straggler({lane: t for lane, (i, t) in started.items()
                                      if i not in taken_over}, durations, now)
                    if slow is not None:
                        index = started[slow][0]
                        taken_over.add(index)
                        running[slow].set()
                        spare = next(n for n in range(len(running) + 1) if n not in running)
                        log.info("segment %d of %s stalled on lane %d: sending it again",
                                 index, manifest.name, slow)
                        start(spare, index)
            if self.progress:
                self.progress(acknowledged, manifest.size)
            changed.wait(TICK)
            changed.clear()
        if self.control is not None:
            log.info("%s: paced at %.2f Mbit/s at the end", manifest.name,
                     self.control.rate_bps / 1e6)
        if failures:
            return failures[0], idle
        return None, idle
