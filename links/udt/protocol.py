"""The bulk image transfer protocol carried on a UDT stream. Pure logic: no networking or files.

UDT gives a reliable, congestion-controlled byte stream over UDP. On it, one connection
carries any number of file transfers, one after the other, in frames::

    +-------+---------+------+-------------+-------------------+
    | magic | version | type | length u32  | payload (length)  |
    | "EB"  |   u8    |  u8  | big-endian  |                   |
    +-------+---------+------+-------------+-------------------+

Theory of operation. The sender opens with a MANIFEST (JSON: transfer id, vehicle, name,
size, SHA-256, format, capture time, optional ATR metadata). The receiver answers ACCEPT
with the byte offset it already holds for that transfer id, or REFUSE with a reason code
and text. The sender then streams DATA frames from that offset up to the declared size;
the receiver verifies the hash and answers with a RECEIPT (ok, or failed with a reason).
If the connection drops, the sender reconnects and sends the same manifest: the answer
carries the new offset, so only the rest travels.

Lanes. UDT's congestion control reads random radio loss as congestion and settles far
below the link rate (about 2 Mbit/s of 10 at 2 % loss); independent connections each
settle there, so a file may be sent as ``segment = [i, n]`` manifests on ``n`` parallel
connections. A segment manifest describes the same file; offsets, DATA and ACCEPT are
relative to the segment (:meth:`Manifest.span`) and its RECEIPT only says "stored". The
sender then sends the plain manifest, which the receiver answers with ACCEPT(size), and
the RECEIPT of that one carries the SHA-256 verdict on the whole file.

Pull. The same exchange runs with the roles of the connection turned round when the
receiver fetches: it connects to a vehicle's image server and sends FETCH (JSON: file
name, optional segment, optional rate: the budget in bit/s, for a segment the budget of
all lanes of that fetch together); the server answers with the MANIFEST of that file and goes on as
the sender above, or with REFUSE (NOT_FOUND) when it has no such file. One connection may
carry any number of fetches, one after the other.

Trailers. UDT learns that a packet was lost when a later one arrives; the last packet
before a pause (a segment's last data, a manifest, an answer, a receipt) has none behind
it, and a loss of it waits for UDT's retransmission timer (at least 300 ms in libudt).
So a sender offers ``"trailers": true`` beside its first manifest's fields on a
connection; a receiver that knows them takes the manifest and closes the deal with its
ACCEPT or CHALLENGE. From then on each end follows every frame after which it waits for
the other (the last DATA of a transfer, MANIFEST, AUTH, ACCEPT, CHALLENGE, REFUSE,
RECEIPT, FETCH) with an empty TRAILER in a packet of its own, which the other end skips:
a lost packet before it is seen and sent again within a round trip. A receiver from
before trailers refuses the offer as an unknown field (BAD_MANIFEST); the sender then
sends the manifest again without it, and no TRAILER crosses that connection.

Either side may send ERROR before closing when the other broke a rule (garbage, a frame
out of place, data past the size).

Authentication. A receiver given per-vehicle pre-shared keys answers each MANIFEST with a
CHALLENGE (32 fresh random bytes) instead of deciding; the sender answers with AUTH, the
HMAC-SHA256 under its vehicle's key of ``AUTH_LABEL || challenge || manifest bytes``
(:func:`auth_tag`). Only a matching tag lets the manifest through; a vehicle without a
key, a wrong tag or no answer gets REFUSE(UNAUTHENTICATED). The challenge is new for every
manifest, so a recorded MANIFEST + AUTH replayed later (or on another connection) fails.
A receiver without keys never challenges, and a sender without a key cannot answer one.

Sender states (``SenderConnection``)::

    IDLE --send_manifest--> AWAIT_ANSWER --ACCEPT--> SENDING --last byte--> AWAIT_RECEIPT
      ^                           |                  (offset == size skips SENDING)   |
      +-------- REFUSE -----------+---------------------- RECEIPT --------------------+

Receiver states (``ReceiverConnection``)::

    AWAIT_MANIFEST --MANIFEST ok--> DECIDING --accept(offset)--> RECEIVING --last byte-->
      ^      |                         |                                  VERIFYING
      |      +--MANIFEST bad: REFUSE   +--refuse()--> AWAIT_MANIFEST          |
      +------------------------------------------------ send_receipt() ------+

Any broken rule moves a connection to CLOSED with a ``ProtocolErrorDetected`` event and
queues an ERROR frame for the peer. Frame sizes are bounded per type (``MAX_PAYLOAD``),
so a peer can never make us buffer more than 64 KiB of control data; DATA payloads are
passed on as they arrive and never buffered whole.
"""

from __future__ import annotations

import hmac
import json
import math
import random
import re
import secrets
import struct
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from enum import Enum, IntEnum
from typing import Any

try:  # OpenSSL's SHA-256 even where hashlib was imported without it (edge-vis run, to stay
    # small): six times Python's own on a large image, and hmac loads OpenSSL here anyway
    from _hashlib import openssl_sha256 as new_sha256
except ImportError:  # an interpreter without OpenSSL
    from hashlib import sha256 as new_sha256

MAGIC = b"EB"
VERSION = 1
HEADER = struct.Struct(">2sBBI")
MAX_FILE_SIZE = 1 << 40
"""Largest file a manifest may declare (1 TiB)."""
DATA_CHUNK = 1 << 20
"""Largest DATA payload, and the size senders use."""
MAX_LANES = 16
#: most segments a file is cut into; lanes take them one after another, so a lane that
#: runs faster takes more of them and no lane is left holding a long tail
MAX_SEGMENTS = 128
SEGMENT_ALIGN = 64 * 1024


class FrameType(IntEnum):
    """Frame types of protocol version 1."""

    MANIFEST = 1
    ACCEPT = 2
    REFUSE = 3
    DATA = 4
    RECEIPT = 5
    ERROR = 6
    CHALLENGE = 7
    AUTH = 8
    FETCH = 9
    TRAILER = 10


MAX_PAYLOAD: dict[FrameType, int] = {
    FrameType.MANIFEST: 16 * 1024,
    FrameType.ACCEPT: 8,
    FrameType.REFUSE: 4 * 1024,
    FrameType.DATA: DATA_CHUNK,
    FrameType.RECEIPT: 4 * 1024,
    FrameType.ERROR: 4 * 1024,
    FrameType.CHALLENGE: 32,
    FrameType.AUTH: 32,
    FrameType.FETCH: 4 * 1024,
    FrameType.TRAILER: 0,
}
MIN_PAYLOAD: dict[FrameType, int] = {
    FrameType.MANIFEST: 2,
    FrameType.ACCEPT: 8,
    FrameType.REFUSE: 2,
    FrameType.DATA: 1,
    FrameType.RECEIPT: 33,
    FrameType.ERROR: 2,
    FrameType.CHALLENGE: 32,
    FrameType.AUTH: 32,
    FrameType.FETCH: 2,
    FrameType.TRAILER: 0,
}
TRAILERS = "trailers"
"""The manifest's key offering trailers (see the module doc); not part of the manifest."""
#: domain separation of the authentication tag
AUTH_LABEL = b"edge-vis bulk manifest auth v1\x00"
#: shortest pre-shared key accepted (bytes)
MIN_KEY_BYTES = 16


class Reason(IntEnum):
    """Why a transfer was refused, failed, or a connection was closed; sent as u16."""

    BAD_FRAME = 1
    BAD_MANIFEST = 2
    BAD_NAME = 3
    QUOTA = 4
    SIZE_MISMATCH = 5
    HASH_MISMATCH = 6
    BUSY = 7
    UNEXPECTED_FRAME = 8
    STORAGE = 9
    TIMEOUT = 10
    SHUTDOWN = 11
    UNAUTHENTICATED = 12
    NOT_FOUND = 13
    UNKNOWN = 0xFFFF

    @classmethod
    def of(cls, value: int) -> Reason:
        try:
            return cls(value)
        except ValueError:
            return cls.UNKNOWN


# --------------------------------------------------------------------------- manifest


class ManifestError(ValueError):
    """A manifest field is missing or invalid; ``reason`` says which and why."""

    def __init__(self, reason: str, code: Reason = Reason.BAD_MANIFEST) -> None:
        super().__init__(reason)
        self.reason = reason
        self.code = code


_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")
_HEX64_RE = re.compile(r"^[0-9a-f]{64}$")
_FORMAT_RE = re.compile(r"^[a-z0-9][a-z0-9+.\-]{0,31}$")


def check_file_name(name: object) -> str:
    """Return ``name`` if it is a safe plain file name, else raise ``ManifestError(BAD_NAME)``.

    A name must stay inside whatever directory it is stored in: no path separators, no
    ``.``/``..``, no drive letters, no NUL or other control characters, at most 255 bytes.
    """
    if not isinstance(name, str):
        raise ManifestError("file name must be a string", Reason.BAD_NAME)
    if not name:
        raise ManifestError("file name is empty", Reason.BAD_NAME)
    if "\x00" in name:
        raise ManifestError("file name contains a NUL byte", Reason.BAD_NAME)
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise ManifestError("file name contains a control character", Reason.BAD_NAME)
    if name.startswith(("/", "\\")) or re.match(r"^[A-Za-z]:", name):
        raise ManifestError(f"file name {name!r} is an absolute path", Reason.BAD_NAME)
    if "/" in name or "\\" in name:
        raise ManifestError(
            f"file name {name!r} contains a path separator", Reason.BAD_NAME
        )
    if name in (".", ".."):
        raise ManifestError(f"file name {name!r} is not a file", Reason.BAD_NAME)
    if len(name.encode("utf-8")) > 255:
        raise ManifestError("file name is longer than 255 bytes", Reason.BAD_NAME)
    return name


@dataclass(frozen=True, slots=True)
class Position:
    """Where a target was seen: WGS-84 degrees, depth in metres below the surface."""

    latitude: float
    longitude: float
    depth: float | None = None


@dataclass(frozen=True, slots=True)
class AtrMetadata:
    """Automatic target recognition result attached to an image (all optional)."""

    target_class: str | None = None
    confidence: float | None = None
    position: Position | None = None


@dataclass(frozen=True, slots=True)
class Manifest:
    """What a sender announces before the data: enough to resume, verify and publish.

    ``capture_time`` is seconds since the Unix epoch (UTC). ``transfer_id`` names the
    transfer across reconnections; :func:`transfer_id_for` derives a stable one.
    """

    transfer_id: str
    vehicle_id: str
    name: str
    size: int
    sha256: str
    image_format: str
    capture_time: float
    atr: AtrMetadata | None = None
    segment: tuple[int, int] | None = None
    """``(index, count)`` when this manifest covers one lane's segment of the file."""

    def span(self) -> tuple[int, int]:
        """Byte range ``[start, end)`` of the file this manifest's data covers."""
        if self.segment is None:
            return 0, self.size
        return segment_bounds(self.size, *self.segment)

    @property
    def length(self) -> int:
        """Bytes of data this manifest's transfer carries (the whole size, or a segment)."""
        start, end = self.span()
        return end - start

    def whole(self) -> Manifest:
        """The same file without a segment."""
        return replace(self, segment=None)

    def to_json(self) -> bytes:
        data = asdict(self)
        if self.atr is None:
            del data["atr"]
        if self.segment is None:
            del data["segment"]
        else:
            data["segment"] = list(self.segment)
        return json.dumps(data, separators=(",", ":"), allow_nan=False).encode("utf-8")

    def to_dict(self) -> dict[str, Any]:
        return json.loads(self.to_json())

    @classmethod
    def from_json(cls, payload: bytes) -> Manifest:
        """Parse and validate; raise :class:`ManifestError` naming the bad field."""
        try:
            data = json.loads(payload.decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise ManifestError(f"manifest is not UTF-8 ({exc.reason})") from exc
        except ValueError as exc:
            raise ManifestError(f"manifest is not valid JSON ({exc})") from exc
        return cls.from_mapping(data)

    @classmethod
    def from_mapping(cls, data: object) -> Manifest:
        """Validate a decoded mapping; raise :class:`ManifestError` naming the bad field."""
        if not isinstance(data, dict):
            raise ManifestError("manifest must be a JSON object")
        known = {
            "transfer_id", "vehicle_id", "name", "size", "sha256", "image_format",
            "capture_time", "atr", "segment",
        }
        unknown = sorted(set(data) - known)
        if unknown:
            raise ManifestError(f"manifest has unknown field(s) {', '.join(unknown)}")
        for key in sorted(known - {"atr", "segment"}):
            if key not in data:
                raise ManifestError(f"manifest.{key} is missing")
        tid = data["transfer_id"]
        if not isinstance(tid, str) or not _ID_RE.match(tid):
            raise ManifestError("manifest.transfer_id must be 1-64 characters [A-Za-z0-9_.-]")
        vid = data["vehicle_id"]
        if not isinstance(vid, str) or not _ID_RE.match(vid):
            raise ManifestError("manifest.vehicle_id must be 1-64 characters [A-Za-z0-9_.-]")
        try:
            name = check_file_name(data["name"])
        except ManifestError as exc:
            raise ManifestError(f"manifest.name: {exc.reason}", Reason.BAD_NAME) from exc
        size = data["size"]
        if isinstance(size, bool) or not isinstance(size, int) or not 0 <= size <= MAX_FILE_SIZE:
            raise ManifestError(f"manifest.size must be an integer 0..{MAX_FILE_SIZE}")
        digest = data["sha256"]
        if not isinstance(digest, str) or not _HEX64_RE.match(digest):
            raise ManifestError("manifest.sha256 must be 64 lower-case hex digits")
        fmt = data["image_format"]
        if not isinstance(fmt, str) or not _FORMAT_RE.match(fmt):
            raise ManifestError("manifest.image_format must be a short lower-case name")
        ctime = _number(data["capture_time"], "manifest.capture_time")
        atr = _atr(data.get("atr"))
        segment = _segment(data.get("segment"))
        return cls(tid, vid, name, size, digest, fmt, ctime, atr, segment)


def _offered_manifest(payload: bytes) -> tuple[Manifest, bool]:
    """A MANIFEST payload's manifest, and whether it offers trailers."""
    try:
        data = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return Manifest.from_json(payload), False  # raises, saying what is wrong with it
    offered = isinstance(data, dict) and data.get(TRAILERS) is True
    if offered:
        del data[TRAILERS]
    return Manifest.from_mapping(data), offered


def _number(value: object, path: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ManifestError(f"{path} must be a finite number")
    if not lo <= value <= hi:
        raise ManifestError(f"{path} must be within {lo}..{hi}")
    return float(value)


def _segment(value: object) -> tuple[int, int] | None:
    if value is None:
        return None
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
            or not 1 <= value[1] <= MAX_SEGMENTS or not 0 <= value[0] < value[1]):
        raise ManifestError(
            f"manifest.segment must be [index, count] with count 1..{MAX_SEGMENTS}")
    return value[0], value[1]


def segment_bounds(size: int, index: int, count: int) -> tuple[int, int]:
    """``[start, end)`` of segment ``index`` of ``count`` (64 KiB-aligned, last one short)."""
    step = -(-size // count)
    step = -(-step // SEGMENT_ALIGN) * SEGMENT_ALIGN
    start = min(size, index * step)
    return start, min(size, start + step)


def _atr(value: object) -> AtrMetadata | None:
    if value is None:
        return None
    if not isinstance(value, dict):
        raise ManifestError("manifest.atr must be an object")
    extra = sorted(set(value) - {"target_class", "confidence", "position"})
    if extra:
        raise ManifestError(f"manifest.atr has unknown field(s) {', '.join(extra)}")
    cls_ = value.get("target_class")
    if cls_ is not None and (not isinstance(cls_, str) or len(cls_) > 64):
        raise ManifestError("manifest.atr.target_class must be a string of at most 64 chars")
    conf = value.get("confidence")
    if conf is not None:
        conf = _number(conf, "manifest.atr.confidence", 0.0, 1.0)
    pos = value.get("position")
    position = None
    if pos is not None:
        if not isinstance(pos, dict) or not {"latitude", "longitude"} <= set(pos):
            raise ManifestError("manifest.atr.position needs latitude and longitude")
        if set(pos) - {"latitude", "longitude", "depth"}:
            raise ManifestError("manifest.atr.position has unknown fields")
        depth = pos.get("depth")
        position = Position(
            _number(pos["latitude"], "manifest.atr.position.latitude", -90.0, 90.0),
            _number(pos["longitude"], "manifest.atr.position.longitude", -180.0, 180.0),
            None if depth is None else _number(depth, "manifest.atr.position.depth"),
        )
    return AtrMetadata(cls_, conf, position)


def auth_tag(key: bytes, challenge: bytes, manifest_bytes: bytes) -> bytes:
    """HMAC-SHA256 that proves the sender holds ``key`` for this manifest and challenge."""
    return hmac.new(key, AUTH_LABEL + challenge + manifest_bytes, new_sha256).digest()


def transfer_id_for(vehicle_id: str, name: str, sha256: str) -> str:
    """A transfer id stable across sender restarts, so a re-run resumes instead of restarting."""
    key = f"{vehicle_id}\x00{name}\x00{sha256}".encode()
    return new_sha256(key).hexdigest()[:32]


def fetch_payload(name: str, segment: tuple[int, int] | None = None,
                  rate_bps: int | None = None) -> bytes:
    """The FETCH payload asking for ``name`` (or one lane's ``segment`` of it), to be sent
    at most at ``rate_bps`` (the fetcher's share of the link budget; for a segment, the
    share of all lanes of the fetch together)."""
    data: dict[str, Any] = {"name": check_file_name(name)}
    if segment is not None:
        data["segment"] = list(_segment(list(segment)) or ())
    if rate_bps:
        data["rate"] = int(rate_bps)
    return json.dumps(data, separators=(",", ":")).encode("utf-8")


def parse_fetch(payload: bytes) -> tuple[str, tuple[int, int] | None, int | None]:
    """``(name, segment, rate_bps)`` of a FETCH payload; a malformed one is a BAD_FRAME."""
    try:
        data = json.loads(payload.decode("utf-8"))
        if not isinstance(data, dict) or set(data) - {"name", "segment", "rate"}:
            raise ValueError("expected an object with name, optional segment and rate")
        rate = data.get("rate")
        if rate is not None and (isinstance(rate, bool) or not isinstance(rate, int)
                                 or rate <= 0):
            raise ValueError("rate must be a positive integer (bit/s)")
        return check_file_name(data.get("name")), _segment(data.get("segment")), rate
    except (UnicodeDecodeError, ValueError) as exc:
        raise _Garbage(f"bad FETCH: {exc}") from exc


# --------------------------------------------------------------------------- events


@dataclass(frozen=True, slots=True)
class ManifestReceived:
    """Receiver: a valid manifest arrived; answer with ``accept`` or ``refuse``."""

    manifest: Manifest


@dataclass(frozen=True, slots=True)
class ManifestRejected:
    """Receiver: a manifest was invalid; a REFUSE has already been queued."""

    code: Reason
    reason: str


@dataclass(frozen=True, slots=True)
class DataReceived:
    """Receiver: ``data`` belongs at byte ``offset`` of the current transfer."""

    transfer_id: str
    offset: int
    data: bytes


@dataclass(frozen=True, slots=True)
class DataComplete:
    """Receiver: every declared byte has arrived; verify, then ``send_receipt``."""

    manifest: Manifest


@dataclass(frozen=True, slots=True)
class Accepted:
    """Sender: the receiver holds ``offset`` bytes already; send from there."""

    transfer_id: str
    offset: int


@dataclass(frozen=True, slots=True)
class Refused:
    """Sender: the receiver will not take this transfer."""

    transfer_id: str
    code: Reason
    reason: str


@dataclass(frozen=True, slots=True)
class ReceiptReceived:
    """Sender: the receiver's verdict on the whole file."""

    transfer_id: str
    ok: bool
    sha256: str
    reason: str


@dataclass(frozen=True, slots=True)
class PeerErrored:
    """The peer reported that we broke a rule and closed; the connection is finished."""

    code: Reason
    reason: str


@dataclass(frozen=True, slots=True)
class ProtocolErrorDetected:
    """The peer broke a rule; an ERROR frame is queued and the connection is finished."""

    code: Reason
    reason: str


@dataclass(frozen=True, slots=True)
class FetchRequested:
    """Image server: the peer asks for file ``name`` (one lane's ``segment`` of it, or all);
    answer with ``send_manifest`` (the normal sending flow follows) or ``refuse_fetch``."""

    name: str
    segment: tuple[int, int] | None
    rate_bps: int | None = None


@dataclass(frozen=True, slots=True)
class FetchRefused:
    """Fetcher: the image server will not serve the file asked for."""

    code: Reason
    reason: str


Event = (
    ManifestReceived | ManifestRejected | DataReceived | DataComplete | Accepted | Refused
    | ReceiptReceived | PeerErrored | ProtocolErrorDetected | FetchRequested | FetchRefused
)


class BulkProtocolError(Exception):
    """A local misuse of a connection (calling ``accept`` in the wrong state, ...)."""


# --------------------------------------------------------------------------- frames


def encode_frame(ftype: FrameType, payload: bytes) -> bytes:
    """One frame; raises ``BulkProtocolError`` if the payload is outside the type's bounds."""
    if not MIN_PAYLOAD[ftype] <= len(payload) <= MAX_PAYLOAD[ftype]:
        raise BulkProtocolError(f"{ftype.name} payload of {len(payload)} bytes out of bounds")
    return HEADER.pack(MAGIC, VERSION, ftype, len(payload)) + payload


def _coded(code: Reason, text: str) -> bytes:
    raw = text.encode("utf-8")[: MAX_PAYLOAD[FrameType.ERROR] - 2]
    return struct.pack(">H", code) + raw


class _FrameReader:
    """Splits the stream into frames; DATA payloads are passed on piecewise, unbuffered."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._consumed = 0  # stream offset of _buf[0]
        self._data_left = 0  # bytes of the current DATA payload still to come

    def feed(self, data: bytes) -> tuple[list[tuple[FrameType, bytes]], _Garbage | None]:
        """Complete frames (DATA possibly in pieces), then the error that stopped reading."""
        out: list[tuple[FrameType, bytes]] = []
        try:
            self._feed(data, out)
        except _Garbage as exc:
            return out, exc
        return out, None

    def _feed(self, data: bytes, out: list[tuple[FrameType, bytes]]) -> None:
        view = memoryview(data)
        while view:
            if self._data_left:
                take = view[: self._data_left]
                self._data_left -= len(take)
                self._consumed += len(take)
                out.append((FrameType.DATA, bytes(take)))
                view = view[len(take):]
                continue
            need = HEADER.size - len(self._buf)
            if need > 0:
                self._buf += view[:need]
                view = view[need:]
                if len(self._buf) < HEADER.size:
                    break
            magic, version, ftype_raw, length = HEADER.unpack_from(self._buf)
            at = self._consumed
            if magic != MAGIC:
                raise _Garbage(
                    f"bad frame magic 0x{magic.hex()} at stream byte {at} "
                    "(not an edge-vis bulk stream)"
                )
            if version != VERSION:
                raise _Garbage(
                    f"unsupported protocol version {version} at stream byte {at} "
                    f"(this end speaks {VERSION})"
                )
            try:
                ftype = FrameType(ftype_raw)
            except ValueError:
                raise _Garbage(f"unknown frame type {ftype_raw} at stream byte {at}") from None
            if not MIN_PAYLOAD[ftype] <= length <= MAX_PAYLOAD[ftype]:
                raise _Garbage(
                    f"{ftype.name} frame length {length} at stream byte {at} outside "
                    f"{MIN_PAYLOAD[ftype]}..{MAX_PAYLOAD[ftype]}"
                )
            if ftype is FrameType.DATA:
                self._consumed += HEADER.size
                self._buf.clear()
                self._data_left = length
                continue
            need = HEADER.size + length - len(self._buf)
            self._buf += view[:need]
            view = view[need:]
            if len(self._buf) < HEADER.size + length:
                break
            out.append((ftype, bytes(self._buf[HEADER.size:])))
            self._consumed += len(self._buf)
            self._buf.clear()


class _Garbage(Exception):
    def __init__(self, reason: str, code: Reason = Reason.BAD_FRAME) -> None:
        super().__init__(reason)
        self.reason = reason
        self.code = code


# --------------------------------------------------------------------------- connections


class State(Enum):
    IDLE = "idle"
    AWAIT_ANSWER = "await-answer"
    SENDING = "sending"
    AWAIT_RECEIPT = "await-receipt"
    AWAIT_MANIFEST = "await-manifest"
    DECIDING = "deciding"
    AWAIT_AUTH = "await-auth"
    RECEIVING = "receiving"
    VERIFYING = "verifying"
    CLOSED = "closed"


@dataclass
class _Base:
    idle_timeout: float = 30.0
    state: State = State.IDLE
    #: both ends agreed on trailers on this connection
    trailers: bool = False
    _reader: _FrameReader = field(default_factory=_FrameReader)
    _out: list[bytes] = field(default_factory=list)
    _last_activity: float | None = None
    _trailer_due: bool = False

    def data_to_send(self) -> bytes:
        """Bytes queued for the peer since the last call."""
        out = b"".join(self._out)
        self._out.clear()
        return out

    def trailer(self) -> bytes:
        """The TRAILER due after :meth:`data_to_send`'s bytes, or nothing: the caller
        sends it on its own (a packet of its own), right after them."""
        due, self._trailer_due = self._trailer_due, False
        return encode_frame(FrameType.TRAILER, b"") if due else b""

    def _turn(self) -> None:
        """This end now waits for the other: a trailer follows what it queued."""
        self._trailer_due = self.trailers

    def next_deadline(self) -> float | None:
        """When :meth:`handle_timer` must be called, or None when nothing is pending."""
        if self.state in (State.CLOSED, State.IDLE, State.AWAIT_MANIFEST):
            return None
        if self._last_activity is None:
            return None
        return self._last_activity + self.idle_timeout

    def touch(self, now: float) -> None:
        """The transport shows progress (e.g. its send buffer is draining): not idle."""
        self._last_activity = now

    def handle_timer(self, now: float) -> list[Event]:
        """Close with TIMEOUT when the peer has been silent past ``idle_timeout`` seconds."""
        deadline = self.next_deadline()
        if deadline is None or now < deadline:
            return []
        return [self._fail(Reason.TIMEOUT, f"peer silent for {self.idle_timeout:g} s")]

    def receive_data(self, data: bytes, now: float) -> list[Event]:
        """Feed bytes from the stream; return what they mean."""
        if self.state is State.CLOSED:
            return []
        self._last_activity = now
        events: list[Event] = []
        frames, garbage = self._reader.feed(data)
        try:
            for ftype, payload in frames:
                if ftype is FrameType.ERROR:
                    (code,) = struct.unpack_from(">H", payload)
                    self.state = State.CLOSED
                    events.append(PeerErrored(Reason.of(code), _text(payload[2:])))
                    return events
                if ftype is FrameType.TRAILER and self.trailers:
                    continue
                events.extend(self._frame(ftype, payload))
                if self.state is State.CLOSED:
                    return events
            if garbage is not None:
                raise garbage
        except _Garbage as exc:
            events.append(self._fail(exc.code, exc.reason))
        return events

    def close_with_error(self, code: Reason, reason: str) -> None:
        """Queue an ERROR frame and finish (e.g. on shutdown or a storage failure)."""
        if self.state is not State.CLOSED:
            self._fail(code, reason)

    def _fail(self, code: Reason, reason: str) -> ProtocolErrorDetected:
        self.state = State.CLOSED
        self._trailer_due = False
        self._out.append(encode_frame(FrameType.ERROR, _coded(code, reason)))
        return ProtocolErrorDetected(code, reason)

    def _frame(self, ftype: FrameType, payload: bytes) -> list[Event]:
        raise NotImplementedError

    def _unexpected(self, ftype: FrameType) -> _Garbage:
        return _Garbage(
            f"unexpected {ftype.name} frame in state {self.state.value}", Reason.UNEXPECTED_FRAME
        )


def _text(raw: bytes) -> str:
    return raw.decode("utf-8", errors="replace")


@dataclass
class ReceiverConnection(_Base):
    """The receiving end of one connection: validates, tracks offsets, asks for decisions.

    ``keys`` (vehicle id -> pre-shared key) turns authentication on: every manifest must
    be answered to a fresh challenge (see the module docstring). ``None``: off.
    """

    state: State = State.AWAIT_MANIFEST
    manifest: Manifest | None = None
    offset: int = 0
    keys: Mapping[str, bytes] | None = None
    nonce: Callable[[], bytes] = field(default=lambda: secrets.token_bytes(32))
    _challenge: bytes = b""
    _manifest_bytes: bytes = b""
    _fetching: bool = False
    _offered: bool = False

    def request(self, name: str, segment: tuple[int, int] | None = None,
                rate_bps: int | None = None) -> None:
        """Ask an image server for ``name`` (pull); its MANIFEST or a ``FetchRefused`` follows."""
        if self.state is not State.AWAIT_MANIFEST:
            raise BulkProtocolError(f"request() in state {self.state.value}")
        self._out.append(encode_frame(FrameType.FETCH, fetch_payload(name, segment, rate_bps)))
        self._fetching = True
        self._turn()

    def _frame(self, ftype: FrameType, payload: bytes) -> list[Event]:
        if ftype is FrameType.REFUSE and self.state is State.AWAIT_MANIFEST and self._fetching:
            (code,) = struct.unpack_from(">H", payload)
            self._fetching = False
            return [FetchRefused(Reason.of(code), _text(payload[2:]))]
        if ftype is FrameType.MANIFEST and self.state is State.AWAIT_MANIFEST:
            self._fetching = False
            try:
                manifest, self._offered = _offered_manifest(payload)
            except ManifestError as exc:
                self._out.append(encode_frame(FrameType.REFUSE, _coded(exc.code, exc.reason)))
                self._turn()
                return [ManifestRejected(exc.code, exc.reason)]
            if self.keys is not None:
                if manifest.vehicle_id not in self.keys:
                    return [self._unauthenticated(
                        f"no key for vehicle {manifest.vehicle_id!r}: not accepted here")]
                self.manifest = manifest
                self._manifest_bytes = payload
                self._challenge = self.nonce()
                self._out.append(encode_frame(FrameType.CHALLENGE, self._challenge))
                self.state = State.AWAIT_AUTH
                self.trailers = self.trailers or self._offered
                self._turn()
                return []
            self.manifest = manifest
            self.state = State.DECIDING
            return [ManifestReceived(manifest)]
        if ftype is FrameType.AUTH and self.state is State.AWAIT_AUTH:
            assert self.manifest is not None and self.keys is not None
            manifest, challenge = self.manifest, self._challenge
            self._challenge = b""  # one answer per challenge: never reusable
            expected = auth_tag(self.keys[manifest.vehicle_id], challenge, self._manifest_bytes)
            if not hmac.compare_digest(expected, payload):
                self.manifest = None
                return [self._unauthenticated(
                    f"authentication failed for vehicle {manifest.vehicle_id!r}: wrong key")]
            self.state = State.DECIDING
            return [ManifestReceived(manifest)]
        if ftype is FrameType.DATA and self.state is State.RECEIVING:
            assert self.manifest is not None
            end = self.offset + len(payload)
            if end > self.manifest.length:
                raise _Garbage(
                    f"data runs past the declared size: manifest says {self.manifest.length} "
                    f"bytes, received at least {end}",
                    Reason.SIZE_MISMATCH,
                )
            event = DataReceived(self.manifest.transfer_id, self.offset, payload)
            self.offset = end
            if end == self.manifest.length:
                self.state = State.VERIFYING
                return [event, DataComplete(self.manifest)]
            return [event]
        raise self._unexpected(ftype)

    def _unauthenticated(self, reason: str) -> ManifestRejected:
        self._out.append(encode_frame(FrameType.REFUSE, _coded(Reason.UNAUTHENTICATED, reason)))
        self.manifest = None
        self.state = State.AWAIT_MANIFEST
        self._turn()
        return ManifestRejected(Reason.UNAUTHENTICATED, reason)

    def accept(self, offset: int) -> list[Event]:
        """Tell the sender to go on from ``offset``; ``DataComplete`` if nothing is missing."""
        if self.state is not State.DECIDING or self.manifest is None:
            raise BulkProtocolError(f"accept() in state {self.state.value}")
        if not 0 <= offset <= self.manifest.length:
            raise BulkProtocolError(f"offset {offset} outside 0..{self.manifest.length}")
        self._out.append(encode_frame(FrameType.ACCEPT, struct.pack(">Q", offset)))
        self.trailers = self.trailers or self._offered
        self._turn()
        self.offset = offset
        if offset == self.manifest.length:
            self.state = State.VERIFYING
            return [DataComplete(self.manifest)]
        self.state = State.RECEIVING
        return []

    def refuse(self, code: Reason, reason: str) -> None:
        """Decline the announced transfer; the connection waits for another manifest."""
        if self.state is not State.DECIDING:
            raise BulkProtocolError(f"refuse() in state {self.state.value}")
        self._out.append(encode_frame(FrameType.REFUSE, _coded(code, reason)))
        self.manifest = None
        self.state = State.AWAIT_MANIFEST
        self._turn()

    def send_receipt(self, ok: bool, sha256: str, reason: str = "") -> None:
        """Report the verdict on the complete file and wait for the next manifest."""
        if self.state is not State.VERIFYING:
            raise BulkProtocolError(f"send_receipt() in state {self.state.value}")
        digest = bytes.fromhex(sha256) if sha256 else bytes(32)
        payload = bytes([0 if ok else 1]) + digest + reason.encode("utf-8")[:1024]
        self._out.append(encode_frame(FrameType.RECEIPT, payload))
        self._turn()
        self.manifest = None
        self.offset = 0
        self.state = State.AWAIT_MANIFEST


@dataclass
class SenderConnection(_Base):
    """The sending end of one connection: one transfer at a time, data only when accepted.

    ``keys`` (vehicle id -> pre-shared key) answer a receiver's challenge.
    """

    manifest: Manifest | None = None
    offset: int = 0
    keys: Mapping[str, bytes] | None = None
    #: the manifest went a second time, without the trailers' offer (a receiver from
    #: before them): its answer took two round trips
    resent: bool = False
    _plain: bool = False  # the receiver refused the trailers' offer: none on this connection
    _manifest_bytes: bytes = b""
    _answered: bool = False
    _offered: bool = False

    def send_manifest(self, manifest: Manifest, now: float) -> None:
        """Announce a transfer; the answer arrives as ``Accepted`` or ``Refused``."""
        if self.state is not State.IDLE:
            raise BulkProtocolError(f"send_manifest() in state {self.state.value}")
        self.manifest = manifest
        self._offered = not (self._plain or self.trailers)  # once a connection
        self.resent = False
        self._announce()
        self._answered = False
        self.state = State.AWAIT_ANSWER
        self._last_activity = now

    def _announce(self) -> None:
        assert self.manifest is not None
        data = json.dumps({**self.manifest.to_dict(), TRAILERS: True},
                          separators=(",", ":"), allow_nan=False).encode("utf-8") \
            if self._offered else self.manifest.to_json()
        self._manifest_bytes = data
        self._out.append(encode_frame(FrameType.MANIFEST, data))
        self._turn()

    def send_data(self, data: bytes, now: float) -> None:
        """Queue the next bytes of the file (at most ``DATA_CHUNK`` per call).

        Sending counts as activity: the idle clock measures silence *after* our last
        byte, since a slow link may take minutes to carry a large file.
        """
        self._last_activity = now
        if self.state is not State.SENDING or self.manifest is None:
            raise BulkProtocolError(f"send_data() in state {self.state.value}")
        if self.offset + len(data) > self.manifest.length:
            raise BulkProtocolError("data past the size declared in the manifest")
        self._out.append(encode_frame(FrameType.DATA, data))
        self.offset += len(data)
        if self.offset == self.manifest.length:
            self.state = State.AWAIT_RECEIPT
            self._turn()

    @property
    def remaining(self) -> int:
        return 0 if self.manifest is None else self.manifest.length - self.offset

    def refuse_fetch(self, code: Reason, reason: str) -> None:
        """Image server: decline a ``FetchRequested``; the connection waits for the next."""
        if self.state is not State.IDLE:
            raise BulkProtocolError(f"refuse_fetch() in state {self.state.value}")
        self._out.append(encode_frame(FrameType.REFUSE, _coded(code, reason)))
        self._turn()

    def _frame(self, ftype: FrameType, payload: bytes) -> list[Event]:
        assert ftype is not FrameType.ERROR
        if ftype is FrameType.FETCH and self.state is State.IDLE:
            return [FetchRequested(*parse_fetch(payload))]
        if self.manifest is None:
            raise self._unexpected(ftype)
        tid = self.manifest.transfer_id
        if ftype is FrameType.CHALLENGE and self.state is State.AWAIT_ANSWER \
                and not self._answered:
            key = (self.keys or {}).get(self.manifest.vehicle_id)
            if key is None:
                raise _Garbage(f"the receiver requires authentication and there is no key "
                               f"for vehicle {self.manifest.vehicle_id!r}",
                               Reason.UNAUTHENTICATED)
            self._answered = True
            self.trailers = self.trailers or self._offered
            self._out.append(encode_frame(FrameType.AUTH,
                                          auth_tag(key, payload, self._manifest_bytes)))
            self._turn()
            return []
        if ftype is FrameType.ACCEPT and self.state is State.AWAIT_ANSWER:
            (offset,) = struct.unpack(">Q", payload)
            self.trailers = self.trailers or self._offered
            if offset > self.manifest.length:
                raise _Garbage(
                    f"receiver offset {offset} beyond the data size {self.manifest.length}",
                    Reason.SIZE_MISMATCH,
                )
            self.offset = offset
            self.state = State.SENDING if offset < self.manifest.length else State.AWAIT_RECEIPT
            return [Accepted(tid, offset)]
        if ftype is FrameType.REFUSE and self.state is State.AWAIT_ANSWER:
            (code,) = struct.unpack_from(">H", payload)
            if code == Reason.BAD_MANIFEST and self._offered and not self.trailers:
                # a receiver from before trailers: the same manifest without the offer
                self._plain, self._offered = True, False
                self.resent = True
                self._announce()
                return []
            self.manifest = None
            self.state = State.IDLE
            return [Refused(tid, Reason.of(code), _text(payload[2:]))]
        if ftype is FrameType.RECEIPT and self.state in (State.AWAIT_RECEIPT, State.SENDING):
            # A receiver may fail a transfer early (e.g. its disk broke) while we still send.
            status, digest, reason = payload[0], payload[1:33].hex(), _text(payload[33:])
            self.manifest = None
            self.state = State.IDLE
            return [ReceiptReceived(tid, status == 0, digest, reason)]
        raise self._unexpected(ftype)


# --------------------------------------------------------------------------- backoff


@dataclass
class Backoff:
    """Exponential reconnection delays with jitter: ``initial * factor**n`` capped at ``maximum``.

    ``reset()`` after progress, so a link that drops now and then reconnects quickly while
    one that stays down is not hammered.
    """

    initial: float = 0.2
    factor: float = 2.0
    maximum: float = 10.0
    jitter: float = 0.1
    seed: int | None = None
    attempts: int = 0
    _rng: random.Random = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    def next_delay(self) -> float:
        base = min(self.maximum, self.initial * self.factor**self.attempts)
        self.attempts += 1
        return base * (1.0 + self._rng.uniform(-self.jitter, self.jitter))

    def reset(self) -> None:
        self.attempts = 0
