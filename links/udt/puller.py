"""The relay side of pull: fetch announced images from vehicles' image servers. Does I/O.

Decisions (what next, when again, how many lanes) are :mod:`links.udt.fetch_queue` and
:mod:`links.udt.lane_plan`; this module connects, sends FETCH and lets the receiver's
normal machinery store, resume and verify into the spool.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from links.udt.fetch_queue import FetchQueue, Verdict, Wanted
from links.udt.lane_plan import LanePlan
from links.udt.transfer import (
    BulkReceiver,
    ConnectionLost,
    FetchOutcome,
    FetchRequest,
    _close,
    _connect,
    _pending,
)

log = logging.getLogger(__name__)

GaveUpFn = Callable[[Wanted, str], None]


class Puller:
    """One thread fetching queued images, lanes chosen by a :class:`LanePlan`.

    ``budget_bps`` is the link's bulk budget, less ``reserved()`` (the JAUS traffic the
    link carries now) at each fetch: the server is asked to keep to what is left.
    """

    def __init__(self, receiver: BulkReceiver, queue: FetchQueue, *,
                 budget_bps: int | None = None, reserved: Callable[[], float] | None = None,
                 lanes: LanePlan | None = None, connect_timeout: float = 2.0,
                 on_gave_up: GaveUpFn | None = None,
                 progress_of: Callable[[str], int] | None = None) -> None:
        self.receiver = receiver
        self.queue = queue
        self.budget_bps = budget_bps
        self.reserved = reserved
        self.lanes = lanes or LanePlan()
        self.connect_timeout = connect_timeout
        self.on_gave_up = on_gave_up
        self.progress_of = progress_of or (lambda _sha: 0)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.counters = {"fetched": 0, "attempts": 0, "gave_up": 0}

    def start(self) -> Puller:
        self._thread = threading.Thread(target=self._run, name="udt-pull", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def want(self, wanted: Wanted) -> bool:
        with self._lock:
            added = self.queue.add(wanted)
        self._wake.set()
        return added

    def arrived(self, sha256: str) -> None:
        """The image came another way (pushed): do not fetch it."""
        with self._lock:
            self.queue.discard(sha256)

    def rate(self) -> int | None:
        """Bit/s the next fetch may use: the budget less the JAUS traffic now."""
        if not self.budget_bps:
            return None
        used = self.reserved() if self.reserved is not None else 0.0
        return int(max(self.budget_bps * 0.1, self.budget_bps - used))

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            with self._lock:
                wanted = self.queue.take(now)
                due = self.queue.next_due(now)
            if wanted is None:
                self._wake.clear()
                self._wake.wait(1.0 if due is None else min(1.0, max(0.01, due - now)))
                continue
            before = self.progress_of(wanted.sha256)
            self.counters["attempts"] += 1
            outcome = self._fetch(wanted)
            progressed = self.progress_of(wanted.sha256) > before
            with self._lock:
                verdict = self.queue.finished(wanted, outcome.state, time.monotonic(),
                                              outcome.reason, progressed)
            self._report(wanted, outcome, verdict)

    def _report(self, wanted: Wanted, outcome: FetchOutcome, verdict: Verdict) -> None:
        if outcome.state == "verified":
            self.counters["fetched"] += 1
            log.info("fetched %s from %s", wanted.name, wanted.vehicle_id)
        elif verdict.action == "given_up":
            self.counters["gave_up"] += 1
            log.error("gave up fetching %s from %s: %s", wanted.name, wanted.vehicle_id,
                      verdict.reason)
            if self.on_gave_up is not None:
                self.on_gave_up(wanted, verdict.reason)
        else:
            log.info("fetch of %s from %s: %s (%s); again in %.1f s", wanted.name,
                     wanted.vehicle_id, outcome.state, outcome.reason,
                     max(0.0, verdict.at - time.monotonic()))

    def _fetch(self, wanted: Wanted) -> FetchOutcome:
        lanes = self.lanes.lanes_for(wanted.size or 0)
        rate = self.rate()
        if lanes <= 1:
            return self._one(wanted, FetchRequest(wanted.name, wanted.sha256, wanted.size,
                                                  None, rate))
        share = None if rate is None else max(1, rate // lanes)
        outcomes: list[FetchOutcome] = [FetchOutcome("lost", "lane did not finish")] * lanes
        started = time.monotonic()

        def lane(i: int) -> None:
            outcomes[i] = self._one(wanted, FetchRequest(
                wanted.name, wanted.sha256, wanted.size, (i, lanes), share))

        threads = [threading.Thread(target=lane, args=(i,), name=f"udt-pull-lane-{i}",
                                    daemon=True) for i in range(lanes)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.lanes.observe(lanes, wanted.size or 0, time.monotonic() - started)
        for o in outcomes:
            if o.state not in ("stored", "verified"):
                return o
        return self._one(wanted, FetchRequest(wanted.name, wanted.sha256, wanted.size,
                                              None, rate))

    def _one(self, wanted: Wanted, request: FetchRequest) -> FetchOutcome:
        host, port = wanted.source
        try:
            sock: Any = _connect(wanted.source, self.connect_timeout, None)
        except ConnectionLost as exc:
            return FetchOutcome("lost", str(exc))
        try:
            outcome = self.receiver.fetch(sock, f"{host}:{port}", request)
            deadline = time.monotonic() + 1.0
            while outcome.state != "lost" and _pending(sock) and time.monotonic() < deadline:
                time.sleep(0.01)  # let the receipt reach the vehicle before closing (no linger)
            return outcome
        finally:
            _close(sock)
