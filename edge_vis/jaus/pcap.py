"""Reading and writing packet captures of JAUS traffic (pcap and pcapng). Pure bytes.

:func:`read_udp` takes the *content* of a classic pcap or a pcapng file and yields the UDP
datagrams in it, so ``edge-vis decode capture.pcap`` works on what Wireshark, tcpdump or
the relay's own mirror wrote. Link types understood: Ethernet, raw IPv4/IPv6, Linux cooked
capture v1/v2 and BSD loopback; VLAN tags are skipped. :class:`PcapWriter` writes classic
pcap with raw IPv4 framing and synthetic UDP headers, which is how the relay mirrors
serial traffic into a form the same tools read.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from typing import BinaryIO

from edge_vis.errors import DecodeError

JUDP_PORT = 3794

_PCAP_MAGICS = {
    b"\xd4\xc3\xb2\xa1": ("<", 1e-6),
    b"\xa1\xb2\xc3\xd4": (">", 1e-6),
    b"\x4d\x3c\xb2\xa1": ("<", 1e-9),
    b"\xa1\xb2\x3c\x4d": (">", 1e-9),
}
_PCAPNG_SHB = b"\x0a\x0d\x0d\x0a"

LINKTYPE_NULL = 0
LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101
LINKTYPE_LINUX_SLL = 113
LINKTYPE_IPV4 = 228
LINKTYPE_IPV6 = 229
LINKTYPE_LINUX_SLL2 = 276


@dataclass(frozen=True, slots=True)
class UdpDatagram:
    """One UDP datagram from a capture."""

    timestamp: float
    source: tuple[str, int]
    destination: tuple[str, int]
    payload: bytes


def is_capture(data: bytes) -> bool:
    """True when ``data`` starts like a pcap or pcapng file."""
    return data[:4] in _PCAP_MAGICS or data[:4] == _PCAPNG_SHB


def read_udp(data: bytes, port: int | None = JUDP_PORT) -> Iterator[UdpDatagram]:
    """Yield the UDP datagrams of a capture; with ``port``, only those to or from it.

    Raises :class:`DecodeError` when the file is not a capture or is cut short in a header;
    packets that are not UDP over IP are skipped silently (a capture holds all sorts).
    """
    for timestamp, linktype, frame in _frames(data):
        datagram = _udp_from_frame(linktype, frame, timestamp)
        if datagram is None:
            continue
        if port is None or port in (datagram.source[1], datagram.destination[1]):
            yield datagram


def _frames(data: bytes) -> Iterator[tuple[float, int, bytes]]:
    magic = data[:4]
    if magic in _PCAP_MAGICS:
        yield from _pcap_frames(data)
    elif magic == _PCAPNG_SHB:
        yield from _pcapng_frames(data)
    else:
        raise DecodeError("not a pcap or pcapng capture", path="capture", offset=0)


def _pcap_frames(data: bytes) -> Iterator[tuple[float, int, bytes]]:
    order, unit = _PCAP_MAGICS[data[:4]]
    if len(data) < 24:
        raise DecodeError("pcap global header is truncated", path="capture", offset=0)
    linktype = struct.unpack_from(order + "I", data, 20)[0] & 0x0FFFFFFF
    offset = 24
    record = struct.Struct(order + "IIII")
    while offset + 16 <= len(data):
        sec, frac, caplen, _origlen = record.unpack_from(data, offset)
        offset += 16
        if offset + caplen > len(data):
            raise DecodeError("pcap record is truncated", path="capture", offset=offset)
        yield sec + frac * unit, linktype, data[offset : offset + caplen]
        offset += caplen


def _pcapng_frames(data: bytes) -> Iterator[tuple[float, int, bytes]]:
    offset = 0
    order = "<"
    interfaces: list[tuple[int, float]] = []
    while offset + 12 <= len(data):
        block_type_raw = data[offset : offset + 4]
        if block_type_raw == _PCAPNG_SHB:
            bom = data[offset + 8 : offset + 12]
            order = "<" if bom == b"\x4d\x3c\x2b\x1a" else ">"
            interfaces = []
        block_type, length = struct.unpack_from(order + "II", data, offset)
        if length < 12 or offset + length > len(data):
            raise DecodeError("pcapng block is truncated", path="capture", offset=offset)
        body = data[offset + 8 : offset + length - 4]
        if block_type == 1:  # interface description
            linktype = struct.unpack_from(order + "H", body, 0)[0]
            interfaces.append((linktype, _pcapng_resolution(body[8:], order)))
        elif block_type == 6 and len(body) >= 20:  # enhanced packet
            iface, high, low, caplen = struct.unpack_from(order + "IIII", body, 0)
            if iface < len(interfaces):
                linktype, unit = interfaces[iface]
                yield ((high << 32) | low) * unit, linktype, body[20 : 20 + caplen]
        elif block_type == 3 and len(body) >= 4 and interfaces:  # simple packet
            linktype, _ = interfaces[0]
            (origlen,) = struct.unpack_from(order + "I", body, 0)
            yield 0.0, linktype, body[4 : 4 + origlen]
        offset += length


def _pcapng_resolution(options: bytes, order: str) -> float:
    offset = 0
    while offset + 4 <= len(options):
        code, length = struct.unpack_from(order + "HH", options, offset)
        if code == 0:
            break
        if code == 9 and length >= 1:  # if_tsresol
            value = options[offset + 4]
            return 2.0 ** -(value & 0x7F) if value & 0x80 else 10.0 ** -value
        offset += 4 + ((length + 3) & ~3)
    return 1e-6


def _udp_from_frame(linktype: int, frame: bytes, timestamp: float) -> UdpDatagram | None:
    ip: bytes | None
    if linktype == LINKTYPE_ETHERNET:
        ip = _strip_ethernet(frame)
    elif linktype in (LINKTYPE_RAW, LINKTYPE_IPV4, LINKTYPE_IPV6):
        ip = frame
    elif linktype == LINKTYPE_LINUX_SLL:
        ip = frame[16:]
    elif linktype == LINKTYPE_LINUX_SLL2:
        ip = frame[20:]
    elif linktype == LINKTYPE_NULL:
        ip = frame[4:]
    else:
        return None
    if not ip:
        return None
    version = ip[0] >> 4
    if version == 4 and len(ip) >= 20:
        ihl = (ip[0] & 0x0F) * 4
        flags_frag = struct.unpack_from("!H", ip, 6)[0]
        if ip[9] != 17 or flags_frag & 0x1FFF:  # not UDP, or a non-first IP fragment
            return None
        src = ".".join(str(b) for b in ip[12:16])
        dst = ".".join(str(b) for b in ip[16:20])
        udp = ip[ihl:]
    elif version == 6 and len(ip) >= 40:
        if ip[6] != 17:
            return None
        src = _ipv6_text(ip[8:24])
        dst = _ipv6_text(ip[24:40])
        udp = ip[40:]
    else:
        return None
    if len(udp) < 8:
        return None
    sport, dport, length = struct.unpack_from("!HHH", udp, 0)
    payload = udp[8:length] if 8 <= length <= len(udp) else udp[8:]
    return UdpDatagram(timestamp, (src, sport), (dst, dport), bytes(payload))


def _strip_ethernet(frame: bytes) -> bytes | None:
    offset = 12
    while offset + 2 <= len(frame):
        (ethertype,) = struct.unpack_from("!H", frame, offset)
        if ethertype in (0x8100, 0x88A8):
            offset += 4
            continue
        if ethertype in (0x0800, 0x86DD):
            return frame[offset + 2 :]
        return None
    return None


def _ipv6_text(raw: bytes) -> str:
    import ipaddress

    return str(ipaddress.IPv6Address(raw))


class PcapWriter:
    """Write UDP datagrams as a classic pcap (raw IPv4 link type) to a binary stream."""

    def __init__(self, stream: BinaryIO) -> None:
        self._stream = stream
        stream.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, LINKTYPE_RAW))

    def write(self, datagram: UdpDatagram) -> None:
        """Append one datagram with synthetic IPv4 and UDP headers."""
        payload = datagram.payload
        udp_len = 8 + len(payload)
        udp = struct.pack("!HHHH", datagram.source[1], datagram.destination[1], udp_len, 0)
        total = 20 + udp_len
        src = bytes(int(x) for x in datagram.source[0].split("."))
        dst = bytes(int(x) for x in datagram.destination[0].split("."))
        header = struct.pack("!BBHHHBBH4s4s", 0x45, 0, total, 0, 0, 64, 17, 0, src, dst)
        checksum = _ip_checksum(header)
        header = header[:10] + struct.pack("!H", checksum) + header[12:]
        frame = header + udp + payload
        sec = int(datagram.timestamp)
        usec = min(999_999, round((datagram.timestamp - sec) * 1e6))
        self._stream.write(struct.pack("<IIII", sec, usec, len(frame), len(frame)))
        self._stream.write(frame)

    def flush(self) -> None:
        """Flush the underlying stream."""
        self._stream.flush()


def _ip_checksum(header: bytes) -> int:
    total = sum(struct.unpack(f"!{len(header) // 2}H", header))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF
