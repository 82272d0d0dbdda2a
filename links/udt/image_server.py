"""The vehicle side of pull: serve the image files of one directory to fetchers over UDT.

``edge-vis serve-images --dir D`` runs an :class:`ImageServer`. A relay that heard a
vehicle announce an image connects, sends FETCH with the file name (or one lane's segment
of it), and the server answers with that file's manifest and data exactly as
``send-image`` would push them; the fetcher's spool decides where to resume. A file is
hashed once per (size, modification time). Names are plain file names inside the
directory (no paths, no hidden or partial files), so nothing outside it can be read. The
files present at start are hashed ahead, in the background.

A fetcher pulls a large file as segments on parallel connections (lanes). The server
sends the data, so it paces them: the lanes one fetcher opened for one file are paced
together at one rate (:class:`~links.udt.lane_run.SharedRate`, the mechanism of
``send-image``'s adaptive lanes), from the round trips of its manifests to their answers
and the bytes the fetcher acknowledged; the rate a segment's FETCH carries is the budget
of all lanes of that fetch together. A connection serving a segment keeps to its share
alone (:mod:`links.udt.udt_cc`); one serving a whole file keeps UDT's own control.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from links.udt import udt_cc
from links.udt.image_service import manifest_for_file
from links.udt.lane_run import TICK, SharedRate
from links.udt.protocol import (
    FetchRequested,
    Manifest,
    ManifestError,
    PeerErrored,
    ProtocolErrorDetected,
    Reason,
    SenderConnection,
    State,
    check_file_name,
)
from links.udt.transfer import (
    POLL_MS,
    BulkSender,
    ConnectionLost,
    TransferResult,
    UdtService,
    _close,
    _flush,
    _set,
    listen,
    parse_address,
    udt4py,
)

log = logging.getLogger(__name__)

MANIFESTS_KEPT = 256
"""Files whose manifest (hash) is kept, and hashed ahead at start."""
#: (fetcher's host, file name, segment count): the lanes of one fetch
FetchKey = tuple[str, str, int]


@dataclass
class _PacedFetch:
    """The lanes (connections) one fetcher opened for one file, paced together. The
    server's lock guards it."""

    rate: SharedRate
    connections: int = 0
    #: lane sender -> (its segment under way or None, bytes of it acknowledged)
    lanes: dict[BulkSender, tuple[tuple[int, int] | None, int]] = field(default_factory=dict)
    done: int = 0  # bytes of the segments served
    #: lane sender -> the length of its segment under way
    lengths: dict[BulkSender, int] = field(default_factory=dict)
    #: the segments asked for so far: once all of them, the fetch is in its last segments
    asked: set[int] = field(default_factory=set)

    def serving(self, sender: BulkSender, segment: tuple[int, int], length: int) -> None:
        self.lanes[sender] = (segment, 0)
        self.lengths[sender] = length
        self.asked.add(segment[0])
        sender.cap(self.rate.joining(sum(s is not None for s, _ in self.lanes.values())))

    def served(self, sender: BulkSender, length: int) -> None:
        self.done += length
        self.lanes[sender] = (None, 0)

    def tick(self, now: float) -> None:
        sending = []  # the lanes with data on its way
        count = None
        for sender, (segment, seen) in list(self.lanes.items()):
            ack = sender.acknowledged()
            if segment is not None and ack is not None and ack[0] == segment:
                self.lanes[sender] = (segment, max(seen, ack[1]))
                count = segment[1]
                if ack[2]:
                    sending.append(sender)
        left = None
        if sending and count is not None and len(self.asked) >= count:
            # every segment asked for (the fetcher held none before): the last ones
            # finish together, as LaneRun's do
            left = [self.lengths.get(sender, 0) - self.lanes[sender][1] for sender in sending]
        caps = self.rate.caps(now, self.done + sum(a for _, a in self.lanes.values()),
                              self.lanes, {sender: sender for sender in sending}, left)
        for sender, cap in caps.items():
            sender.cap(cap)


class ImageServer(UdtService):
    """Serves ``directory``'s files as vehicle ``vehicle_id``'s images (see module doc).

    ``max_rate_bps`` caps each connection's send rate (``UDT_MAXBW``), like ``send-image``.
    """

    def __init__(self, directory: str | os.PathLike[str], listen: tuple[str, int] = (
            "127.0.0.1", 0), *, vehicle_id: str = "vehicle", max_rate_bps: int | None = None,
            idle_timeout: float = 60.0, max_connections: int = 32) -> None:
        self.directory = Path(directory)
        self.vehicle_id = vehicle_id
        self.max_rate_bps = max_rate_bps
        self.idle_timeout = idle_timeout
        self.max_connections = max_connections
        super().__init__(listen)
        self._lock = threading.Lock()
        self._hashing = threading.Lock()  # one file hashed at a time, each once
        self._changed = threading.Event()  # a lane served its segment: pace again now
        self._manifests: dict[str, tuple[tuple[int, int], Manifest]] = {}
        self._fetches: dict[FetchKey, _PacedFetch] = {}
        #: the rate probe's course in the last paced fetch that ended (time, bit/s, phase)
        self.rate_history: list[tuple[float, float, str]] = []
        self._open = 0
        self.counters = {"connections": 0, "served": 0, "not_found": 0, "interrupted": 0}

    _kind = "image server"
    _conn_thread = "udt-serve"

    def start(self) -> ImageServer:
        self._listener = listen(self._bind, linger=0, max_rate_bps=self.max_rate_bps or 0,
                                switchable=True)
        for target, name in ((self._accept_loop, "udt-serve-accept"),
                             (self._pace_loop, "udt-serve-pace"),
                             (self._warm, "udt-serve-warm")):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)
        log.info("serving images of %s on udt://%s:%d", self.directory, *self.address)
        return self

    def manifest(self, name: str) -> Manifest:
        """The manifest of file ``name``; ``ManifestError(NOT_FOUND/BAD_NAME)`` if not served."""
        check_file_name(name)
        path = self.directory / name
        if name.startswith(".") or not path.is_file():
            raise ManifestError(f"no image {name!r} here", Reason.NOT_FOUND)
        st = path.stat()
        stamp = (st.st_size, st.st_mtime_ns)
        with self._lock:
            known = self._manifests.get(name)
        if known is not None and known[0] == stamp:
            return known[1]
        with self._hashing:  # lanes asking together: the first hashes, the others wait
            with self._lock:
                known = self._manifests.get(name)
            if known is not None and known[0] == stamp:
                return known[1]
            m = manifest_for_file(path, vehicle_id=self.vehicle_id)
            with self._lock:
                self._manifests[name] = (stamp, m)
                while len(self._manifests) > MANIFESTS_KEPT:
                    del self._manifests[next(iter(self._manifests))]
        return m

    def _warm(self) -> None:
        """Hash the files served at start, newest first, so a fetch's first answer does
        not wait for the hash (the radio would stand idle meanwhile)."""
        try:
            entries = sorted((p for p in self.directory.iterdir() if p.is_file()),
                             key=lambda p: p.stat().st_mtime_ns, reverse=True)
        except OSError as exc:
            log.warning("cannot list %s: %s", self.directory, exc)
            return
        for path in entries[:MANIFESTS_KEPT]:
            if self._stop.is_set():
                return
            try:
                self.manifest(path.name)
            except (ManifestError, OSError) as exc:
                log.debug("not hashed ahead: %s: %s", path.name, exc)

    def _admit(self, sock: Any) -> bool:
        with self._lock:
            busy = self._open >= self.max_connections
            self._open += 0 if busy else 1
        return not busy

    def _pace_loop(self) -> None:
        """Every ``TICK``, and at once when a lane has served a segment (its share goes
        to the lanes still sending, as :class:`~links.udt.lane_run.LaneRun` does)."""
        while not self._stop.is_set():
            self._changed.wait(TICK)
            self._changed.clear()
            now = time.monotonic()
            with self._lock:
                for fetch in self._fetches.values():
                    fetch.tick(now)

    def _join(self, key: FetchKey, budget_bps: int | None) -> _PacedFetch:
        with self._lock:
            fetch = self._fetches.get(key)
            if fetch is None:
                fetch = self._fetches[key] = _PacedFetch(SharedRate(budget_bps))
            fetch.connections += 1
            return fetch

    def _leave(self, key: FetchKey, fetch: _PacedFetch, sender: BulkSender) -> None:
        with self._lock:
            fetch.lanes.pop(sender, None)
            fetch.lengths.pop(sender, None)
            fetch.connections -= 1
            if fetch.connections <= 0 and self._fetches.get(key) is fetch:
                del self._fetches[key]
                self.rate_history = list(fetch.rate.control.history)

    def _serve(self, sock: Any, peer: str) -> None:
        udt = udt4py()
        _set(sock, {"UDT_RCVTIMEO": POLL_MS, "UDT_SNDTIMEO": POLL_MS})
        # (the peer as accept gave it: udt4py's peer_address holds the GIL in libudt)
        sender = BulkSender(parse_address(peer), max_rate_bps=self.max_rate_bps,
                            stop=self._stop, idle_timeout=self.idle_timeout)
        conn = SenderConnection(idle_timeout=self.idle_timeout)
        buf = bytearray(64 * 1024)
        joined: dict[FetchKey, _PacedFetch] = {}  # the fetches this connection is a lane of
        try:
            while not self._stop.is_set():
                try:
                    n = sock.recv(buf)
                except udt.UDTException as exc:
                    if exc.error_code != udt.UDTException.ETIMEOUT:
                        return
                    continue
                events = conn.receive_data(bytes(buf[:n]), time.monotonic())
                while events:
                    event = events.pop(0)
                    if isinstance(event, FetchRequested):
                        self._answer(sock, conn, sender, event, peer, joined)
                        events += sender.unhandled()  # the next FETCH behind the receipt
                    elif isinstance(event, PeerErrored | ProtocolErrorDetected):
                        log.info("fetcher %s: %s", peer, event.reason)
                _flush(sock, conn)
                if conn.state is not State.IDLE:
                    return
        except ConnectionLost as exc:
            log.info("fetcher %s lost: %s", peer, exc)
        finally:
            for key, fetch in joined.items():
                self._leave(key, fetch, sender)
            with self._lock:
                self._open -= 1
            _close(sock)

    def _pacing(self, rate: SharedRate) -> tuple[Callable[[float], None],
                                                 Callable[[int], float] | None]:
        """A lane's hooks into its fetch's rate: round trips to the probe, and the
        budget's pacer (None without a budget), under the server's lock."""
        def answered(seconds: float) -> None:
            with self._lock:
                rate.control.round_trip(seconds)

        def paced(n: int) -> float:
            assert rate.pace is not None
            with self._lock:
                return rate.pace.delay(n, time.monotonic())
        return answered, None if rate.pace is None else paced

    def _answer(self, sock: Any, conn: SenderConnection, sender: BulkSender,
                event: FetchRequested, peer: str, joined: dict[FetchKey, _PacedFetch]) -> None:
        try:
            m = self.manifest(event.name)
        except ManifestError as exc:
            self.counters["not_found"] += 1
            log.info("fetcher %s asked for %s: %s", peer, event.name, exc.reason)
            conn.refuse_fetch(exc.code, exc.reason)
            return
        except OSError as exc:
            conn.refuse_fetch(Reason.STORAGE, f"cannot read {event.name}: {exc.strerror}")
            return
        rate = min(r for r in (self.max_rate_bps, event.rate_bps) if r) if (
            self.max_rate_bps or event.rate_bps) else None
        fetch = None
        if event.segment is not None:
            m = replace(m, segment=event.segment)
            key = (peer.rpartition(":")[0], event.name, event.segment[1])
            fetch = joined.get(key)
            if fetch is None:  # the fetch's budget, never above our own cap
                fetch = joined[key] = self._join(key, rate)
            with self._lock:
                fetch.serving(sender, event.segment, m.length)
                sender.on_round_trip, sender.pace = self._pacing(fetch.rate)
        elif rate:  # the fetcher's share of its link budget, never above our own cap
            sender.cap(rate)
        # a lane's share is its whole rate: UDT's own loss reaction would hold it below
        udt_cc.pace(sock, fetch is not None)
        result = None
        try:
            result = sender.serve(sock, conn, self.directory / event.name, m)
        finally:
            sender.on_round_trip = sender.pace = None
            if fetch is not None:
                with self._lock:
                    fetch.served(sender, m.length if isinstance(result, TransferResult)
                                 and result.ok else 0)
                self._changed.set()
        if isinstance(result, int) or result is None:
            self.counters["interrupted"] += 1
            raise ConnectionLost(f"{event.name} interrupted")
        if result.ok:
            self.counters["served"] += 1
        log.info("served %s to %s: %s", event.name, peer, result.reason)
