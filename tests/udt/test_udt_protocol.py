"""The sans-I/O bulk transfer protocol: frames, manifests, state machines, resume, garbage."""

from __future__ import annotations

import hashlib
import itertools
import json
import struct
from dataclasses import replace

import pytest

from links.udt.protocol import (
    HEADER,
    MAGIC,
    Accepted,
    AtrMetadata,
    Backoff,
    BulkProtocolError,
    DataComplete,
    DataReceived,
    FrameType,
    Manifest,
    ManifestError,
    ManifestReceived,
    ManifestRejected,
    PeerErrored,
    Position,
    ProtocolErrorDetected,
    Reason,
    ReceiptReceived,
    ReceiverConnection,
    Refused,
    SenderConnection,
    State,
    check_file_name,
    encode_frame,
    transfer_id_for,
)

CONTENT = bytes(range(256)) * 40  # 10 240 bytes


def make_manifest(content: bytes = CONTENT, name: str = "sonar_0001.png", **kw: object) -> Manifest:
    sha = hashlib.sha256(content).hexdigest()
    fields = {
        "transfer_id": transfer_id_for("uuv1", name, sha), "vehicle_id": "uuv1", "name": name,
        "size": len(content), "sha256": sha, "image_format": "png",
        "capture_time": 1_700_000_000.25,
        "atr": AtrMetadata("mine-like", 0.87, Position(36.5, -121.9, 42.0)),
    }
    fields.update(kw)
    return Manifest(**fields)  # type: ignore[arg-type]


def pump(a: SenderConnection | ReceiverConnection, b: SenderConnection | ReceiverConnection,
         now: float = 0.0, piece: int | None = None) -> list[object]:
    """Move a's queued bytes into b (optionally in small pieces); return b's events."""
    data = a.data_to_send()
    if piece is None:
        return b.receive_data(data, now)
    events: list[object] = []
    for i in range(0, len(data), piece):
        events += b.receive_data(data[i:i + piece], now)
    return events


def run_transfer(sender: SenderConnection, receiver: ReceiverConnection, content: bytes,
                 held: bytes, chunk: int = 1000, piece: int | None = None
                 ) -> tuple[bytearray, list[object]]:
    """Drive one transfer where the receiver already holds ``held``; return what it stored."""
    stored = bytearray(held)
    m = make_manifest(content)
    sender.send_manifest(m, 0.0)
    events = pump(sender, receiver, piece=piece)
    assert events == [ManifestReceived(m)]
    receiver.accept(len(held))
    (accepted,) = pump(receiver, sender)
    assert accepted == Accepted(m.transfer_id, len(held))
    trail: list[object] = []
    pos = accepted.offset
    while sender.state is State.SENDING:
        sender.send_data(content[pos:pos + chunk], 0.0)
        pos += len(content[pos:pos + chunk])
        for ev in pump(sender, receiver, piece=piece):
            if isinstance(ev, DataReceived):
                assert ev.offset == len(stored)
                stored += ev.data
            else:
                trail.append(ev)
    return stored, trail


def test_full_transfer_then_receipt_and_next_manifest():
    s, r = SenderConnection(), ReceiverConnection()
    stored, trail = run_transfer(s, r, CONTENT, b"", piece=7)
    assert bytes(stored) == CONTENT
    assert trail == [DataComplete(make_manifest())]
    r.send_receipt(True, hashlib.sha256(stored).hexdigest())
    (receipt,) = pump(r, s)
    assert isinstance(receipt, ReceiptReceived) and receipt.ok
    assert receipt.sha256 == make_manifest().sha256
    assert s.state is State.IDLE and r.state is State.AWAIT_MANIFEST
    # The same connection carries the next file.
    s.send_manifest(make_manifest(b"second", name="b.png"), 1.0)
    assert isinstance(pump(s, r)[0], ManifestReceived)


def test_resume_sends_only_the_rest():
    s, r = SenderConnection(), ReceiverConnection()
    held = CONTENT[:6000]
    stored, trail = run_transfer(s, r, CONTENT, held)
    assert bytes(stored) == CONTENT
    assert s.offset == len(CONTENT)
    assert isinstance(trail[-1], DataComplete)


def test_accept_at_full_size_completes_without_data():
    s, r = SenderConnection(), ReceiverConnection()
    m = make_manifest()
    s.send_manifest(m, 0.0)
    pump(s, r)
    assert r.accept(m.size) == [DataComplete(m)]
    assert pump(r, s) == [Accepted(m.transfer_id, m.size)]
    assert s.state is State.AWAIT_RECEIPT


def test_refusal_reaches_sender_with_code_and_reason():
    s, r = SenderConnection(), ReceiverConnection()
    s.send_manifest(make_manifest(), 0.0)
    pump(s, r)
    r.refuse(Reason.QUOTA, "spool quota full: needs 10 KiB")
    (ev,) = pump(r, s)
    tid = make_manifest().transfer_id
    assert ev == Refused(tid, Reason.QUOTA, "spool quota full: needs 10 KiB")
    assert s.state is State.IDLE and r.state is State.AWAIT_MANIFEST


def test_manifest_round_trips_through_json():
    m = make_manifest()
    assert Manifest.from_json(m.to_json()) == m
    bare = make_manifest(atr=None)
    assert "atr" not in json.loads(bare.to_json())
    assert Manifest.from_json(bare.to_json()) == bare


@pytest.mark.parametrize(
    ("name", "reason"),
    [
        ("../x", "path separator"),
        ("/etc/passwd", "absolute path"),
        ("\\\\server\\share", "absolute path"),
        ("C:evil.png", "absolute path"),
        ("a\x00b.png", "NUL"),
        ("..", "not a file"),
        (".", "not a file"),
        ("", "empty"),
        ("line\nbreak", "control character"),
        ("x" * 256, "255 bytes"),
        ("sub/dir.png", "path separator"),
    ],
)
def test_file_names_that_could_escape_are_refused(name: str, reason: str):
    with pytest.raises(ManifestError, match=reason) as info:
        check_file_name(name)
    assert info.value.code is Reason.BAD_NAME
    # And over the wire: a REFUSE with BAD_NAME, connection still usable.
    s, r = SenderConnection(), ReceiverConnection()
    raw = json.loads(make_manifest().to_json())
    raw["name"] = name
    s._out.append(encode_frame(FrameType.MANIFEST, json.dumps(raw).encode()))
    (ev,) = pump(s, r)
    assert isinstance(ev, ManifestRejected) and ev.code is Reason.BAD_NAME
    assert reason in ev.reason
    assert r.state is State.AWAIT_MANIFEST
    frame = r.data_to_send()
    assert frame[3] == FrameType.REFUSE


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.pop("sha256"), "manifest.sha256 is missing"),
        (lambda d: d.update(sha256="ABC"), "64 lower-case hex"),
        (lambda d: d.update(size=-1), "manifest.size"),
        (lambda d: d.update(size=True), "manifest.size"),
        (lambda d: d.update(size=2**41), "manifest.size"),
        (lambda d: d.update(extra=1), "unknown field(s) extra"),
        (lambda d: d.update(vehicle_id="../v"), "manifest.vehicle_id"),
        (lambda d: d.update(transfer_id=""), "manifest.transfer_id"),
        (lambda d: d.update(capture_time="yesterday"), "manifest.capture_time"),
        (lambda d: d["atr"].update(confidence=1.5), "manifest.atr.confidence"),
        (lambda d: d["atr"]["position"].update(latitude=91), "latitude"),
        (lambda d: d.update(image_format="PNG image"), "image_format"),
    ],
)
def test_bad_manifest_fields_are_named(mutate, message):
    raw = json.loads(make_manifest().to_json())
    mutate(raw)
    with pytest.raises(ManifestError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Manifest.from_mapping(raw)


def test_manifest_that_is_not_json():
    r = ReceiverConnection()
    (ev,) = r.receive_data(encode_frame(FrameType.MANIFEST, b"{not json"), 0.0)
    assert isinstance(ev, ManifestRejected) and ev.code is Reason.BAD_MANIFEST
    assert "not valid JSON" in ev.reason


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"GET / HTTP/1.1\r\n\r\n", "bad frame magic"),
        (HEADER.pack(MAGIC, 9, 1, 10) + bytes(10), "unsupported protocol version 9"),
        (HEADER.pack(MAGIC, 1, 77, 0), "unknown frame type 77"),
        (HEADER.pack(MAGIC, 1, FrameType.MANIFEST, 10_000_000), "MANIFEST frame length 10000000"),
        (HEADER.pack(MAGIC, 1, FrameType.DATA, 5) + b"hello", "unexpected DATA frame"),
        (encode_frame(FrameType.ACCEPT, bytes(8)), "unexpected ACCEPT frame"),
    ],
)
def test_garbage_is_a_protocol_error_with_a_specific_reason(data: bytes, reason: str):
    r = ReceiverConnection()
    events = r.receive_data(data, 0.0)
    assert isinstance(events[-1], ProtocolErrorDetected)
    assert reason in events[-1].reason
    assert r.state is State.CLOSED
    reply = r.data_to_send()
    assert reply[:2] == MAGIC and reply[3] == FrameType.ERROR
    assert reason in reply[HEADER.size + 2:].decode()
    assert r.receive_data(b"more", 1.0) == []  # finished: ignores the rest


def test_data_past_the_declared_size_is_refused():
    s, r = SenderConnection(), ReceiverConnection()
    m = make_manifest(b"0123456789")
    s.send_manifest(m, 0.0)
    pump(s, r)
    r.accept(0)
    pump(r, s)
    # A broken sender: 16 bytes for a 10-byte manifest.
    events = r.receive_data(encode_frame(FrameType.DATA, b"x" * 16), 0.0)
    assert isinstance(events[-1], ProtocolErrorDetected)
    assert events[-1].code is Reason.SIZE_MISMATCH
    assert "manifest says 10 bytes" in events[-1].reason
    # Our own sender refuses to do that.
    with pytest.raises(BulkProtocolError):
        s.send_data(b"x" * 16, 0.0)


def test_frames_before_garbage_in_the_same_read_are_kept():
    s, r = SenderConnection(), ReceiverConnection()
    m = make_manifest(b"abcdef")
    s.send_manifest(m, 0.0)
    pump(s, r)
    r.accept(0)
    events = r.receive_data(encode_frame(FrameType.DATA, b"abc") + b"JUNKJUNKJUNK", 0.0)
    assert events[0] == DataReceived(m.transfer_id, 0, b"abc")
    assert isinstance(events[1], ProtocolErrorDetected)


def test_peer_error_frame_ends_the_connection():
    s = SenderConnection()
    s.send_manifest(make_manifest(), 0.0)
    payload = struct.pack(">H", Reason.SHUTDOWN) + b"receiver shutting down"
    (ev,) = s.receive_data(encode_frame(FrameType.ERROR, payload), 1.0)
    assert ev == PeerErrored(Reason.SHUTDOWN, "receiver shutting down")
    assert s.state is State.CLOSED


def test_idle_timeout_uses_the_given_clock():
    r = ReceiverConnection(idle_timeout=5.0)
    s = SenderConnection()
    s.send_manifest(make_manifest(), 100.0)
    r.receive_data(s.data_to_send(), 100.0)
    r.accept(0)
    assert r.next_deadline() == 105.0
    assert r.handle_timer(104.9) == []
    (ev,) = r.handle_timer(105.0)
    assert isinstance(ev, ProtocolErrorDetected) and ev.code is Reason.TIMEOUT


def test_local_misuse_raises():
    r = ReceiverConnection()
    with pytest.raises(BulkProtocolError):
        r.accept(0)
    s = SenderConnection()
    with pytest.raises(BulkProtocolError):
        s.send_data(b"x", 0.0)


def test_transfer_id_is_stable_and_distinct():
    a = transfer_id_for("uuv1", "a.png", "0" * 64)
    assert a == transfer_id_for("uuv1", "a.png", "0" * 64)
    assert a != transfer_id_for("uuv2", "a.png", "0" * 64)
    assert a != transfer_id_for("uuv1", "a.png", "1" * 64)


def test_backoff_grows_caps_and_resets():
    b = Backoff(initial=0.1, factor=2.0, maximum=1.0, jitter=0.0)
    assert [round(b.next_delay(), 3) for _ in range(6)] == [0.1, 0.2, 0.4, 0.8, 1.0, 1.0]
    b.reset()
    assert b.next_delay() == pytest.approx(0.1)
    jittery = Backoff(initial=1.0, jitter=0.1, seed=4)
    assert 0.9 <= jittery.next_delay() <= 1.1


def test_segment_manifests_cover_the_file_exactly_once():
    from links.udt.protocol import segment_bounds

    for size in (0, 1, 65_535, 65_536, 1_000_003, 20 << 20):
        for count in (1, 2, 3, 4, 7, 16):
            spans = [segment_bounds(size, i, count) for i in range(count)]
            assert spans[0][0] == 0 and spans[-1][1] == size
            assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))


def test_segment_transfer_is_relative_to_its_span():
    content = bytes(range(256)) * 1024  # 262 144 bytes: 4 segments of 64 KiB
    m = make_manifest(content)
    lane = Manifest.from_json(replace(m, segment=(2, 4)).to_json())
    assert lane.segment == (2, 4) and lane.span() == (131_072, 196_608)
    assert lane.whole() == m
    s, r = SenderConnection(), ReceiverConnection()
    s.send_manifest(lane, 0.0)
    pump(s, r)
    r.accept(0)
    pump(r, s)
    s.send_data(content[131_072:196_608], 0.0)
    events = pump(s, r)
    assert events[-1] == DataComplete(lane)
    assert sum(len(e.data) for e in events if isinstance(e, DataReceived)) == 65_536


@pytest.mark.parametrize("segment", [[4, 4], [0, 0], [0, 129], [-1, 2], [0], "0/4", [True, 2]])
def test_bad_segment_is_refused(segment):
    raw = json.loads(make_manifest().to_json())
    raw["segment"] = segment
    with pytest.raises(ManifestError, match=r"manifest\.segment"):
        Manifest.from_mapping(raw)



# --------------------------------------------------------------------------- trailers


def sends(conn: SenderConnection | ReceiverConnection) -> list[list[FrameType]]:
    """The frame types of what ``conn`` sends now, one list per send: what it queued,
    then its trailer on its own."""
    out = []
    for data in (conn.data_to_send(), conn.trailer()):
        types, at = [], 0
        while at < len(data):
            _magic, _version, ftype, length = HEADER.unpack_from(data, at)
            types.append(FrameType(ftype))
            at += HEADER.size + length
        if types:
            out.append(types)
    return out


def deliver(a: SenderConnection | ReceiverConnection,
            b: SenderConnection | ReceiverConnection) -> list[object]:
    """Move what a sends, trailer included, into b; return b's events."""
    return b.receive_data(a.data_to_send() + a.trailer(), 0.0)


def offered(data: bytes) -> dict[str, object]:
    """The JSON of the MANIFEST frame ``data`` starts with."""
    _magic, _version, ftype, length = HEADER.unpack_from(data)
    assert ftype == FrameType.MANIFEST
    return dict(json.loads(data[HEADER.size:HEADER.size + length]))


def refuse(code: Reason, text: str) -> bytes:
    return encode_frame(FrameType.REFUSE, struct.pack(">H", code) + text.encode())


TRAILER = encode_frame(FrameType.TRAILER, b"")
RECEIPT_OK = encode_frame(FrameType.RECEIPT, bytes(1) + bytes(32))


def test_the_first_manifest_offers_trailers_beside_its_fields_and_no_trailer_follows_it():
    sender = SenderConnection()
    sender.send_manifest(make_manifest(), 0.0)
    data = sender.data_to_send()
    assert offered(data)["trailers"] is True
    assert sender.trailer() == b""  # an end from before trailers would choke on one
    receiver = ReceiverConnection()
    assert receiver.receive_data(data, 0.0) == [ManifestReceived(make_manifest())]


def test_ends_that_agreed_follow_each_turn_with_a_trailer_sent_on_its_own():
    sender, receiver = SenderConnection(), ReceiverConnection()
    m = make_manifest()
    sender.send_manifest(m, 0.0)
    deliver(sender, receiver)
    receiver.accept(0)
    assert sends(receiver) == [[FrameType.ACCEPT], [FrameType.TRAILER]]
    assert sender.receive_data(encode_frame(FrameType.ACCEPT, bytes(8)) + TRAILER, 0.0) == [
        Accepted(m.transfer_id, 0)]
    assert sender.trailers and receiver.trailers
    sender.send_data(CONTENT[:4000], 0.0)
    first = sender.data_to_send()
    assert sender.trailer() == b""  # more follows at once: no trailer
    receiver.receive_data(first, 0.0)
    sender.send_data(CONTENT[4000:], 0.0)
    data, trailer = sender.data_to_send(), sender.trailer()
    assert trailer == TRAILER
    events = receiver.receive_data(data + trailer, 0.0)  # skipped, after the data
    assert events[-1] == DataComplete(m) and receiver.state is State.VERIFYING
    receiver.send_receipt(True, m.sha256)
    assert sends(receiver) == [[FrameType.RECEIPT], [FrameType.TRAILER]]
    assert isinstance(sender.receive_data(RECEIPT_OK + TRAILER, 0.0)[0], ReceiptReceived)
    sender.send_manifest(make_manifest(name="sonar_0002.png"), 0.0)
    assert sends(sender) == [[FrameType.MANIFEST], [FrameType.TRAILER]]
    assert receiver.receive_data(TRAILER, 0.0) == []  # between transfers too


def test_a_receiver_from_before_trailers_gets_the_manifest_again_without_the_offer():
    """That receiver refuses any field it does not know (hand-written frames here)."""
    sender, m = SenderConnection(), make_manifest()
    sender.send_manifest(m, 0.0)
    assert "trailers" in offered(sender.data_to_send())
    assert sender.receive_data(refuse(Reason.BAD_MANIFEST,
                                      "manifest has unknown field(s) trailers"), 0.0) == []
    again = sender.data_to_send()
    assert again == encode_frame(FrameType.MANIFEST, m.to_json()) and sender.resent
    assert sender.trailer() == b""
    assert sender.receive_data(encode_frame(FrameType.ACCEPT, bytes(8)), 0.0) == [
        Accepted(m.transfer_id, 0)]
    sender.send_data(CONTENT, 0.0)
    assert sends(sender) == [[FrameType.DATA]]  # never a trailer to that receiver
    sender.receive_data(RECEIPT_OK, 0.0)
    m2 = make_manifest(name="sonar_0002.png")
    sender.send_manifest(m2, 0.0)  # no offer again on that connection
    assert sender.data_to_send() == encode_frame(FrameType.MANIFEST, m2.to_json())
    assert sender.trailer() == b"" and not sender.resent
    # a manifest refused as bad without the offer is refused: no second try
    assert sender.receive_data(refuse(Reason.BAD_MANIFEST, "no"), 0.0) == [
        Refused(m2.transfer_id, Reason.BAD_MANIFEST, "no")]


def test_a_sender_from_before_trailers_never_gets_one_and_may_not_send_one():
    receiver, m = ReceiverConnection(), make_manifest()
    assert receiver.receive_data(encode_frame(FrameType.MANIFEST, m.to_json()), 0.0) == [
        ManifestReceived(m)]
    receiver.accept(0)
    assert sends(receiver) == [[FrameType.ACCEPT]]
    receiver.receive_data(encode_frame(FrameType.DATA, CONTENT), 0.0)
    receiver.send_receipt(True, m.sha256)
    assert sends(receiver) == [[FrameType.RECEIPT]]
    (event,) = receiver.receive_data(TRAILER, 0.0)  # nothing agreed: as strict as before
    assert isinstance(event, ProtocolErrorDetected)
    assert event.code is Reason.UNEXPECTED_FRAME


def test_a_challenge_agrees_on_trailers_and_the_answer_is_followed_by_one():
    keys = {"uuv1": b"k" * 32}
    sender = SenderConnection(keys=keys)
    receiver = ReceiverConnection(keys=keys, nonce=lambda: b"n" * 32)
    m = make_manifest()
    sender.send_manifest(m, 0.0)
    assert deliver(sender, receiver) == []
    assert sends(receiver) == [[FrameType.CHALLENGE], [FrameType.TRAILER]]
    sender.receive_data(encode_frame(FrameType.CHALLENGE, b"n" * 32) + TRAILER, 0.0)
    auth = sender.data_to_send()
    assert sender.trailer() == TRAILER
    assert receiver.receive_data(auth + TRAILER, 0.0) == [ManifestReceived(m)]


def test_a_fetcher_and_an_image_server_agree_on_the_first_fetch_of_a_connection():
    fetcher, server, m = ReceiverConnection(), SenderConnection(), make_manifest()
    fetcher.request(m.name)
    assert sends(fetcher) == [[FrameType.FETCH]]
    server.receive_data(encode_frame(FrameType.FETCH, json.dumps({"name": m.name}).encode()),
                        0.0)
    server.send_manifest(m, 0.0)
    assert deliver(server, fetcher) == [ManifestReceived(m)]
    fetcher.accept(0)
    deliver(fetcher, server)
    server.send_data(CONTENT, 0.0)
    deliver(server, fetcher)
    fetcher.send_receipt(True, m.sha256)
    deliver(fetcher, server)  # the trailer behind the receipt finds the server idle
    fetcher.request("sonar_0002.png")
    assert sends(fetcher) == [[FrameType.FETCH], [FrameType.TRAILER]]
    server.refuse_fetch(Reason.NOT_FOUND, "no such file")
    assert sends(server) == [[FrameType.REFUSE], [FrameType.TRAILER]]
