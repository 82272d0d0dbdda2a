"""JAUS serial framing (AS5669A "JSerial", as spoken by the JAUS Toolset). No I/O.

One general transport message (see :mod:`edge_vis.jaus.transport`) per frame::

    DLE SOH | version(1) length(2) | DLE STX | header CRC(2) | message ... seq | DLE ETX | CRC(2)

* ``length`` is the message's data size (header + payload + sequence number).
* The header CRC covers version and length, register seeded with 0xFFFF.
* The packet CRC covers the header-CRC field through the sequence number (not DLE ETX),
  register seeded with the header CRC value.
* Both CRCs are CRC-16/MCRF4XX (reflected 0x8408, no final XOR) over the *unstuffed* bytes.
* Every 0x10 other than the three framing DLEs is sent doubled ("DLE stuffing").

:class:`SerialDeframer` is a byte-stream parser: feed it whatever the port returned and
it yields whole frames or specific errors. Theory of operation:

* Bytes before a ``DLE SOH`` are line noise; they are reported as one
  ``SerialError("noise", bytes)`` per contiguous run, never silently dropped. Every byte
  fed ends up in exactly one frame's ``raw`` or one error's ``data`` (or is still
  buffered).
* A frame is parsed from its ``DLE SOH``. A ``DLE SOH`` seen inside a frame means the
  sender restarted: the partial frame is reported (``"truncated"``) and parsing resumes
  at the new start, so a lost byte costs one frame, not the stream.
* A bad header (CRC, length) skips only the ``DLE SOH`` pair and resynchronises on the
  next start; a bad packet CRC consumes the frame.
* A partial frame older than ``timeout`` seconds (judged by the ``now`` passed to
  :meth:`SerialDeframer.feed`) is discarded and reported, so a radio that dropped the
  tail of a frame does not hold back the next one. ``feed(b"", now)`` checks the timeout
  without new data.
* The buffer is bounded: a partial frame can never exceed the stuffed size its header
  announced, nor ``max_frame`` bytes.
"""

from __future__ import annotations

import struct
from binascii import crc_hqx
from collections.abc import Iterable
from dataclasses import dataclass

from edge_vis.errors import DecodeError
from edge_vis.jaus.transport import (
    JUDP_VERSION,
    MIN_DATA_SIZE,
    Packet,
    decode_packet,
    encode_packet,
)

DLE = 0x10
SOH = 0x01
STX = 0x02
ETX = 0x03

_START = bytes((DLE, SOH))
_MID = bytes((DLE, STX))
_END = bytes((DLE, ETX))
_DLE = bytes((DLE,))
_DLE2 = bytes((DLE, DLE))
_U16 = struct.Struct("<H")
_HEAD = struct.Struct("<BH")  # version, length

#: unstuffed bytes a frame adds around the general transport message
FRAME_OVERHEAD = 15
#: default bound on one stuffed frame (a full 16-bit data size, every byte stuffed)
MAX_FRAME = 2 * (0xFFFF + FRAME_OVERHEAD)


#: each byte value with its bits in reverse order
_REVERSED = bytes(int(f"{b:08b}"[::-1], 2) for b in range(256))


def crc16(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
    """CRC-16/MCRF4XX of ``data`` continuing from register value ``crc``.

    ``crc16(b"123456789") == 0x6F91``. MCRF4XX is the bit-reflected form of the CCITT
    CRC that :func:`binascii.crc_hqx` computes in C: reversing the bits of every input
    byte and of the register turns one into the other, at C speed instead of a Python
    loop per byte (a frame is checked twice on the way in and computed twice on the way out).
    """
    rev = _REVERSED
    crc = crc_hqx(bytes(data).translate(rev), rev[crc & 0xFF] << 8 | rev[crc >> 8])
    return rev[crc & 0xFF] << 8 | rev[crc >> 8]


#: :func:`_framed_head` by message length, looked up inline by :func:`frame`
_HEADS: dict[int, tuple[bytes, int]] = {}


def _framed_head(length: int) -> tuple[bytes, int]:
    """Everything of a frame that depends only on its message's length: ``DLE SOH``, the
    stuffed version and length, ``DLE STX`` and the stuffed header CRC; and the packet
    CRC's register after the header CRC (bit-reversed, for ``crc_hqx``: see :func:`crc16`).
    """
    head = _HEAD.pack(JUDP_VERSION, length)
    crc = crc16(head)
    crc_bytes = _U16.pack(crc)
    rev = _REVERSED
    register = crc_hqx(crc_bytes.translate(rev), rev[crc & 0xFF] << 8 | rev[crc >> 8])
    if len(_HEADS) >= 256:
        _HEADS.clear()
    found = _HEADS[length] = (
        _START + head.replace(_DLE, _DLE2) + _MID + crc_bytes.replace(_DLE, _DLE2), register)
    return found


#: the stuffed byte that ends a frame for each value of half the ``crc_hqx`` register
_TAIL = tuple(bytes((_REVERSED[b],)).replace(bytes((DLE,)), bytes((DLE, DLE)))
              for b in range(256))


def stuff(data: bytes) -> bytes:
    """Double every DLE byte."""
    return data.replace(_DLE, _DLE2)


def frame(packet: Packet) -> bytes:
    """The bytes on the line for one packet (framed, CRCs computed, DLE-stuffed).

    :func:`crc16` written out: this runs once per packet sent on a serial link.
    """
    message = packet.wire
    if message is None:
        message = encode_packet(packet)
    start, register = _HEADS.get(len(message)) or _framed_head(len(message))
    crc = crc_hqx(message.translate(_REVERSED), register)
    # the packet CRC, little-endian, is the bit-reversed register's bytes in swapped order
    return b"".join((start, message.replace(_DLE, _DLE2), _END, _TAIL[crc >> 8],
                     _TAIL[crc & 0xFF]))


#: pieces :func:`frame_parts` makes of each frame
FRAME_PARTS = 5


def frame_parts(messages: Iterable[bytes]) -> list[bytes]:
    """The frames of general transport messages given as their bytes (``Packet.wire``,
    or what :func:`~edge_vis.jaus.transport.encode_packet` returns), as one list of
    pieces, :data:`FRAME_PARTS` per frame: ``b"".join`` of a frame's pieces is
    :func:`frame` of it, byte for byte; of the whole list, every frame in order (one
    write for a batch, without a call or a join per message)."""
    heads = _HEADS
    rev = _REVERSED
    tail = _TAIL
    end = _END
    dle, dle2 = _DLE, _DLE2
    out: list[bytes] = []
    extend = out.extend
    for message in messages:
        start, register = heads.get(len(message)) or _framed_head(len(message))
        crc = crc_hqx(message.translate(rev), register)
        extend((start, message.replace(dle, dle2), end, tail[crc >> 8], tail[crc & 0xFF]))
    return out


@dataclass(frozen=True, slots=True)
class SerialFrame:
    """A frame that passed both CRCs and decoded; ``raw`` is its stuffed bytes."""

    packet: Packet
    raw: bytes


@dataclass(frozen=True, slots=True)
class SerialError:
    """Bytes that were discarded, and why (``noise``, ``header CRC mismatch``, ...)."""

    reason: str
    data: bytes


class _Incomplete(Exception):
    """More bytes are needed."""


class _Broken(Exception):
    """A DLE followed by a byte not allowed here; ``at`` is the DLE's index."""

    def __init__(self, at: int, control: int) -> None:
        self.at = at
        self.control = control


def _unstuff_until(buf: bytearray, pos: int, marker: int, limit: int) -> tuple[bytes, int]:
    """Unstuff from ``pos`` up to ``DLE marker``; return the data and the index after it."""
    out = bytearray()
    while True:
        i = buf.find(DLE, pos)
        if i < 0 or i + 1 >= len(buf):
            out += buf[pos:] if i < 0 else buf[pos:i]
            if len(out) > limit:
                raise _Broken(len(buf) if i < 0 else i, -1)
            raise _Incomplete
        out += buf[pos:i]
        control = buf[i + 1]
        if control == DLE:
            out.append(DLE)
            pos = i + 2
        elif control == marker:
            return bytes(out), i + 2
        else:
            raise _Broken(i, control)
        if len(out) > limit:
            raise _Broken(i, -1)


def _unstuff_count(buf: bytearray, pos: int, count: int) -> tuple[bytes, int]:
    """Read ``count`` unstuffed bytes from ``pos``; return them and the index after."""
    out = bytearray()
    end = len(buf)
    while len(out) < count:
        if pos >= end:
            raise _Incomplete
        byte = buf[pos]
        if byte == DLE:
            if pos + 1 >= end:
                raise _Incomplete
            if buf[pos + 1] != DLE:
                raise _Broken(pos, buf[pos + 1])
            pos += 1
        out.append(byte)
        pos += 1
    return bytes(out), pos


class SerialDeframer:
    """Turns a serial byte stream into :class:`SerialFrame` and :class:`SerialError` values.

    ``timeout`` (seconds) bounds how long a partial frame is kept; ``max_frame`` bounds
    the bytes of one stuffed frame (and so the buffer).
    """

    def __init__(self, *, timeout: float = 1.0, max_frame: int = MAX_FRAME) -> None:
        self.timeout = timeout
        self.max_frame = max_frame
        self._buf = bytearray()
        self._started: float | None = None

    @property
    def buffered(self) -> int:
        """Bytes held for a partial frame."""
        return len(self._buf)

    def feed(self, data: bytes, now: float = 0.0) -> list[SerialFrame | SerialError]:
        """Add received bytes; return every frame and error they complete, in order."""
        out: list[SerialFrame | SerialError] = []
        buf = self._buf
        if buf and self._started is not None and now - self._started > self.timeout:
            out.append(SerialError("timeout", bytes(buf)))
            buf.clear()
            self._started = None
        buf += data
        while buf:
            start = self._find_start(buf, out)
            if start < 0:
                break
            if start:
                del buf[:start]
            try:
                result, consumed = self._parse(buf)
            except _Incomplete:
                restart = self._complete_frame_behind(buf)
                if restart:
                    out.append(SerialError("truncated", bytes(buf[:restart])))
                    del buf[:restart]
                    self._started = None
                    continue
                if len(buf) > self.max_frame:
                    out.append(SerialError("oversize", bytes(buf)))
                    buf.clear()
                    break
                if self._started is None:
                    self._started = now
                break
            if isinstance(result, SerialError):
                # never let a broken frame swallow the start of the next one
                nxt = buf.find(_START, 1, consumed)
                if nxt > 0:
                    consumed = nxt
                    result = SerialError(result.reason, bytes(buf[:nxt]))
            out.append(result)
            del buf[:consumed]
            self._started = None
        if not buf:
            self._started = None
        return out

    @staticmethod
    def _find_start(buf: bytearray, out: list[SerialFrame | SerialError]) -> int:
        """Index of the next DLE SOH (reporting noise before it), or -1 to wait.

        Noise has no stuffing context, so the search is greedy: any ``10 01`` is tried as
        a start. A false start fails its header CRC and costs two bytes; pairing DLEs here
        instead would lose a real frame whenever the noise ended in an odd DLE.
        """
        i = buf.find(_START)
        if i < 0:
            keep = 1 if buf[-1] == DLE else 0  # may be the first half of DLE SOH
            if len(buf) > keep:
                out.append(SerialError("noise", bytes(buf[: len(buf) - keep])))
                del buf[: len(buf) - keep]
            return -1
        if i:
            out.append(SerialError("noise", bytes(buf[:i])))
        return i

    def _complete_frame_behind(self, buf: bytearray) -> int:
        """Index of a later start holding a whole valid frame, else 0.

        An incomplete start can be false (noise containing ``10 01`` whose stray DLE
        pairs with a real frame's DLE); a valid frame behind it must not wait for it.
        """
        pos = buf.find(_START, 1)
        while pos > 0:
            try:
                result, _ = self._parse(buf[pos:])
            except _Incomplete:
                result = None
            if isinstance(result, SerialFrame):
                return pos
            pos = buf.find(_START, pos + 1)
        return 0

    def _parse(self, buf: bytearray) -> tuple[SerialFrame | SerialError, int]:
        """Parse the frame starting at ``buf[0:2] == DLE SOH``; return it and bytes used."""
        try:
            head, pos = _unstuff_until(buf, 2, STX, 3)
            if len(head) != 3:
                return SerialError("bad header", bytes(buf[:pos])), pos
            version = head[0] & 0x0F
            (length,) = _U16.unpack_from(head, 1)
            if version != JUDP_VERSION:
                return SerialError(f"unsupported version {head[0]:#04x}", bytes(buf[:2])), 2
            if length < MIN_DATA_SIZE:
                return SerialError(f"length {length} below {MIN_DATA_SIZE}", bytes(buf[:2])), 2
            header_crc_bytes, pos = _unstuff_count(buf, pos, 2)
            header_crc = crc16(head)
            if _U16.unpack(header_crc_bytes)[0] != header_crc:
                return SerialError("header CRC mismatch", bytes(buf[:2])), 2
            message, pos = _unstuff_until(buf, pos, ETX, length)
            crc_bytes, pos = _unstuff_count(buf, pos, 2)
        except _Broken as exc:
            if exc.control == SOH:
                return SerialError("truncated", bytes(buf[: exc.at])), exc.at
            if exc.control == -1:
                at = max(exc.at, 2)
                return SerialError("length mismatch", bytes(buf[:at])), at
            return (
                SerialError(f"unexpected DLE {exc.control:#04x}", bytes(buf[: exc.at + 2])),
                exc.at + 2,
            )
        raw = bytes(buf[:pos])
        if len(message) != length:
            return SerialError("length mismatch", raw), pos
        if _U16.unpack(crc_bytes)[0] != crc16(message, crc16(header_crc_bytes, header_crc)):
            return SerialError("packet CRC mismatch", raw), pos
        try:
            packet, used = decode_packet(message)
        except DecodeError as exc:
            return SerialError(f"undecodable message: {exc}", raw), pos
        if used != len(message):
            return SerialError("length mismatch", raw), pos
        return SerialFrame(packet, raw), pos
