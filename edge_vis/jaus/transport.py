"""The AS5669A general transport header and JUDP datagrams. No I/O.

A JUDP datagram is one version byte (``0x02``) followed by one or more *general
transport messages* back to back::

    +0  u8   message type (bits 0-5) | header-compression flags (bits 6-7)
    +1  u16  data size: bytes of this message from +0 through the sequence number
   [+3  u8   HC number  } only when the HC flags are non-zero
    +4  u8   HC length  }]
    +3  u8   flags: priority (0-1) | broadcast (2-3) | ACK/NAK (4-5) | data flags (6-7)
    +4  u32  destination JAUS ID
    +8  u32  source JAUS ID
    +12 ...  payload: the 2-byte message code and the body (or a fragment of them)
    end u16  sequence number

Everything is little-endian. The serial link carries the same general transport
message inside its own framing, so :func:`encode_packet`/:func:`decode_packet` are shared.

Header compression is parsed (so that an error names it) but not supported: nobody in the
public JAUS code bases implements it, and the position of its flag bits differs between
them. A datagram using it raises :class:`~edge_vis.errors.UnsupportedError`.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Any

from edge_vis.errors import DecodeError, EncodeError, UnsupportedError
from edge_vis.jaus.address import ADDRESSES, JausAddress, address_from_id

JUDP_VERSION = 2
#: data size of a message with an empty payload (header 12 bytes + sequence number 2)
MIN_DATA_SIZE = 14
#: the largest payload (message code + body) a JAUS Toolset node manager accepts per packet
JTS_MAX_PAYLOAD = 4079

_HEAD = struct.Struct("<BHBII")  # type/hc, data size, flags, destination, source
#: the header's fixed part: type/HC flags, data size, flags, destination, source
HEADER = _HEAD
_HEAD_HC = struct.Struct("<BHBBBII")  # with HC number and HC length
_SEQ = struct.Struct("<H")
_CODE = struct.Struct("<H")
_from_id = address_from_id  # cached: two per packet header


class Priority(IntEnum):
    """Transport priority (flags bits 0-1)."""

    LOW = 0
    STANDARD = 1
    HIGH = 2
    SAFETY_CRITICAL = 3


class Broadcast(IntEnum):
    """Broadcast flag (flags bits 2-3)."""

    NONE = 0
    LOCAL = 1
    GLOBAL = 2


class AckNak(IntEnum):
    """ACK/NAK field (flags bits 4-5)."""

    NONE = 0
    REQUEST = 1
    NAK = 2
    ACK = 3


class DataFlags(IntEnum):
    """Large-message fragment position (flags bits 6-7)."""

    SINGLE = 0
    FIRST = 1
    MIDDLE = 2
    LAST = 3


@dataclass(frozen=True, slots=True)
class Packet:
    """One general transport message: header fields and the payload.

    ``payload`` is the application payload (2-byte message code + body) for a single
    packet, or a slice of it for a fragment of a large message.
    """

    destination: JausAddress
    source: JausAddress
    payload: bytes
    sequence: int = 0
    priority: int = Priority.STANDARD
    broadcast: int = Broadcast.NONE
    ack_nak: int = AckNak.NONE
    data_flags: int = DataFlags.SINGLE
    message_type: int = 0
    hc_flags: int = 0
    hc_number: int = 0
    hc_length: int = 0
    #: the bytes this packet was decoded from, re-sent as they are when it is forwarded
    #: (not an init field: ``replace()`` leaves it ``None``, so a changed copy is encoded anew)
    wire: bytes | None = field(default=None, init=False, compare=False, repr=False)

    @property
    def message_code(self) -> int | None:
        """The JAUS message code, when this packet starts a message; else ``None``."""
        if self.data_flags in (DataFlags.SINGLE, DataFlags.FIRST) and len(self.payload) >= 2:
            return int(_CODE.unpack_from(self.payload)[0])
        return None

    @property
    def data_size(self) -> int:
        """The header's data size field for this packet."""
        return MIN_DATA_SIZE + len(self.payload) + (2 if self.hc_flags else 0)

    @property
    def flags(self) -> int:
        """The packed flags byte."""
        return (
            (self.priority & 3)
            | (self.broadcast & 3) << 2
            | (self.ack_nak & 3) << 4
            | (self.data_flags & 3) << 6
        )

    def with_sequence(self, sequence: int) -> Packet:
        """A copy carrying another sequence number."""
        return replace(self, sequence=sequence & 0xFFFF)

    def header_dict(self) -> dict[str, object]:
        """The header fields as plain values (for logs and ``edge-vis decode``)."""
        return {
            "message_type": self.message_type,
            "hc_flags": self.hc_flags,
            "data_size": self.data_size,
            "priority": self.priority,
            "broadcast": self.broadcast,
            "ack_nak": self.ack_nak,
            "data_flags": self.data_flags,
            "destination": str(self.destination),
            "source": str(self.source),
            "sequence": self.sequence,
        }


class _Decoded:
    """Builds a :class:`Packet` for the decoder at a fraction of the cost.

    A frozen dataclass sets each of its 13 fields through ``object.__setattr__``, the
    most expensive step of receiving a datagram. This class has the very same slots; the
    decoder makes one with ``object.__new__`` (no ``__init__`` call), assigns the slots
    directly, then makes it a ``Packet`` (``__class__`` assignment between classes of one
    layout): from then on it is an ordinary, frozen ``Packet``.
    """

    __slots__ = Packet.__slots__  # type: ignore[attr-defined]


_new = object.__new__


def _packet(dst: int, src: int, flags: int, message_type: int, wire: bytes) -> Packet:
    """The :class:`Packet` of one undamaged general transport message ``wire``."""
    p: Any = _new(_Decoded)
    addresses = ADDRESSES
    p.destination = addresses.get(dst) or _from_id(dst)
    p.source = addresses.get(src) or _from_id(src)
    p.payload = wire[12:-2]
    p.sequence = wire[-2] | wire[-1] << 8
    p.priority = flags & 3
    p.broadcast = (flags >> 2) & 3
    p.ack_nak = (flags >> 4) & 3
    p.data_flags = (flags >> 6) & 3
    p.message_type = message_type
    p.hc_flags = p.hc_number = p.hc_length = 0
    p.wire = wire
    p.__class__ = Packet
    return p  # type: ignore[no-any-return]


def encode_packet(packet: Packet) -> bytes:
    """Encode one general transport message (no version byte).

    A packet that was decoded from the wire encodes to the very bytes it came from.
    """
    wire = packet.wire
    if wire is not None:
        return wire
    size = packet.data_size
    if size > 0xFFFF:
        raise EncodeError(f"payload of {len(packet.payload)} bytes exceeds one packet; fragment it")
    if packet.hc_flags:
        raise EncodeError("header compression is not supported")
    head = _HEAD.pack(
        (packet.message_type & 0x3F),
        size,
        packet.flags,
        packet.destination.id,
        packet.source.id,
    )
    return b"".join((head, packet.payload, _SEQ.pack(packet.sequence & 0xFFFF)))


def decode_packet(data: bytes | memoryview, offset: int = 0) -> tuple[Packet, int]:
    """Decode one general transport message at ``offset``; return it and the next offset.

    Raises :class:`DecodeError` for truncated or inconsistent input and
    :class:`UnsupportedError` for header compression.
    """
    available = len(data) - offset
    if available < MIN_DATA_SIZE:
        raise DecodeError(
            f"truncated transport header: {available} bytes, need at least {MIN_DATA_SIZE}",
            path="transport",
            offset=offset,
        )
    type_hc, size, flags, dst, src = _HEAD.unpack_from(data, offset)
    hc_flags = type_hc >> 6
    message_type = type_hc & 0x3F
    if hc_flags:
        if available >= _HEAD_HC.size:
            _, _, hc_number, hc_length, _, _, _ = _HEAD_HC.unpack_from(data, offset)
        else:
            hc_number = hc_length = 0
        raise UnsupportedError(
            f"header compression (HC flags {hc_flags}, HC number {hc_number}, "
            f"HC length {hc_length}) is not supported",
            path="transport.hc_flags",
            offset=offset,
        )
    if size < MIN_DATA_SIZE:
        raise DecodeError(
            f"data size {size} is below the minimum of {MIN_DATA_SIZE}",
            path="transport.data_size",
            offset=offset + 1,
        )
    if size > available:
        raise DecodeError(
            f"data size {size} exceeds the {available} bytes left",
            path="transport.data_size",
            offset=offset + 1,
        )
    end = offset + size
    return _packet(dst, src, flags, message_type, bytes(data[offset:end])), end


def packet_from_wire(wire: bytes) -> Packet:
    """The :class:`Packet` of ``wire``, one whole general transport message without
    header compression (its data size equal to its length): what a router that took
    such bytes without decoding them (:meth:`edge_vis.routing.router.Router.forward`)
    queues. Raises :class:`DecodeError` otherwise."""
    packets = unpack_message(wire)
    if len(packets) != 1:
        raise DecodeError(f"{len(packets)} transport messages where one was expected",
                          path="transport", offset=0)
    return packets[0]


def unpack_message(wire: bytes) -> list[Packet]:
    """Every general transport message in ``wire``: a JUDP datagram without its version
    byte. Raises :class:`DecodeError` as :func:`unpack_datagram` does."""
    return _messages(wire, 0)


def _messages(data: bytes | memoryview, start: int) -> list[Packet]:
    """Every general transport message in ``data`` from ``start`` on (1: behind a JUDP
    version byte; 0: a message's bytes), offsets in errors counted from ``data``'s start."""
    end = len(data)
    if end - start >= MIN_DATA_SIZE:  # the usual case: one message, no compression
        type_hc, length, flags, dst, src = _HEAD.unpack_from(data, start)
        if length == end - start and length >= MIN_DATA_SIZE and not type_hc >> 6:
            return [_packet(dst, src, flags, type_hc & 0x3F, bytes(data[start:]))]
    packets = []
    offset = start
    while offset < end:
        packet, offset = decode_packet(data, offset)
        packets.append(packet)
    if not packets:
        raise DecodeError("datagram holds no transport message", path="transport", offset=1)
    return packets


def pack_datagram(packets: Iterable[Packet]) -> bytes:
    """A JUDP datagram: the version byte, then every packet back to back."""
    return bytes([JUDP_VERSION]) + b"".join(encode_packet(p) for p in packets)


def unpack_datagram(data: bytes | memoryview, size: int | None = None) -> list[Packet]:
    """Every general transport message in a JUDP datagram.

    ``size``: the datagram is the first ``size`` bytes of ``data`` (a receive buffer);
    default all of it. Raises :class:`DecodeError` when the datagram is empty, has another
    version, or any message in it is malformed (a datagram is accepted or refused whole).
    """
    if size is not None:
        if size >= 1 + MIN_DATA_SIZE and data[0] == JUDP_VERSION:
            # the usual datagram: one message, no header compression
            type_hc, length, flags, dst, src = _HEAD.unpack_from(data, 1)
            if length == size - 1 and length >= MIN_DATA_SIZE and not type_hc >> 6:
                return [_packet(dst, src, flags, type_hc & 0x3F, bytes(data[1:size]))]
        data = data[:size]
    if not data:
        raise DecodeError("empty datagram", path="version", offset=0)
    version = data[0]
    if version != JUDP_VERSION:
        if version == 1:
            raise UnsupportedError("JUDP version 1 (AS5669) header is not supported",
                                   path="version", offset=0)
        if version == 0x4A:  # 'J', the legacy "JAUS01.0" OPC header
            raise UnsupportedError("legacy JAUS01.0 (OPC 2.75) header is not supported",
                                   path="version", offset=0)
        raise DecodeError(f"unknown JUDP version byte 0x{version:02X}", path="version", offset=0)
    return _messages(data, 1)
