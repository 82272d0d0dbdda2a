"""A traffic mirror for analysis: copies of every JAUS packet the links carry. Does I/O.

Attach it to links (:meth:`Mirror.attach`) and every packet received or sent is copied,
as a JUDP datagram (version byte + general transport message), to

* a UDP port on loopback, for Wireshark or ``tcpdump -i lo udp port N`` live, and/or
* a classic pcap file (raw IPv4 link type) with synthetic IPv4/UDP headers on port 3794,
  which ``edge-vis decode FILE.pcap`` and Wireshark read.

Serial traffic has no IP addresses, so both ends get synthetic ones: the relay is
``127.0.0.1:3794``; a peer that is not an ``(ip, port)`` pair (a serial device) becomes
``127.0.1.N:3794``, one ``N`` per (link, peer) in order of appearance; a broadcast goes
to ``239.255.0.1:3794``. Mirroring never blocks the relay: a full socket buffer or a
write error drops the copy and counts it in :attr:`Mirror.dropped`.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import BinaryIO

from edge_vis.jaus.pcap import JUDP_PORT, PcapWriter, UdpDatagram
from edge_vis.jaus.transport import Packet, pack_datagram
from edge_vis.routing.link import Link, Peer

log = logging.getLogger(__name__)

RELAY_ADDRESS = ("127.0.0.1", JUDP_PORT)
BROADCAST_ADDRESS = ("239.255.0.1", JUDP_PORT)


class Mirror:
    """Copies link traffic to a loopback UDP port and/or a pcap file."""

    def __init__(
        self,
        *,
        udp_port: int | None = None,
        pcap: str | Path | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.udp_port = udp_port
        self.clock = clock
        self.copied = 0
        self.dropped = 0
        self._socket: socket.socket | None = None
        self._file: BinaryIO | None = None
        self._writer: PcapWriter | None = None
        self._synthetic: dict[tuple[str, Peer], tuple[str, int]] = {}
        if udp_port is not None:
            self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._socket.setblocking(False)
        if pcap is not None:
            self._file = open(pcap, "wb")  # noqa: SIM115 - kept open for the mirror's life
            self._writer = PcapWriter(self._file)

    def attach(self, link: Link) -> None:
        """Mirror everything ``link`` receives and sends from now on."""
        link.add_tap(self.tap)

    def tap(self, link: str, direction: str, peer: Peer | None,
            packets: Sequence[Packet]) -> None:
        """Record one datagram's worth of packets (a
        :data:`~edge_vis.routing.link.TapCallback`)."""
        data = pack_datagram(packets)
        if self._socket is not None and self.udp_port is not None:
            try:
                self._socket.sendto(data, ("127.0.0.1", self.udp_port))
            except OSError:
                self.dropped += 1
        if self._writer is not None:
            remote = self._address(link, peer)
            src, dst = (remote, RELAY_ADDRESS) if direction == "in" else (RELAY_ADDRESS, remote)
            try:
                self._writer.write(UdpDatagram(self.clock(), src, dst, data))
            except (OSError, ValueError):
                self.dropped += 1
        self.copied += 1

    def _address(self, link: str, peer: Peer | None) -> tuple[str, int]:
        if peer is None:
            return BROADCAST_ADDRESS
        if (isinstance(peer, tuple) and len(peer) >= 2 and isinstance(peer[0], str)
                and isinstance(peer[1], int) and peer[0].count(".") == 3):
            return (peer[0], peer[1])
        key = (link, peer)
        found = self._synthetic.get(key)
        if found is None:
            n = len(self._synthetic) + 1
            found = self._synthetic[key] = (f"127.0.{1 + (n - 1) // 250}.{1 + (n - 1) % 250}",
                                            JUDP_PORT)
        return found

    def close(self) -> None:
        """Flush and close the outputs; safe to call twice."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None
        if self._file is not None:
            self._file.close()
            self._file = None
            self._writer = None
