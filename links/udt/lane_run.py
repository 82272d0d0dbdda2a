"""One file on parallel UDT lanes: threads that take segments off a shared queue. Does I/O.

The decisions are :mod:`links.udt.lane_plan`'s (how many segments, how many lanes now,
the shared budget's pacing, which stalled segment to send again); this module runs them:
each lane is a :class:`~links.udt.transfer.BulkSender` on its own connection that sends
segment after segment; a coordinating loop samples progress every ``TICK`` seconds,
starts or retires lanes and, once every segment is handed out, takes a stalled one over
on an idle lane (the receiver hands the segment to the newest connection and resumes it
at the bytes it holds).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from links.udt.lane_plan import Pace, straggler
from links.udt.protocol import MAX_LANES, Manifest, segment_bounds
from links.udt.rate_probe import RateProbe, lane_share

log = logging.getLogger(__name__)

TICK = 0.05
import os
LANES_PACED = int(os.environ.get("LP", "16"))
"""Seconds between the coordinator's looks at the lanes."""

#: make_sender(progress, pace, stop) -> a BulkSender for one lane
SenderFactory = Callable[[Callable[[int, int], None], Callable[[int], float] | None,
                          threading.Event], Any]


def _length(manifest: Manifest, index: int, count: int) -> int:
    start, end = segment_bounds(manifest.size, index, count)
    return end - start


@dataclass
class LaneRun:
    """Send the ``count`` segments of ``manifest`` on ``lanes`` lanes (0: adapt)."""

    make_sender: SenderFactory
    lanes: int
    budget_bps: int | None
    stop: threading.Event
    progress: Callable[[int, int], None] | None = None
    control: RateProbe | None = None
    results: list[Any] = field(default_factory=list)
    #: lanes started (connections opened, reconnections aside)
    started: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def send(self, path: Path, manifest: Manifest, count: int) -> tuple[Any, list[Any]]:
        """Run every segment; return (the first failed result or None, the idle senders,
        whose open connections can carry the whole-file manifest)."""
        if self.lanes == 0:
            self.control = RateProbe(budget_bps=self.budget_bps, **{k[3:].lower(): float(v) for k, v in os.environ.items() if k.startswith("RP_")})
        pace = Pace(self.budget_bps) if self.budget_bps else None
        todo = deque(i for i in range(count) if _length(manifest, i, count))
        running: dict[int, threading.Event] = {}
        started: dict[int, tuple[int, float]] = {}  # lane -> (segment, when)
        inflight: dict[int, int] = {}
        durations: list[float] = []
        stored: set[int] = set()
        failures: list[Any] = []
        idle: list[Any] = []
        target = [LANES_PACED if self.control is not None else self.lanes]
        senders: dict[int, Any] = {}
        shares: dict[int, float] = {}
        sharing = [1.0]  # lanes sending at a time, smoothed
        taken_over: set[int] = set()

        def paced(n: int) -> float:
            assert pace is not None
            with self._lock:
                return pace.delay(n, time.monotonic())

        def answered(seconds: float) -> None:
            assert self.control is not None
            with self._lock:
                self.control.round_trip(seconds)

        def run(lane: int, stop: threading.Event, first: int | None) -> None:
            def report(value: int, _total: int) -> None:
                with self._lock:
                    inflight[lane] = value

            sender = self.make_sender(report, paced if pace is not None else None, stop)
            if self.control is not None:
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
                        elif failures or lane >= target[0] or not todo:
                            return
                        else:
                            index = todo.popleft()
                        inflight[lane] = 0
                        started[lane] = (index, time.monotonic())
                    result = sender.send_file(path, replace(manifest, segment=(index, count)))
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
            if self.control is not None:  # paced from its first packet
                shares[lane] = lane_share(self.control.rate_bps, len(running))
            threading.Thread(target=run, args=(lane, stop, first), name=f"udt-lane-{lane}",
                             daemon=True).start()

        while True:
            now = time.monotonic()
            with self._lock:
                busy = []
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
                if self.control is not None:
                    rate = self.control.sample(now, acknowledged)
                    sharing[0] = max(1, len(busy))
                    share = lane_share(rate, sharing[0])
                    for lane in running:
                        if shares.get(lane) != share:
                            shares[lane] = share
                            if lane in senders:
                                senders[lane].cap(share)
                for lane in range(min(target[0], len(todo) + len(running))):
                    if lane not in running and todo and not failures:
                        start(lane)
                        if self.control is not None:
                            # One new lane per tick: each opens with a burst of a
                            # window UDT sends before any pacing applies.
                            break
                if not todo and not failures and len(running) < max(2, target[0]):
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
            if log.isEnabledFor(logging.DEBUG) and acknowledged - getattr(self, "_prev", 0) > 150_000:
                log.debug("JUMP %d %s %s", acknowledged - self._prev, dict(inflight), sorted(stored)[-5:])
            self._prev = acknowledged
            if self.control is not None and log.isEnabledFor(logging.DEBUG):
                log.debug("t %.2f ack %d rate %.2f run %d send %d base %s deliv %.2f ph %s", now, acknowledged,
                          self.control.rate_bps / 1e6, len(running), len(busy),
                          self.control.queued, self.control.delivered_bps() / 1e6, self.control.phase)
            if self.progress:
                self.progress(acknowledged, manifest.size)
            time.sleep(TICK)
        if self.control is not None:
            log.info("%s: paced at %.2f Mbit/s at the end", manifest.name,
                     self.control.rate_bps / 1e6)
        if failures:
            return failures[0], idle
        return None, idle
