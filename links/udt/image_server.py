"""The vehicle side of pull: serve the image files of one directory to fetchers over UDT.

``edge-vis serve-images --dir D`` runs an :class:`ImageServer`. A relay that heard a
vehicle announce an image connects, sends FETCH with the file name (or one lane's segment
of it), and the server answers with that file's manifest and data exactly as
``send-image`` would push them; the fetcher's spool decides where to resume. A file is
hashed once per (size, modification time). Names are plain file names inside the
directory (no paths, no hidden or partial files), so nothing outside it can be read.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from edge_vis.errors import LinkError
from links.udt.image_service import manifest_for_file
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
    _close,
    _send_all,
    listen,
    udt4py,
)

log = logging.getLogger(__name__)


class ImageServer:
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
        self._bind = listen
        self._listener: Any = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()
        self._manifests: dict[str, tuple[tuple[int, int], Manifest]] = {}
        self._open = 0
        self.counters = {"connections": 0, "served": 0, "not_found": 0, "interrupted": 0}

    @property
    def address(self) -> tuple[str, int]:
        if self._listener is None:
            raise LinkError("image server not started")
        return tuple(self._listener.address)  # type: ignore[return-value]

    def start(self) -> ImageServer:
        self._listener = listen(self._bind, linger=0, max_rate_bps=self.max_rate_bps or 0)
        t = threading.Thread(target=self._accept_loop, name="udt-serve-accept", daemon=True)
        t.start()
        self._threads.append(t)
        log.info("serving images of %s on udt://%s:%d", self.directory, *self.address)
        return self

    def stop(self) -> None:
        """Stop accepting and serving (idempotent)."""
        self._stop.set()
        if self._listener is not None:
            self._listener.close()
        for t in list(self._threads):
            t.join(timeout=5)
        self._threads.clear()

    def __enter__(self) -> ImageServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

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
        m = manifest_for_file(path, vehicle_id=self.vehicle_id)
        with self._lock:
            self._manifests[name] = (stamp, m)
            while len(self._manifests) > 256:
                del self._manifests[next(iter(self._manifests))]
        return m

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
            with self._lock:
                busy = self._open >= self.max_connections
                self._open += 0 if busy else 1
            if busy:
                _close(sock)
                continue
            t = threading.Thread(target=self._serve, args=(sock, f"{peer[0]}:{peer[1]}"),
                                 name=f"udt-serve-{peer[1]}", daemon=True)
            self._threads = [x for x in self._threads if x.is_alive()]
            self._threads.append(t)
            t.start()

    def _serve(self, sock: Any, peer: str) -> None:
        udt = udt4py()
        sock.UDT_RCVTIMEO = POLL_MS
        sock.UDT_SNDTIMEO = POLL_MS
        sender = BulkSender(sock.peer_address, max_rate_bps=self.max_rate_bps,
                            stop=self._stop, idle_timeout=self.idle_timeout)
        conn = SenderConnection(idle_timeout=self.idle_timeout)
        buf = bytearray(64 * 1024)
        try:
            while not self._stop.is_set():
                try:
                    n = sock.recv(buf)
                except udt.UDTException as exc:
                    if exc.error_code != udt.UDTException.ETIMEOUT:
                        return
                    continue
                for event in conn.receive_data(bytes(buf[:n]), time.monotonic()):
                    if isinstance(event, FetchRequested):
                        self._answer(sock, conn, sender, event, peer)
                    elif isinstance(event, PeerErrored | ProtocolErrorDetected):
                        log.info("fetcher %s: %s", peer, event.reason)
                out = conn.data_to_send()
                if out:
                    _send_all(sock, out)
                if conn.state is not State.IDLE:
                    return
        except ConnectionLost as exc:
            log.info("fetcher %s lost: %s", peer, exc)
        finally:
            with self._lock:
                self._open -= 1
            _close(sock)

    def _answer(self, sock: Any, conn: SenderConnection, sender: BulkSender,
                event: FetchRequested, peer: str) -> None:
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
        if event.segment is not None:
            m = replace(m, segment=event.segment)
        rate = min(r for r in (self.max_rate_bps, event.rate_bps) if r) if (
            self.max_rate_bps or event.rate_bps) else None
        if rate:  # the fetcher's share of its link budget, never above our own cap
            sock.UDT_MAXBW = max(1, rate // 8)
        result = sender.serve(sock, conn, self.directory / event.name, m)
        if isinstance(result, int) or result is None:
            self.counters["interrupted"] += 1
            raise ConnectionLost(f"{event.name} interrupted")
        if result.ok:
            self.counters["served"] += 1
        log.info("served %s to %s: %s", event.name, peer, result.reason)
