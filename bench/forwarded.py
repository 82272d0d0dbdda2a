"""What the forwarder benchmarks send through the router and read back.

Shared by ``bench/router.py`` and ``bench/footprint.py``: one small JAUS message per
datagram with a stamp in its payload (it keeps runs distinct for the router's duplicate
filter, and carries the send time for latency), and the sink that counts or reads the
forwarded messages out of a UDP socket or a pty master (JAUS serial framing).
"""

from __future__ import annotations

import os
import socket
import struct

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import SerialDeframer, SerialFrame
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

SOURCE = JausAddress(42, 1, 1)
TARGET = JausAddress(126, 1, 199)
_STAMP = struct.Struct("<QI")


def message(seq: int, stamp: int, destination: JausAddress = TARGET) -> bytes:
    payload = b"\x05\x04" + _STAMP.pack(stamp, seq)  # 0x0405 SetWrenchEffort-sized
    return pack_datagram([Packet(destination, SOURCE, payload, sequence=seq & 0xFFFF)])


def stamp_of(payload: bytes) -> int:
    return int(_STAMP.unpack_from(payload, 2)[0])


class Sink:
    """Receives forwarded messages from a UDP socket or a pty master."""

    def __init__(self, udp: socket.socket | None, pty_fd: int | None,
                 only_from: JausAddress | None = None) -> None:
        self.udp = udp
        self.fd = pty_fd
        #: keep only serial frames from this source (a relay writes its own queries too)
        self.only_from = only_from
        self.deframer = SerialDeframer()
        self.tail = b""

    def count(self) -> int:
        """How many messages arrived (cheap: the sink must not be the bottleneck)."""
        if self.udp is not None:
            n = 0
            while True:
                try:
                    self.udp.recv(65535)
                except BlockingIOError:
                    return n
                n += 1
        n = 0
        while True:
            try:
                data = os.read(self.fd, 65536)  # type: ignore[arg-type]
            except (BlockingIOError, OSError):
                return n
            if not data:
                return n
            # DLE SOH + version 2 starts every frame; these payloads never contain it
            n += (self.tail + data).count(b"\x10\x01\x02")
            self.tail = data[-2:]

    def fileno(self) -> int:
        return self.udp.fileno() if self.udp is not None else self.fd  # type: ignore[return-value]

    def drain(self) -> list[int]:
        """Send stamps of everything available now (non-blocking)."""
        out: list[int] = []
        if self.udp is not None:
            while True:
                try:
                    data = self.udp.recv(65535)
                except BlockingIOError:
                    return out
                for p in unpack_datagram(data):
                    out.append(stamp_of(p.payload))
        while True:
            try:
                data = os.read(self.fd, 65536)  # type: ignore[arg-type]
            except (BlockingIOError, OSError):
                return out
            if not data:
                return out
            for r in self.deframer.feed(data):
                if isinstance(r, SerialFrame) and (self.only_from is None
                                                   or r.packet.source == self.only_from):
                    out.append(stamp_of(r.packet.payload))
