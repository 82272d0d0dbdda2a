"""The relay side of pull: fetch announced images from vehicles' image servers. Does I/O.

Decisions (what next, when again) are :mod:`links.udt.fetch_queue`'s; a file of several
segments comes in on parallel lanes run by :class:`~links.udt.lane_run.LaneRun` as for
``send-image`` (up to 16, started one per tick, a stalled segment asked for again on a
fresh lane), each lane a connection asking for segment after segment; the image server
paces the lanes together, since it sends the data. This module connects, sends FETCH
and lets the receiver's normal machinery store, resume and verify into the spool; the
last FETCH, for the whole file, asks for the verdict on a lane's open connection, unless
the segment that completed the file brought it already.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from links.udt.fetch_queue import FetchQueue, Verdict, Wanted
from links.udt.lane_plan import segments_for
from links.udt.lane_run import LaneRun
from links.udt.protocol import MAX_LANES, Manifest, ReceiverConnection
from links.udt.transfer import (
    CLOSE_WAIT,
    BulkReceiver,
    ConnectionLost,
    FetchOutcome,
    FetchRequest,
    LocalPort,
    _close,
    _connect,
    _delivered,
)

log = logging.getLogger(__name__)

GaveUpFn = Callable[[Wanted, str], None]


class Puller:
    """One thread fetching queued images, each on ``lanes`` lanes (0: adaptive, paced by
    the image server; 1: one connection).

    ``budget_bps`` is the link's bulk budget, less ``reserved()`` (the JAUS traffic the
    link carries now) at each fetch: the server is asked to keep to what is left.
    """

    def __init__(self, receiver: BulkReceiver, queue: FetchQueue, *,
                 budget_bps: int | None = None, reserved: Callable[[], float] | None = None,
                 lanes: int = 0, connect_timeout: float = 2.0,
                 on_gave_up: GaveUpFn | None = None,
                 progress_of: Callable[[str], int] | None = None) -> None:
        self.receiver = receiver
        self.queue = queue
        self.budget_bps = budget_bps
        self.reserved = reserved
        if not 0 <= lanes <= MAX_LANES:
            raise ValueError(f"lanes must be 0 (adapt) or 1..{MAX_LANES}")
        self.lanes = lanes
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
        rate = self.rate()
        whole = FetchRequest(wanted.name, wanted.sha256, wanted.size, None, rate)
        count = segments_for(wanted.size or 0) if self.lanes != 1 else 1
        if count <= 1:
            return self._one(wanted, whole)
        manifest = Manifest(wanted.image_id, wanted.vehicle_id, wanted.name, wanted.size or 0,
                            wanted.sha256, "", wanted.capture_time)

        local = LocalPort()  # every lane's connections from one port: one teardown

        def make_lane(_progress: object, _pace: object, stop: threading.Event) -> _Lane:
            return _Lane(self, wanted, rate, local)

        run = LaneRun(make_lane, self.lanes, None, self._stop, paced=False)
        failed, idle = run.send(Path(wanted.name), manifest, count)
        try:
            if failed is not None:
                return failed  # type: ignore[no-any-return]
            verified = [r for r in run.results if r.state == "verified"]
            if verified:  # the last segment completed the file and it verified
                closer = _Lane(self, wanted, rate)
                return verified[0]  # type: ignore[no-any-return]
            closer = idle.pop() if idle else _Lane(self, wanted, rate, local)
            return closer.fetch(whole)
        finally:
            for lane in idle:
                lane.close()
            if failed is None:
                closer.close()

    def _one(self, wanted: Wanted, request: FetchRequest) -> FetchOutcome:
        lane = _Lane(self, wanted, request.rate_bps)
        try:
            return lane.fetch(request)
        finally:
            lane.close()


class _Lane:
    """One connection to an image server, asking for segment after segment: a lane of a
    :class:`LaneRun` (its ``send_file`` fetches the segment its manifest names)."""

    def __init__(self, puller: Puller, wanted: Wanted, rate: int | None,
                 local: LocalPort | None = None) -> None:
        self.puller = puller
        self.local = local
        self.wanted = wanted
        self.rate = rate
        self.on_round_trip: Callable[[float], None] | None = None
        self._sock: Any = None
        self._conn: ReceiverConnection | None = None  # the connection's protocol state

    def send_file(self, _path: object, manifest: Manifest) -> FetchOutcome:
        w = self.wanted
        return self.fetch(FetchRequest(w.name, w.sha256, w.size, manifest.segment, self.rate))

    def fetch(self, request: FetchRequest) -> FetchOutcome:
        host, port = self.wanted.source
        if self._sock is None:
            try:
                self._sock = _connect(self.wanted.source, self.puller.connect_timeout, None,
                                      self.local)
            except ConnectionLost as exc:
                return FetchOutcome("lost", str(exc))
            receiver = self.puller.receiver
            self._conn = ReceiverConnection(idle_timeout=receiver.idle_timeout,
                                            keys=receiver.keys)
        outcome = self.puller.receiver.fetch(self._sock, f"{host}:{port}", request, self._conn)
        if outcome.state == "lost":
            self.close()
        return outcome

    def acknowledged(self) -> None:
        """Nothing to report: the image server paces the lanes."""
        return None

    def cap(self, _data_bps: float) -> None:
        """Nothing to cap here: the image server sends the data."""

    def close(self) -> None:
        sock, self._sock = self._sock, None
        if sock is None:
            return
        _delivered(sock, CLOSE_WAIT)  # the receipt reaches the vehicle (no linger here)
        _close(sock)
