"""UDT I/O for bulk image transfer: udt4py sockets, one thread per connection. Does I/O.

The protocol decisions live in :mod:`links.udt.protocol` and storage in
:mod:`links.udt.spool`; this module only moves bytes between them and UDT sockets.
UDT calls block and release the GIL, so plain threads are the natural shell (UDT
sockets have no OS file descriptor an asyncio loop could watch).

Call order::

    BulkReceiver(spool, bind).start() -> (connections served on threads)* -> stop()
    BulkSender(address).send_file(path, manifest) -> TransferResult   (blocking)
    Forwarder(spool, target).start() -> (outbox drained, retried with backoff)* -> stop()
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from edge_vis.errors import LinkError
from links.udt import udt_calls, udt_cc, udt_stats
from links.udt.lane_plan import segments_for
from links.udt.lane_run import LaneRun
from links.udt.protocol import (
    DATA_CHUNK,
    MAX_LANES,
    Accepted,
    Backoff,
    DataComplete,
    DataReceived,
    FetchRefused,
    Manifest,
    ManifestReceived,
    ManifestRejected,
    PeerErrored,
    ProtocolErrorDetected,
    Reason,
    ReceiptReceived,
    ReceiverConnection,
    Refused,
    SenderConnection,
    State,
)
from links.udt.spool import Spool, SpoolRefusal

log = logging.getLogger(__name__)

EARLY_KEPT = 1024
"""Transfers a receiver remembers as verified with their last segment, to answer a
sender that asks again with the whole-file manifest without announcing twice."""
POLL_MS = 250
"""Receive timeout on every socket, so threads notice ``stop()`` within this time."""
PACED_CHUNK = 64 * 1024
"""DATA payload size while a shared budget paces the lanes (finer steps, smaller bursts)."""
CAP_POLL_MS = 40
"""Receive timeout of a paced lane's socket: how soon it takes a new share of the rate."""
CLOSE_WAIT = 1.0
"""Seconds a connection about to close waits for its last frames (an ERROR, a receipt)
to be acknowledged (the receiver's listener lingers as long)."""
SNDBUF_MIN = 256 * 1024
SNDBUF_MAX = 12 * 1024 * 1024


def udt4py() -> Any:
    """The udt4py module, or :class:`LinkError` saying how to install it."""
    try:
        import udt4py as mod
    except ImportError as exc:
        raise LinkError(
            "the UDT link needs udt4py (pip install 'edge-vis[udt]', with libudt-dev)"
        ) from exc
    return mod


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (IPv4) → tuple; raises ValueError with the reason."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"expected HOST:PORT, got {text!r}")
    return host, int(port)


class ConnectionLost(Exception):
    """The UDT connection broke or timed out; the transfer can resume on a new one."""


def _wire_rate(sock: Any, data_bps: float) -> int:
    """``UDT_MAXBW`` (bytes/s on the wire, IP and UDP headers included) for ``data_bps``
    bits of file data per second."""
    mss = _option(sock, "UDT_MSS") or 1500
    return max(1, int(data_bps / 8 * mss / (mss - 44)))


def _set(sock: Any, options: Mapping[str, int]) -> bool:
    """Set socket options (:mod:`links.udt.udt_calls`: a wait inside libudt does not stop
    the other threads); False when libudt refused one (a closed or broken socket)."""
    return all(udt_calls.set_option(sock, name, value) for name, value in options.items())


class LocalPort:
    """One local UDP port for the connections of one transfer's lanes.

    libudt gives a connection bound to a port of its own a multiplexer of its own (a UDP
    socket and two threads), and its garbage collector tears each one down a second or
    two after the connection closed, holding the library's global lock: 16 lanes' took
    about 100 ms, and the next file's connections (and every socket call) waited behind
    it. Connections sharing a port share one multiplexer (as those a listener accepts
    do), torn down once. Thread-safe: lanes connect side by side.
    """

    def __init__(self) -> None:
        self.port = 0  # 0 until the first lane's bind picked one
        self._lock = threading.Lock()

    def bind(self, make: Callable[[], Any]) -> Any:
        """A socket from ``make`` (options set: some cannot be once bound) bound to the
        shared port (the first: to one the system picks); bound to a new port when the
        old one is gone (every lane on it closed and torn down, and the port taken since)."""
        with self._lock:
            sock = make()
            if self.port:
                if udt_calls.bind_any(sock, self.port) is not None:
                    return sock
                sock.close()  # a refused bind leaves the socket in no known state
                sock = make()
            port = udt_calls.bind_any(sock, 0)
            if port is None:
                sock.close()
                raise ConnectionLost("libudt refused to bind a new socket")
            self.port = port
            return sock


def _connect(address: tuple[str, int], timeout: float, max_rate_bps: int | None,
             local: LocalPort | None = None, paced: bool = False) -> Any:
    """Open a UDT connection within ``timeout`` seconds (UDT's own wait is a fixed 3 s),
    from ``local``'s port when given; ``paced``: its rate is its ``UDT_MAXBW`` alone, set
    by the lanes' coordinator (:mod:`links.udt.udt_cc`; UDT's own control where that
    library is missing). The state and options go through
    :mod:`links.udt.udt_calls`: read through udt4py, a new lane's state waited with the
    GIL held while libudt tore down the lanes of the file before, and the whole relay
    stood still."""
    udt = udt4py()
    # A sender closes only after the receipt or on giving up a dead connection; either
    # way nothing queued is worth waiting for (UDT would linger up to 180 s by default).
    options = {"UDT_LINGER": 0, "UDT_RCVSYN": False}
    if max_rate_bps:
        options["UDT_MAXBW"] = max(1, int(max_rate_bps) // 8)
        # Keep about two seconds of data in flight, so progress means "delivered" and a
        # slow link does not hold megabytes that a reconnection would send again.
        options["UDT_SNDBUF"] = int(min(SNDBUF_MAX, max(SNDBUF_MIN, max_rate_bps / 8 * 2)))

    def make() -> Any:
        sock = udt.UDTSocket()
        if paced:
            udt_cc.install(sock, paced=True)
        if not _set(sock, options):
            sock.close()
            raise ConnectionLost(f"libudt refused the options of a new socket to "
                                 f"{address[0]}:{address[1]}")
        return sock

    sock = make() if local is None else local.bind(make)
    try:
        sock.connect(address)
    except udt.UDTException as exc:
        sock.close()
        raise ConnectionLost(f"connect to {address[0]}:{address[1]}: {exc}") from exc
    status = udt.UDTSocket.Status
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        st = udt_calls.state(sock)
        if st == status.CONNECTED:
            if _set(sock, {"UDT_RCVSYN": True, "UDT_RCVTIMEO": POLL_MS,
                           "UDT_SNDTIMEO": POLL_MS}):
                return sock
            break
        if st not in (status.CONNECTING, status.OPENED, status.INIT):
            break
        time.sleep(0.005)
    sock.close()
    raise ConnectionLost(f"no UDT answer from {address[0]}:{address[1]} within {timeout:g} s")


def _option(sock: Any, name: str) -> int:
    """A socket option's value (:mod:`links.udt.udt_calls`), 0 when it cannot be read:
    the lanes' coordinator reads a lane's socket while the lane's thread may be closing
    it, and udt4py raises TypeError, not UDTException, for a closed socket (that ended a
    transfer's thread)."""
    try:
        return udt_calls.get_option(sock, name) or 0
    except (udt4py().UDTException, TypeError):
        return 0


def _payload(sock: Any) -> int:
    """File bytes a full data packet carries (the MSS less IP, UDP and UDT headers)."""
    return max(0, _option(sock, "UDT_MSS") - 44)


def _pending(sock: Any, payload: int | None = None) -> int:
    """Bytes accepted by UDT but not yet acknowledged by the peer (approximately).

    ``UDT_SNDDATA`` counts packets; each carries the MSS less IP, UDP and UDT headers
    (``payload``, read from the socket when not given).
    """
    return _option(sock, "UDT_SNDDATA") * (_payload(sock) if payload is None else payload)


def _delivered(sock: Any, timeout: float) -> None:
    """Wait up to ``timeout`` seconds until the peer acknowledged everything sent, before
    closing: a fixed pause let a loaded machine close before the last frame left."""
    deadline = time.monotonic() + timeout
    while _pending(sock) and time.monotonic() < deadline:
        time.sleep(0.01)


def listen(bind: tuple[str, int], *, linger: int, max_rate_bps: int = 0,
           switchable: bool = False) -> Any:
    """A UDT socket listening on ``bind``; ``linger``, the rate cap (bit/s, 0 = none) and,
    with ``switchable``, a congestion control that can be told to pace a connection by its
    cap alone (:func:`links.udt.udt_cc.pace`) are inherited by the connections it accepts.
    :class:`LinkError` names the address."""
    udt = udt4py()
    sock = udt.UDTSocket()
    if switchable:
        udt_cc.install(sock)
    try:
        sock.UDT_REUSEADDR = True
        sock.UDT_LINGER = linger
        if max_rate_bps:
            sock.UDT_MAXBW = max(1, max_rate_bps // 8)
        sock.bind(bind)
        sock.listen(32)
    except udt.UDTException as exc:
        sock.close()
        raise LinkError(f"cannot listen on {bind[0]}:{bind[1]}: {exc}") from exc
    return sock


def _close(sock: Any) -> None:
    """Close, tolerating a socket another thread closed first (drop_connections)."""
    with contextlib.suppress(udt4py().UDTException):
        sock.close()


class _Watchdog:
    """Declares a connection dead when the peer acknowledges nothing for ``stall`` seconds.

    UDT itself gives up on a vanished peer only after its exponential EXP timer runs out
    (tens of seconds); a radio relay should reconnect much sooner than that.
    """

    def __init__(self, sock: Any, stall: float) -> None:
        self.sock = sock
        self.stall = stall
        self._pending = -1
        self._since = time.monotonic()

    def check(self) -> int:
        """Raise :class:`ConnectionLost` on a stall; return the bytes still unacknowledged."""
        pending = _pending(self.sock)
        now = time.monotonic()
        if pending == 0 or pending != self._pending:
            self._pending = pending
            self._since = now
        elif now - self._since > self.stall:
            raise ConnectionLost(f"no acknowledgement from the receiver for {self.stall:g} s")
        return pending


def _send_all(sock: Any, data: bytes, watchdog: _Watchdog | None = None) -> None:
    """Send everything; with a watchdog, the socket must have ``UDT_SNDTIMEO`` set."""
    udt = udt4py()
    view = memoryview(data)
    while view:
        try:
            sent = sock.send(view)
        except udt.UDTException as exc:
            if exc.error_code != udt.UDTException.ETIMEOUT:
                raise ConnectionLost(str(exc)) from exc
            sent = 0
        view = view[sent:]
        if watchdog is not None:
            watchdog.check()


def _flush(sock: Any, conn: ReceiverConnection | SenderConnection,
           watchdog: _Watchdog | None = None) -> None:
    """Send what ``conn`` queued, then its trailer in a send of its own: UDT starts a new
    packet for each send, and the trailer must not share the last one."""
    for out in (conn.data_to_send(), conn.trailer()):
        if out:
            _send_all(sock, out, watchdog)


# --------------------------------------------------------------------------- sender


@dataclass(frozen=True, slots=True)
class TransferResult:
    """How a transfer ended. ``ok`` only when the far end confirmed the SHA-256."""

    ok: bool
    reason: str = ""
    code: Reason | None = None
    attempts: int = 1
    resumed_from: tuple[int, ...] = ()
    #: the SHA-256 the receipt confirmed: a lane's segment receipt carries the whole
    #: file's when that segment completed the file and the receiver verified it
    sha256: str = ""


ProgressFn = Callable[[int, int], None]
"""``progress(bytes_confirmed_or_sent, total)``, called after each chunk."""


class BulkSender:
    """Sends files to one receiver, reconnecting with backoff and resuming where it left off.

    ``max_rate_bps`` caps the UDT send rate (bit/s, via ``UDT_MAXBW``) so bulk data leaves
    room for control traffic on a shared radio. ``give_up_after`` (seconds without any
    progress) bounds retries; None retries until ``stop`` is set. Refusals whose code is in
    ``retry_refusals`` (the receiver is busy or full) are retried like a dropped link.
    """

    def __init__(
        self,
        address: tuple[str, int],
        *,
        max_rate_bps: int | None = None,
        backoff: Backoff | None = None,
        connect_timeout: float = 2.0,
        idle_timeout: float = 20.0,
        give_up_after: float | None = 60.0,
        retry_refusals: frozenset[Reason] = frozenset({Reason.BUSY}),
        stop: threading.Event | None = None,
        progress: ProgressFn | None = None,
        stall_timeout: float = 10.0,
        lanes: int = 1,
        keys: Mapping[str, bytes] | None = None,
        pace: Callable[[int], float] | None = None,
        local_port: LocalPort | None = None,
        capped: bool = False,
    ) -> None:
        if not 0 <= lanes <= MAX_LANES:
            raise ValueError(f"lanes must be 0 (adapt) or 1..{MAX_LANES}")
        self.lanes = lanes
        #: seconds to wait before handing n more bytes to UDT (a budget shared by lanes)
        self.pace = pace
        #: the pacing rate's changes in the last adaptive transfer (time, bit/s, phase)
        self.rate_history: list[tuple[float, float, str]] = []
        #: told how long each manifest waited for its answer (the rate probe's signal)
        self.on_round_trip: Callable[[float], None] | None = None
        self.keys = keys  # vehicle id -> pre-shared key, to answer a receiver's challenge
        self.address = address
        #: the port this sender's connections leave from, shared with the other lanes
        #: of a transfer (None: one the system picks for each connection)
        self.local_port = local_port
        #: a lane of an adaptive transfer: its connections keep to the share :meth:`cap`
        #: sets, not slowed further by UDT's own loss reaction (:mod:`links.udt.udt_cc`)
        self.capped = capped
        self.max_rate_bps = max_rate_bps
        self.backoff = backoff or Backoff()
        self.connect_timeout = connect_timeout
        self.idle_timeout = idle_timeout
        self.give_up_after = give_up_after
        self.retry_refusals = retry_refusals
        self.stop = stop or threading.Event()
        self.progress = progress
        self.stall_timeout = stall_timeout
        self._idle: tuple[Any, SenderConnection | None] = (None, None)
        self._pending_events: list[Any] = []
        self._live: Any = None  # the socket of the attempt under way
        self._live_conn: SenderConnection | None = None
        self._cap: float | None = None
        self._cap_on: float | None = None  # the cap the live socket has
        self._round_trip: float | None = None
        self._ceiling: float | None = None
        self._packets: tuple[Any, int, int] | None = None

    def acknowledged(self) -> tuple[tuple[int, int] | None, int, bool] | None:
        """(segment, bytes of it the receiver acknowledged, whether data of it is still
        to leave) of the transfer under way now; None between transfers. Called from
        another thread: a lane waiting for an answer, for acknowledgements of what it
        sent or for a receipt leaves the radio to the others. Also reads the smoothed
        round trip :meth:`round_trip` returns."""
        sock, conn = self._live, self._live_conn
        if sock is None or conn is None:
            return None
        # (read once: the sender's thread moves on to the next segment meanwhile)
        manifest, state, offset = conn.manifest, conn.state, conn.offset
        if manifest is None:
            return None
        if state not in (State.SENDING, State.AWAIT_RECEIPT):
            return manifest.segment, 0, False
        payload = _payload(sock)
        pending = _pending(sock, payload)
        stats = udt_stats.read(sock)
        self._round_trip = None if stats is None else stats.round_trip
        self._ceiling = payload * 8 / stats.pace if stats and stats.pace and payload else None
        if stats is not None:
            self._packets = (sock, stats.sent, stats.resent)
        # data still to leave: what UDT holds less what it sent and awaits an ACK for
        unsent = pending if stats is None else pending - stats.in_flight * payload
        return manifest.segment, max(0, offset - pending), \
            state is State.SENDING or unsent > 0

    def round_trip(self) -> float | None:
        """UDT's smoothed round trip (s) of the connection under way, radio queue
        included, as :meth:`acknowledged` last read it; None between transfers or before
        it settled. Called from another thread."""
        return self._round_trip

    def packets(self) -> tuple[Any, int, int] | None:
        """(the connection, data packets it sent, of them sent again) as :meth:`acknowledged`
        last read them: what the lanes resend says an over-run radio (the rate probe's
        :meth:`~links.udt.rate_probe.RateProbe.sent`). Called from another thread."""
        return self._packets

    def ceiling(self) -> float | None:
        """The file bit/s UDT lets the connection under way send now, as
        :meth:`acknowledged` last read it: under the cap (:meth:`cap`) while UDT's own
        loss reaction holds the connection back; None when not known. Called from another
        thread."""
        return self._ceiling

    def cap(self, data_bps: float) -> None:
        """Hold this sender's connection to ``data_bps`` bits of file data per second
        (``UDT_MAXBW``): a share of the rate at which the lanes of a transfer are paced
        together. Called from another thread; the sender's own thread applies it within
        ``CAP_POLL_MS`` (UDT's setsockopt waits for the socket's send and receive locks,
        which a blocked ``recv`` holds)."""
        self._cap = data_bps

    def _apply_cap(self, sock: Any) -> None:
        cap = self._cap
        if cap and cap != self._cap_on:
            self._cap_on = cap
            with contextlib.suppress(udt4py().UDTException):
                _set(sock, {"UDT_MAXBW": _wire_rate(sock, cap), "UDT_RCVTIMEO": CAP_POLL_MS})

    @property
    def target(self) -> str:
        return f"{self.address[0]}:{self.address[1]}"

    def send_file(self, path: str | Path, manifest: Manifest) -> TransferResult:
        """Send ``path`` as described by ``manifest``; return once the receipt says so.

        With ``lanes`` other than 1 and a file of several segments (:func:`segments_for`),
        the segments go on parallel connections, each lane taking the next segment when
        it is done with one; ``lanes`` = 0 runs up to ``MAX_LANES`` lanes paced together
        at the rate a :class:`~links.udt.rate_probe.RateProbe` finds for the radio.
        Then the whole-file manifest asks for the verdict.
        """
        if self.lanes != 1 and manifest.segment is None:
            count = segments_for(manifest.size)
            if count > 1:
                return self._send_lanes(Path(path), manifest, count)
        return self._send_one(Path(path), manifest)

    def _send_lanes(self, path: Path, manifest: Manifest, count: int) -> TransferResult:
        local = LocalPort()  # every lane's connections from one port: one teardown

        def make_sender(progress: ProgressFn, pace: Callable[[int], float] | None,
                        stop: threading.Event) -> BulkSender:
            return BulkSender(
                self.address, max_rate_bps=self.max_rate_bps,
                backoff=Backoff(self.backoff.initial, self.backoff.factor, self.backoff.maximum,
                                self.backoff.jitter),
                connect_timeout=self.connect_timeout, idle_timeout=self.idle_timeout,
                give_up_after=self.give_up_after, retry_refusals=self.retry_refusals,
                stop=stop, progress=progress, stall_timeout=self.stall_timeout,
                keys=self.keys, pace=pace, local_port=local, capped=self.lanes == 0)

        run = LaneRun(make_sender, self.lanes, self.max_rate_bps, self.stop, self.progress)
        failed, idle = run.send(path, manifest, count)
        if run.control is not None:
            self.rate_history = list(run.control.history)
        # connections opened: one per lane and one per reconnection
        attempts = run.started + sum(r.attempts - 1 for r in run.results)
        offsets = tuple(o for r in run.results for o in r.resumed_from if o)
        try:
            if failed is not None:
                return TransferResult(False, failed.reason, failed.code, attempts, offsets)
            if any(r.ok and r.sha256 == manifest.sha256 for r in run.results):
                # the last segment's receipt carried the verdict on the whole file
                final, closer = TransferResult(True, "SHA-256 verified", attempts=0), self
            else:  # the whole-file manifest on a lane's open connection: no handshake
                closer = idle.pop() if idle else self
                final = closer._send_one(path, manifest)
        finally:
            for sender in idle:
                sender.close()
        if closer is not self:
            closer.close()
        if final.ok and self.progress:
            self.progress(manifest.size, manifest.size)
        return TransferResult(final.ok, final.reason, final.code, attempts + final.attempts,
                              offsets + final.resumed_from)

    def _send_one(self, path: Path, manifest: Manifest) -> TransferResult:
        self.backoff.reset()
        attempts = 0
        offsets: list[int] = []
        last_progress = time.monotonic()
        best = -1
        while True:
            attempts += 1
            try:
                outcome = self._attempt(Path(path), manifest, offsets)
            except ConnectionLost as exc:
                log.info("transfer %s to %s interrupted: %s", manifest.name, self.target, exc)
                outcome = None
            if isinstance(outcome, int):
                log.info("transfer %s to %s interrupted at byte %d", manifest.name, self.target,
                         outcome)
            if isinstance(outcome, TransferResult):
                return TransferResult(
                    outcome.ok, outcome.reason, outcome.code, attempts, tuple(offsets),
                    outcome.sha256)
            if offsets and offsets[-1] > best:
                best = offsets[-1]
                last_progress = time.monotonic()
                self.backoff.reset()
            if outcome is not None and outcome > best:  # bytes sent this attempt
                best = outcome
                last_progress = time.monotonic()
                self.backoff.reset()
            if self.give_up_after is not None and (
                time.monotonic() - last_progress > self.give_up_after
            ):
                return TransferResult(
                    False, f"gave up: no progress towards {self.target} for "
                    f"{self.give_up_after:g} s", Reason.TIMEOUT, attempts, tuple(offsets),
                )
            delay = self.backoff.next_delay()
            log.info("reconnecting to %s in %.2f s", self.target, delay)
            if self.stop.wait(delay):
                return TransferResult(
                    False, "stopped", Reason.SHUTDOWN, attempts, tuple(offsets)
                )

    def _open(self) -> tuple[Any, SenderConnection, bool]:
        """The idle connection kept from the previous file, or a new one; True if reused."""
        sock, conn = self._idle
        self._idle = (None, None)
        self._pending_events.clear()
        if sock is not None and conn is not None and conn.state is State.IDLE:
            if udt_calls.state(sock) == udt4py().UDTSocket.Status.CONNECTED:
                return sock, conn, True
            _close(sock)
        sock = _connect(self.address, self.connect_timeout, self.max_rate_bps,
                        self.local_port, self.capped)
        return sock, SenderConnection(idle_timeout=self.idle_timeout, keys=self.keys), False

    def close(self) -> None:
        """Close the connection kept open between files (idempotent)."""
        sock, _ = self._idle
        self._idle = (None, None)
        if sock is not None:
            _close(sock)

    def __enter__(self) -> BulkSender:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _attempt(
        self, path: Path, manifest: Manifest, offsets: list[int]
    ) -> TransferResult | int | None:
        """One connection. A result ends the transfer; an int is bytes reached before a drop.

        A connection that ends a transfer cleanly stays open for the next file: UDT's
        slow start then costs once per batch rather than once per file.
        """
        sock, conn, reused = self._open()
        keep = False
        self._live, self._live_conn = sock, conn
        self._cap_on = None
        self._apply_cap(sock)
        try:
            try:
                answer = self._announce(sock, conn, manifest)
            except ConnectionLost:
                if not reused:
                    raise
                # The kept connection died while idle (receiver restarted): a fresh one.
                _close(sock)
                sock = _connect(self.address, self.connect_timeout, self.max_rate_bps,
                                self.local_port, self.capped)
                conn = SenderConnection(idle_timeout=self.idle_timeout, keys=self.keys)
                self._live, self._live_conn = sock, conn
                self._cap_on = None
                self._apply_cap(sock)
                answer = self._announce(sock, conn, manifest)
            result, keep = self._exchange(sock, conn, path, manifest, answer, offsets)
            return result
        finally:
            self._live, self._live_conn = None, None
            if keep and conn.state is State.IDLE and not self.stop.is_set():
                self._idle = (sock, conn)
            else:
                _close(sock)

    def _announce(self, sock: Any, conn: SenderConnection, manifest: Manifest) -> Any:
        sent = time.monotonic()
        conn.send_manifest(manifest, sent)
        _flush(sock, conn)
        answer = self._next_event(sock, conn)
        if self.on_round_trip is not None and isinstance(answer, Accepted) \
                and not conn.resent:  # two round trips say no queue
            self.on_round_trip(time.monotonic() - sent)
        return answer

    def serve(self, sock: Any, conn: SenderConnection, path: Path, manifest: Manifest
              ) -> TransferResult | int | None:
        """Send ``path`` on a connection the peer opened (an image server answering a FETCH).

        One attempt: a result ends the transfer, an int is the bytes reached before a drop,
        None a refusal to retry. The connection stays open for the peer's next request.
        """
        self._live, self._live_conn = sock, conn
        try:
            answer = self._announce(sock, conn, manifest)
            result, _keep = self._exchange(sock, conn, path, manifest, answer, [])
        finally:
            self._live, self._live_conn = None, None
        return result

    def unhandled(self) -> list[Any]:
        """Events read behind the last answer :meth:`serve` waited for (a fetcher's next
        FETCH often arrives in one read with its receipt); the caller handles them."""
        events, self._pending_events = self._pending_events, []
        return events

    def _exchange(self, sock: Any, conn: SenderConnection, path: Path, manifest: Manifest,
                  answer: Any, offsets: list[int]) -> tuple[TransferResult | int | None, bool]:
        """The rest of one attempt after the manifest's answer; True: the connection is
        idle and reusable."""
        watchdog = _Watchdog(sock, self.stall_timeout)
        if isinstance(answer, Refused):
            if answer.code in self.retry_refusals:
                log.info("%s refused %s for now: %s", self.target, manifest.name, answer.reason)
                return None, True
            return TransferResult(False, answer.reason, answer.code), True
        if not isinstance(answer, Accepted):
            return self._ended(answer), False
        offsets.append(answer.offset)
        if answer.offset:
            log.info("resuming %s at byte %d of %d", manifest.name, answer.offset,
                     manifest.size)
        try:
            self._stream(sock, conn, path, answer.offset, watchdog)
        except ConnectionLost:
            # The receiver may have said why before closing.
            return self._reason_after_drop(sock, conn), False
        receipt = self._next_event(sock, conn, watchdog=watchdog)
        if isinstance(receipt, ReceiptReceived):
            if self.progress and receipt.ok:
                self.progress(manifest.length, manifest.length)
            return TransferResult(receipt.ok, receipt.reason or "SHA-256 verified",
                                  None if receipt.ok else Reason.HASH_MISMATCH,
                                  sha256=receipt.sha256 if receipt.ok else ""), True
        return self._ended(receipt), False

    def _stream(self, sock: Any, conn: SenderConnection, path: Path, offset: int,
                watchdog: _Watchdog) -> None:
        if conn.state is not State.SENDING or conn.manifest is None:
            return  # nothing to send: the receiver holds everything
        total = conn.manifest.length
        with open(path, "rb") as fh:
            fh.seek(conn.manifest.span()[0] + offset)
            while conn.state is State.SENDING:
                if self.stop.is_set():
                    raise ConnectionLost("stopped")
                chunk = fh.read(min(PACED_CHUNK if self.pace else DATA_CHUNK, conn.remaining))
                if not chunk:
                    raise LinkError(f"{path} is shorter than its manifest says ({total} bytes)")
                if self.pace is not None and self.stop.wait(self.pace(len(chunk))):
                    raise ConnectionLost("stopped")
                conn.send_data(chunk, time.monotonic())
                _flush(sock, conn, watchdog)
                self._apply_cap(sock)
                if self.progress:
                    self.progress(max(offset, conn.offset - _pending(sock)), total)

    def _reason_after_drop(self, sock: Any, conn: SenderConnection) -> TransferResult | int:
        reached = conn.offset
        try:
            event = self._next_event(sock, conn, limit=0.5)
        except ConnectionLost:
            return reached
        if isinstance(event, ReceiptReceived) and not event.ok:
            return TransferResult(False, event.reason, Reason.HASH_MISMATCH)
        if isinstance(event, PeerErrored) and event.code not in (Reason.SHUTDOWN, Reason.TIMEOUT):
            return TransferResult(False, event.reason, event.code)
        return reached

    def _ended(self, event: object) -> TransferResult | None:
        if isinstance(event, PeerErrored):
            if event.code in (Reason.SHUTDOWN, Reason.TIMEOUT, Reason.BUSY):
                log.info("%s closed the connection: %s", self.target, event.reason)
                return None
            return TransferResult(False, event.reason, event.code)
        if isinstance(event, ProtocolErrorDetected):
            if event.code is Reason.TIMEOUT:
                raise ConnectionLost(event.reason)
            if event.code is Reason.UNAUTHENTICATED:
                return TransferResult(False, event.reason, event.code)
            return TransferResult(False, f"receiver broke the protocol: {event.reason}", event.code)
        raise ConnectionLost(f"unexpected {event!r}")

    def _next_event(self, sock: Any, conn: SenderConnection, limit: float | None = None,
                    watchdog: _Watchdog | None = None) -> Any:
        if self._pending_events:
            return self._pending_events.pop(0)
        udt = udt4py()
        buf = bytearray(64 * 1024)
        started = time.monotonic()
        while True:
            if self.stop.is_set():
                raise ConnectionLost("stopped")
            self._apply_cap(sock)
            try:
                n = sock.recv(buf)
            except udt.UDTException as exc:
                if exc.error_code != udt.UDTException.ETIMEOUT:
                    raise ConnectionLost(str(exc)) from exc
                n = 0
            now = time.monotonic()
            if n:
                events = conn.receive_data(bytes(buf[:n]), now)
            else:
                pending = watchdog.check() if watchdog is not None else _pending(sock)
                if pending:  # our data is still draining: the link is slow, not dead
                    conn.touch(now)
                    # (while a manifest waits for its answer, the offset is the last
                    # transfer's and the pending bytes are the manifest's)
                    if self.progress and conn.manifest is not None \
                            and conn.state is State.AWAIT_RECEIPT:
                        self.progress(max(0, conn.offset - pending), conn.manifest.length)
                events = conn.handle_timer(now)
            _flush(sock, conn)
            if events:
                # ACCEPT and RECEIPT may arrive in one read (nothing left to send).
                self._pending_events.extend(events[1:])
                return events[0]
            if limit is not None and now - started > limit:
                raise ConnectionLost("no answer")


# --------------------------------------------------------------------------- receiver


@dataclass(frozen=True, slots=True)
class FetchRequest:
    """What to pull from an image server, and what the announcement said it must be."""

    name: str
    sha256: str
    size: int | None = None
    segment: tuple[int, int] | None = None
    rate_bps: int | None = None


@dataclass(frozen=True, slots=True)
class FetchOutcome:
    """How one fetch ended: ``verified``, ``stored`` (a lane segment), ``mismatch`` (refused:
    not what was announced, or data failing the hash), ``refused``, ``not_found``, ``lost``."""

    state: str
    reason: str = ""

    @property
    def ok(self) -> bool:
        """The file, or the lane's segment, is held."""
        return self.state in ("stored", "verified")


def _mismatch(expect: FetchRequest | None, m: Manifest) -> str:
    """Why the server's manifest is not the announced image ("" when it is)."""
    if expect is None:
        return ""
    if m.sha256 != expect.sha256:
        return (f"SHA-256 mismatch: announced {expect.sha256[:16]}..., the image server "
                f"offers {m.sha256[:16]}... for {m.name}")
    if expect.size is not None and m.size != expect.size:
        return f"size mismatch: announced {expect.size} bytes, the image server offers {m.size}"
    return ""

VerifiedFn = Callable[[Manifest, Path], None]
StatusFn = Callable[[dict[str, Any]], None]


class UdtService:
    """What the two UDT servers (the bulk receiver and the image server) share: a
    listener, an accept thread that hands each admitted connection to a thread of its own,
    and an idempotent stop that joins them all. A subclass opens the listener in
    ``start`` and implements ``_serve`` (and ``_admit`` to refuse when busy)."""

    #: what the service is called in errors, and its connection threads' name prefix
    _kind = "UDT service"
    _conn_thread = "udt-conn"

    def __init__(self, bind: tuple[str, int]) -> None:
        self._bind = bind
        self._listener: Any = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.counters: dict[str, int] = {"connections": 0}

    @property
    def address(self) -> tuple[str, int]:
        if self._listener is None:
            raise LinkError(f"{self._kind} not started")
        return tuple(self._listener.address)  # type: ignore[return-value]

    def start(self) -> Self:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self) -> None:
        """Stop accepting, end every connection's thread (idempotent)."""
        self._stop.set()
        if self._listener is not None:
            self._listener.close()
        for t in list(self._threads):
            t.join(timeout=5)
        self._threads.clear()

    def _admit(self, sock: Any) -> bool:
        """Whether to serve a new connection; a refused one is closed by the caller."""
        return True

    def _serve(self, sock: Any, peer: str) -> None:
        raise NotImplementedError

    def _accept_loop(self) -> None:
        udt = udt4py()
        while not self._stop.is_set():
            try:
                sock, peer = self._listener.accept()
            except udt.UDTException as exc:
                if not self._stop.is_set():
                    log.error("accept failed: %s", exc)
                    self._stop.wait(0.1)
                continue
            self.counters["connections"] += 1
            if not self._admit(sock):
                _close(sock)
                continue
            t = threading.Thread(target=self._serve, args=(sock, f"{peer[0]}:{peer[1]}"),
                                 name=f"{self._conn_thread}-{peer[1]}", daemon=True)
            self._threads = [x for x in self._threads if x.is_alive()]
            self._threads.append(t)
            t.start()


class BulkReceiver(UdtService):
    """Accepts UDT connections and stores transfers in a :class:`Spool`.

    ``on_verified(manifest, path)`` is called once per file whose SHA-256 matched, after the
    spool recorded it; ``on_status(dict)`` gets a ``TransferStatus``-shaped dict on each
    state change (started, resumed, verified, refused, failed).
    """

    def __init__(
        self,
        spool: Spool,
        bind: tuple[str, int] = ("127.0.0.1", 0),
        *,
        on_verified: VerifiedFn | None = None,
        on_status: StatusFn | None = None,
        idle_timeout: float = 30.0,
        max_connections: int = 64,
        keys: Mapping[str, bytes] | None = None,
    ) -> None:
        self.spool = spool
        #: vehicle id -> pre-shared key; when set, only those vehicles may deliver
        self.keys = keys
        super().__init__(bind)
        self.on_verified = on_verified
        self.on_status = on_status
        self.idle_timeout = idle_timeout
        self.max_connections = max_connections
        self._conns: dict[int, Any] = {}
        self._owners: dict[tuple[str, int | None], Any] = {}  # claim -> socket holding it
        self._lock = threading.Lock()
        self._local = threading.local()
        self._cut: set[int] = set()  # ids of sockets their serving thread must close
        #: transfers verified with their last segment (the most recent ``EARLY_KEPT``)
        self._verified_early: dict[str, None] = {}
        self._status_lock = threading.Lock()
        self.counters = {"connections": 0, "protocol_errors": 0, "refused": 0, "verified": 0,
                         "unauthenticated": 0}

    _kind = "receiver"

    def start(self) -> BulkReceiver:
        # linger, inherited by connections: time to deliver a last ERROR
        self._listener = listen(self._bind, linger=1)
        t = threading.Thread(target=self._accept_loop, name="udt-accept", daemon=True)
        t.start()
        self._threads.append(t)
        log.info("receiving images on udt://%s:%d", *self.address)
        return self

    def drop_connections(self) -> int:
        """Cut every open connection (partial data is kept); return how many.

        Each connection's own thread closes its socket within one receive timeout: closing
        a UDT socket under a thread blocked in ``recv`` breaks udt4py's call.
        """
        with self._lock:
            conns = list(self._conns)
            self._cut.update(conns)
        return len(conns)

    def _admit(self, sock: Any) -> bool:
        with self._lock:
            busy = len(self._conns) >= self.max_connections
        if busy:
            conn = ReceiverConnection()
            conn.close_with_error(Reason.BUSY, "too many connections; retry later")
            with contextlib.suppress(ConnectionLost):
                _flush(sock, conn)
        return not busy

    def _status(self, manifest: Manifest, state: str, offset: int, detail: str = "") -> None:
        if self.on_status is None:
            return
        try:
            self.on_status({
                "transfer_id": manifest.transfer_id,
                "vehicle_id": manifest.vehicle_id,
                "name": manifest.name,
                "state": state,
                "bytes_received": offset,
                "size": manifest.size,
                "detail": detail,
                "sha256": manifest.sha256,
                "manifest": manifest,
            })
        except Exception:  # a status consumer must not break a transfer
            log.exception("status callback failed")

    def _serve(self, sock: Any, peer: str) -> None:
        try:
            self._run_connection(sock, peer, None)
        finally:
            _close(sock)

    def fetch(self, sock: Any, peer: str, request: FetchRequest,
              conn: ReceiverConnection | None = None) -> FetchOutcome:
        """Pull one file (or lane segment) on ``sock``, a connection to an image server.

        The server's manifest must match the announced SHA-256 and size, or it is refused
        with that reason. The socket stays open for the next request unless the outcome
        says the connection was lost; the caller closes it.
        """
        return self._run_connection(sock, peer, request, conn)

    def _run_connection(self, sock: Any, peer: str, request: FetchRequest | None,
                        conn: ReceiverConnection | None = None) -> FetchOutcome:
        udt = udt4py()
        with self._lock:
            self._conns[id(sock)] = sock
        self._local.sock = sock
        self._local.outcome = None
        self._local.expect = request
        _set(sock, {"UDT_RCVTIMEO": POLL_MS})
        if conn is None:
            conn = ReceiverConnection(idle_timeout=self.idle_timeout, keys=self.keys)
        buf = bytearray(DATA_CHUNK)
        current: Manifest | None = None
        lost = FetchOutcome("lost", "connection closed")
        try:
            if request is not None:
                conn.request(request.name, request.segment, request.rate_bps)
                _flush(sock, conn)
            while not self._stop.is_set():
                if id(sock) in self._cut:
                    return FetchOutcome("lost", "connection cut")
                try:
                    n = sock.recv(buf)
                except udt.UDTException as exc:
                    if exc.error_code != udt.UDTException.ETIMEOUT:
                        idle = conn.state is State.AWAIT_MANIFEST
                        log.log(logging.DEBUG if idle else logging.INFO,
                                "connection from %s ended: %s", peer, exc)
                        return FetchOutcome("lost", str(exc))
                    n = 0
                now = time.monotonic()
                events = conn.receive_data(bytes(buf[:n]), now) if n else conn.handle_timer(now)
                for event in events:
                    current = self._handle(conn, event, peer, current)
                _flush(sock, conn)
                if conn.state is State.CLOSED:
                    _delivered(sock, CLOSE_WAIT)  # the ERROR frame reaches the peer
                    return self._local.outcome or FetchOutcome("lost", "protocol error")
                if request is not None and self._local.outcome is not None:
                    return self._local.outcome  # type: ignore[no-any-return]
            conn.close_with_error(Reason.SHUTDOWN, "receiver shutting down")
            _flush(sock, conn)
            return FetchOutcome("lost", "stopped")
        except ConnectionLost as exc:
            log.info("connection from %s lost: %s", peer, exc)
            return lost
        finally:
            if current is not None:
                self._release(current, sock)
                entry = self.spool.entry(current.transfer_id)
                if entry is not None and entry.state.value == "partial":
                    self._status(current, "interrupted", entry.held)
            with self._lock:
                self._conns.pop(id(sock), None)
                self._cut.discard(id(sock))

    def _outcome(self, state: str, reason: str = "") -> None:
        self._local.outcome = FetchOutcome(state, reason)

    @staticmethod
    def _claim_key(m: Manifest) -> tuple[str, int | None]:
        return m.transfer_id, None if m.segment is None else m.segment[0]

    def _release(self, m: Manifest, sock: Any) -> None:
        with self._lock:
            if self._owners.get(self._claim_key(m)) is sock:
                del self._owners[self._claim_key(m)]
        self.spool.release(m)

    def _take_over(self, m: Manifest, peer: str) -> None:
        """A sender reconnected while its old connection looks alive here: the old one is
        dead (the sender would not reconnect otherwise), so close it and take its place."""
        key = self._claim_key(m)
        with self._lock:
            old = self._owners.get(key)
        if old is None or old is self._local.sock:
            return
        log.info("transfer %s: new connection from %s replaces a stale one", m.transfer_id, peer)
        with self._lock:
            self._cut.add(id(old))
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            with self._lock:
                if key not in self._owners:
                    return
            time.sleep(0.01)

    def _held(self, m: Manifest) -> int:
        entry = self.spool.entry(m.transfer_id)
        return m.size if entry is None else min(m.size, entry.held)

    def _completes(self, m: Manifest) -> bool:
        """Whether this segment was the last one the file lacked (claimed here by one
        connection only: two lanes may finish together)."""
        if not self.spool.all_held(m.transfer_id):
            return False
        entry = self.spool.entry(m.transfer_id)
        with self._lock:
            if entry is None or entry.state.value != "partial" \
                    or m.transfer_id in self._verified_early:
                return False
            self._verified_early[m.transfer_id] = None
            while len(self._verified_early) > EARLY_KEPT:
                del self._verified_early[next(iter(self._verified_early))]
        return True

    def _verdict(self, conn: ReceiverConnection, m: Manifest, peer: str) -> None:
        """Verify the whole file and answer with the receipt: on the whole-file manifest,
        or on the segment that completed a pushed file (its receipt then carries the
        file's SHA-256, and the sender need not ask)."""
        sock, whole = self._local.sock, m.whole()
        try:
            path = self.spool.complete(m)
        except SpoolRefusal as exc:
            log.warning("%s from %s failed verification: %s", m.name, peer, exc.reason)
            with self._lock:
                self._verified_early.pop(m.transfer_id, None)
            self._release(m, sock)
            conn.send_receipt(False, "", exc.reason)
            self._status(whole, "failed", m.size, exc.reason)
            self._outcome("mismatch", exc.reason)
            return None
        self._release(m, sock)
        self.counters["verified"] += 1  # before the sender can hear of it
        conn.send_receipt(True, m.sha256, "" if m.segment is None else
                          f"segment {m.segment[0] + 1}/{m.segment[1]} stored; SHA-256 verified")
        # The sender waits for this receipt; thumbnails and announcements need not
        # hold it up (a lost connection is noticed by the caller's next send).
        with contextlib.suppress(ConnectionLost):
            _flush(sock, conn)
        log.info("verified %s from %s (sha256 %s...)", m.name, m.vehicle_id, m.sha256[:12])
        with self._status_lock:
            self._status(whole, "verified", m.size)
        self._outcome("verified")
        if self.on_verified is not None:
            try:
                self.on_verified(whole, path)
            except Exception:  # announcing must not lose the file
                log.exception("announcing %s failed", m.name)
        return None

    def _handle(self, conn: ReceiverConnection, event: Any, peer: str,
                current: Manifest | None) -> Manifest | None:
        if isinstance(event, ManifestReceived):
            m = event.manifest
            wrong = _mismatch(self._local.expect, m)
            if wrong:
                self.counters["refused"] += 1
                log.warning("refused %s from %s: %s", m.name, peer, wrong)
                conn.refuse(Reason.HASH_MISMATCH, wrong)
                self._status(m, "refused", 0, wrong)
                self._outcome("mismatch", wrong)
                return None
            self._take_over(m, peer)
            try:
                offset = self.spool.begin(m)
            except SpoolRefusal as exc:
                self.counters["refused"] += 1
                log.warning("refused %s from %s (%s): %s", m.name, peer, exc.code.name, exc.reason)
                conn.refuse(exc.code, exc.reason)
                self._status(m, "refused", 0, exc.reason)
                self._outcome("refused", exc.reason)
                return None
            with self._lock:
                self._owners[self._claim_key(m)] = self._local.sock
            lane = "" if m.segment is None else f" lane {m.segment[0] + 1}/{m.segment[1]}"
            log.info("%s %s%s (%d bytes) from %s at offset %d",
                     "resuming" if offset else "receiving", m.name, lane, m.length, peer, offset)
            self._status(m, "resumed" if offset else "started", self._held(m))
            for follow in conn.accept(offset):
                self._handle(conn, follow, peer, m)
            return m if conn.state is not State.AWAIT_MANIFEST else None
        if isinstance(event, DataReceived):
            assert current is not None
            try:
                self.spool.write(current, event.offset, event.data)
            except SpoolRefusal as exc:
                log.error("storage failure for %s: %s", event.transfer_id, exc.reason)
                conn.close_with_error(exc.code, exc.reason)
            return current
        if isinstance(event, DataComplete):
            m = event.manifest
            sock = self._local.sock
            if m.segment is not None:
                self._release(m, sock)
                if self._completes(m):  # the file's last segment: the verdict now
                    return self._verdict(conn, m, peer)
                conn.send_receipt(True, "", f"segment {m.segment[0] + 1}/{m.segment[1]} stored")
                with self._status_lock:  # never after the verdict another lane gave
                    if m.transfer_id not in self._verified_early:
                        self._status(m, "active", self._held(m))
                self._outcome("stored")
                return None
            with self._lock:
                early = self._verified_early.pop(m.transfer_id, "") is None
            if early:  # verified with its last segment; the sender asks anyway
                self._release(m, sock)
                conn.send_receipt(True, m.sha256)
                self._outcome("verified")
                return None
            return self._verdict(conn, m, peer)
        if isinstance(event, ManifestRejected):
            self.counters["refused"] += 1
            if event.code is Reason.UNAUTHENTICATED:
                self.counters["unauthenticated"] += 1
            log.warning("refused a manifest from %s (%s): %s", peer, event.code.name, event.reason)
            return current
        if isinstance(event, ProtocolErrorDetected):
            self.counters["protocol_errors"] += 1
            log.warning("closing connection from %s (%s): %s", peer, event.code.name, event.reason)
            return current
        if isinstance(event, FetchRefused):
            log.info("%s will not serve %s: %s", peer, self._local.expect.name, event.reason)
            self._outcome("not_found" if event.code is Reason.NOT_FOUND else "refused",
                          event.reason)
            return current
        if isinstance(event, PeerErrored):
            log.info("%s closed with %s: %s", peer, event.code.name, event.reason)
        return current


# --------------------------------------------------------------------------- forwarder


class Forwarder:
    """Drains a spool's outbox to one downstream receiver; waits out outages with backoff.

    Files stay in the spool (and count against its quota) until the target's receipt
    confirms the hash, so an unreachable target only delays them.
    """

    def __init__(
        self,
        spool: Spool,
        target: tuple[str, int],
        *,
        max_rate_bps: int | None = None,
        backoff: Backoff | None = None,
        connect_timeout: float = 1.0,
        lanes: int = 0,
        keys: Mapping[str, bytes] | None = None,
    ) -> None:
        self.spool = spool
        self.target = target
        self.name = f"{target[0]}:{target[1]}"
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._sender = BulkSender(
            target, max_rate_bps=max_rate_bps,
            backoff=backoff or Backoff(initial=0.2, maximum=5.0),
            connect_timeout=connect_timeout, give_up_after=None,
            retry_refusals=frozenset({Reason.BUSY, Reason.QUOTA, Reason.STORAGE}),
            stop=self._stop, lanes=lanes, keys=keys,
        )
        self._thread: threading.Thread | None = None
        self.counters = {"forwarded": 0, "rejected": 0}

    @property
    def rate_history(self) -> list[tuple[float, float, str]]:
        """The rate probe's course in the last file forwarded (time, bit/s, phase)."""
        return self._sender.rate_history

    def start(self) -> Forwarder:
        self._thread = threading.Thread(target=self._run, name=f"udt-fwd-{self.name}",
                                        daemon=True)
        self._thread.start()
        return self

    def wake(self) -> None:
        """A new file is verified: look at the outbox now."""
        self._wake.set()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._sender.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.clear()
            for manifest, path in self.spool.outbox(self.name):
                if self._stop.is_set():
                    return
                result = self._sender.send_file(path, manifest)
                if result.ok:
                    self.spool.mark_forwarded(manifest.transfer_id, self.name)
                    self.counters["forwarded"] += 1
                    log.info("forwarded %s to %s", manifest.name, self.name)
                elif result.code is not Reason.SHUTDOWN:
                    # A permanent refusal: keep the file (never drop unsent data) and say so.
                    self.counters["rejected"] += 1
                    log.error("%s rejected %s: %s (kept in the spool)", self.name,
                              manifest.name, result.reason)
            self._wake.wait(5.0)
