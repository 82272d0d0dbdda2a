"""Helpers of the UDT bulk-transfer tests: hashes, free ports, waiting, a connection's
pace, a raw client."""

from __future__ import annotations

import hashlib
import socket
import time
from collections.abc import Callable
from typing import Any


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(predicate: Callable[[], Any], timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def paces_until(sock: Any, received: list[int], size: int, every: float) -> list[float]:
    """The seconds between packets libudt kept to on ``sock`` (read every ``every``
    seconds) until ``received`` (byte counts read at the far end) adds up to ``size``."""
    from links.udt import udt_stats

    paces = []
    while sum(received) < size:
        stats = udt_stats.read(sock)
        if stats is not None and stats.pace is not None:
            paces.append(stats.pace)
        time.sleep(every)
    return paces


class RawClient:
    """A UDT client that sends arbitrary bytes and reads back raw frames (a misbehaving peer)."""

    def __init__(self, address: tuple[str, int]) -> None:
        import udt4py

        from links.udt.protocol import _FrameReader

        self._udt = udt4py
        self.sock = udt4py.UDTSocket()
        self.sock.connect(address)
        self.sock.UDT_RCVTIMEO = 200
        self._reader = _FrameReader()

    def send(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            view = view[self.sock.send(view):]

    def frame(self, timeout: float = 5.0) -> tuple[Any, bytes]:
        """The next control frame the receiver sent, as (FrameType, payload)."""
        buf = bytearray(65536)
        deadline = time.monotonic() + timeout
        pending: list[tuple[Any, bytes]] = []
        while time.monotonic() < deadline:
            try:
                n = self.sock.recv(buf)
            except self._udt.UDTException as exc:
                if exc.error_code != self._udt.UDTException.ETIMEOUT:
                    break
                continue
            frames, garbage = self._reader.feed(bytes(buf[:n]))
            assert garbage is None, garbage
            pending += frames
            if pending:
                return pending[0]
        raise AssertionError("no frame from the receiver")

    def close(self) -> None:
        self.sock.close()
