"""JAUS serial framing against the JAUS Toolset's own frames, and a deframer under abuse."""

from __future__ import annotations

import random
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import SerialDeframer, SerialError, SerialFrame, crc16, frame
from edge_vis.jaus.transport import AckNak, Packet

CAPTURES = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus" / "captures.md"
needs_captures = pytest.mark.skipif(
    not CAPTURES.is_file(), reason=f"reference captures not found at {CAPTURES}")


def serial_captures() -> list[bytes]:
    """The line bytes of every frame in the captures' "Serial" section."""
    text = CAPTURES.read_text()
    section = text[text.index("## Serial"):]
    return [bytes.fromhex(h) for h in re.findall(r"\| `(10010[0-9a-f]+)` \|", section)]


@needs_captures
def test_capture_file_has_both_frames() -> None:
    assert len(serial_captures()) == 2


@needs_captures
@pytest.mark.parametrize("index", [0, 1])
def test_toolset_frames_decode_and_reencode_byte_for_byte(index: int) -> None:
    raw = serial_captures()[index]
    (result,) = SerialDeframer().feed(raw)
    assert isinstance(result, SerialFrame)
    assert result.raw == raw
    assert frame(result.packet) == raw


@needs_captures
def test_capture_contents() -> None:
    query, report = serial_captures()
    (q,) = SerialDeframer().feed(query)
    assert isinstance(q, SerialFrame)
    assert q.packet.destination == JausAddress(126, 1, 199)
    assert q.packet.source == JausAddress(42, 1, 1)
    assert q.packet.message_code == 0x2B00 and q.packet.sequence == 5
    (r,) = SerialDeframer().feed(report)
    assert isinstance(r, SerialFrame)
    assert r.packet.message_code == 0x4B00
    assert b"SimulatedVehicle" in r.packet.payload  # its length byte 0x10 was stuffed
    assert r.packet.sequence == 1


def test_crc_check_value() -> None:
    assert crc16(b"123456789") == 0x6F91


def _crc_bitwise(data: bytes, crc: int) -> int:
    """CRC-16/MCRF4XX one bit at a time, as the standard defines it (reflected 0x1021)."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
    return crc


def test_crc_agrees_with_the_bitwise_definition_for_any_input_and_seed() -> None:
    rng = random.Random(24)
    for _ in range(500):
        data = rng.randbytes(rng.randrange(0, 80))
        seed = rng.randrange(0x10000)
        assert crc16(data, seed) == _crc_bitwise(data, seed)
        assert crc16(bytearray(data), seed) == crc16(memoryview(data), seed) == crc16(data, seed)


def packet(seq: int, payload: bytes = b"\x02\x20") -> Packet:
    return Packet(JausAddress(1, 1, 1), JausAddress(2, 1, 1), payload, sequence=seq)


def test_every_dle_is_stuffed_and_survives() -> None:
    p = packet(0x1010, b"\x10" * 20)  # DLEs in payload and sequence number
    raw = frame(p)
    (result,) = SerialDeframer().feed(raw)
    assert isinstance(result, SerialFrame) and result.packet == p
    assert raw.count(b"\x10\x10") >= 21


def test_byte_at_a_time() -> None:
    raw = b"".join(frame(packet(i)) for i in range(5))
    deframer = SerialDeframer()
    out = [r for i in range(len(raw)) for r in deframer.feed(raw[i:i + 1])]
    assert [r.packet.sequence for r in out if isinstance(r, SerialFrame)] == list(range(5))
    assert not [r for r in out if isinstance(r, SerialError)]


def test_noise_is_reported_and_frames_resync() -> None:
    raw = b"garbage\x10" + frame(packet(1)) + b"\x00\x10\x10\x03" + frame(packet(2))
    out = SerialDeframer().feed(raw)
    frames = [r.packet.sequence for r in out if isinstance(r, SerialFrame)]
    errors = [r for r in out if isinstance(r, SerialError)]
    assert frames == [1, 2]
    assert [e.reason for e in errors] == ["noise", "noise"]
    assert errors[0].data == b"garbage\x10"


def test_bad_packet_crc_is_reported_and_next_frame_kept() -> None:
    bad = bytearray(frame(packet(1)))
    bad[-1] ^= 0xFF
    out = SerialDeframer().feed(bytes(bad) + frame(packet(2)))
    assert isinstance(out[0], SerialError) and out[0].reason == "packet CRC mismatch"
    assert isinstance(out[1], SerialFrame) and out[1].packet.sequence == 2


def test_bad_header_crc_is_reported() -> None:
    bad = bytearray(frame(packet(1)))
    bad[bad.index(b"\x10\x02") + 2] ^= 0x01  # header CRC low byte
    out = SerialDeframer().feed(bytes(bad) + frame(packet(2)))
    assert any(isinstance(r, SerialError) and r.reason == "header CRC mismatch" for r in out)
    assert [r.packet.sequence for r in out if isinstance(r, SerialFrame)] == [2]


def test_truncated_frame_then_new_start() -> None:
    first = frame(packet(1))
    out = SerialDeframer().feed(first[:20] + frame(packet(2)))
    assert isinstance(out[0], SerialError) and out[0].reason == "truncated"
    assert out[0].data == first[:20]
    assert isinstance(out[1], SerialFrame) and out[1].packet.sequence == 2


def test_stale_partial_frame_times_out() -> None:
    deframer = SerialDeframer(timeout=0.5)
    raw = frame(packet(1))
    assert deframer.feed(raw[:10], now=10.0) == []
    assert deframer.feed(b"", now=10.4) == []
    (err,) = deframer.feed(b"", now=10.6)
    assert err == SerialError("timeout", raw[:10])
    assert deframer.buffered == 0
    (ok,) = deframer.feed(frame(packet(2)), now=10.7)
    assert isinstance(ok, SerialFrame)


def test_buffer_is_bounded_when_no_end_arrives() -> None:
    deframer = SerialDeframer(max_frame=200)
    head = frame(packet(1, b"\x00" * 150))[:-6]  # drop DLE ETX and the CRC
    out = deframer.feed(head + b"\x00" * 500)
    assert any(isinstance(r, SerialError) for r in out)
    assert deframer.buffered <= 200


def test_ack_frame_round_trip() -> None:
    ack = Packet(JausAddress(1, 1, 1), JausAddress(2, 1, 1), b"", sequence=7,
                 ack_nak=AckNak.ACK)
    (out,) = SerialDeframer().feed(frame(ack))
    assert isinstance(out, SerialFrame) and out.packet == ack


def test_fuzz_every_valid_frame_survives_and_every_byte_is_accounted() -> None:
    rng = random.Random(5669)
    deframer = SerialDeframer()
    sent = []
    stream = bytearray()
    for seq in range(300):
        choice = rng.random()
        if choice < 0.3:  # random noise, with DLE-heavy bytes now and then
            stream += bytes(rng.choice((0x10, 0x01, 0x02, 0x03, rng.randrange(256)))
                            for _ in range(rng.randrange(1, 40)))
        elif choice < 0.4:  # a corrupted frame
            bad = bytearray(frame(packet(seq, rng.randbytes(rng.randrange(0, 60)))))
            bad[rng.randrange(len(bad))] ^= 1 << rng.randrange(8)
            stream += bad
        p = packet(seq, rng.randbytes(rng.randrange(0, 80)))
        sent.append(p)
        stream += frame(p)
    results = []
    pos = 0
    while pos < len(stream):
        step = rng.randrange(1, 64)
        results += deframer.feed(bytes(stream[pos:pos + step]))
        pos += step
    got = [r.packet for r in results if isinstance(r, SerialFrame)]
    # every valid frame arrives, in order; a corrupted one is never mistaken for valid
    # unless the bit flip happened to leave it valid (then it equals what was framed)
    assert [p for p in got if p in sent] == sent
    accounted = sum(len(r.raw if isinstance(r, SerialFrame) else r.data) for r in results)
    assert accounted + deframer.buffered == len(stream)


@pytest.mark.parametrize(
    "noise", [b"\x10\x01\x10", b"\x10\x01\x02\x10", b"\x10\x01\x02\x30\x00\x10"]
)
def test_false_start_in_noise_does_not_hold_back_a_real_frame(noise: bytes) -> None:
    # the stray DLE pairs with the real frame's DLE SOH; the frame must still come out now
    out = SerialDeframer().feed(noise + frame(packet(9)))
    assert [r.packet.sequence for r in out if isinstance(r, SerialFrame)] == [9]


@given(
    payload=st.binary(max_size=300),
    sequence=st.integers(0, 0xFFFF),
    flags=st.integers(0, 0xFF),
    ids=st.tuples(st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFFFFFF)),
    cuts=st.lists(st.integers(1, 50), max_size=20),
)
@settings(max_examples=200, deadline=None)
def test_any_packet_round_trips_in_any_chunking(
    payload: bytes, sequence: int, flags: int, ids: tuple[int, int], cuts: list[int]
) -> None:
    p = Packet(JausAddress.from_id(ids[0]), JausAddress.from_id(ids[1]), payload,
               sequence=sequence, priority=flags & 3, broadcast=(flags >> 2) & 3,
               ack_nak=(flags >> 4) & 3, data_flags=(flags >> 6) & 3)
    raw = frame(p)
    deframer = SerialDeframer()
    out = []
    pos = 0
    for cut in [*cuts, len(raw)]:
        out += deframer.feed(raw[pos:pos + cut])
        pos += cut
    assert out == [SerialFrame(p, raw)]
