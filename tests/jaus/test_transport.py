"""The AS5669A general transport header and JUDP datagrams, against hand-worked bytes."""

from __future__ import annotations

import random

import pytest

from edge_vis.errors import DecodeError, UnsupportedError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.transport import (
    AckNak,
    Broadcast,
    DataFlags,
    Packet,
    Priority,
    decode_packet,
    encode_packet,
    pack_datagram,
    unpack_datagram,
)

OCU = JausAddress(42, 1, 1)
ROBOT = JausAddress(126, 1, 199)


def test_header_only_ack_datagram() -> None:
    # The JAUS Toolset's ACK: data size 14, flags 0x31 (priority 1 + ACK), no payload,
    # echoing sequence number 14 (worked out from the AS5669A header layout).
    data = bytes.fromhex("02" "00" "0e00" "31" "01012a00" "c7017e00" "0e00")
    (packet,) = unpack_datagram(data)
    assert packet == Packet(
        destination=OCU, source=ROBOT, payload=b"", sequence=14,
        priority=Priority.STANDARD, ack_nak=AckNak.ACK,
    )
    assert packet.message_code is None
    assert packet.data_size == 14
    assert pack_datagram([packet]) == data


def test_flags_byte_bit_positions() -> None:
    packet = Packet(BROADCAST, OCU, b"\x00\x2b\x02", priority=Priority.SAFETY_CRITICAL,
                    broadcast=Broadcast.GLOBAL, ack_nak=AckNak.REQUEST,
                    data_flags=DataFlags.LAST)
    assert packet.flags == 0b11_01_10_11
    encoded = encode_packet(packet)
    assert encoded[3] == 0xDB
    assert encoded[4:8] == b"\xff\xff\xff\xff"
    again, end = decode_packet(encoded)
    assert again == packet and end == len(encoded)


def test_packed_datagram_of_two_messages() -> None:
    # QueryIdentification(2) then QueryStatus, one version byte, each with its own size.
    data = bytes.fromhex(
        "02"
        "00" "1100" "01" "c7017e00" "01012a00" "002b" "02" "0500"
        "00" "1000" "01" "c7017e00" "01012a00" "0220" "0600"
    )
    first, second = unpack_datagram(data)
    assert (first.message_code, first.payload, first.sequence) == (0x2B00, b"\x00\x2b\x02", 5)
    assert (second.message_code, second.payload, second.sequence) == (0x2002, b"\x02\x20", 6)
    assert first.destination == ROBOT and first.source == OCU
    assert pack_datagram([first, second]) == data


def test_fragment_in_the_middle_has_no_message_code() -> None:
    packet = Packet(ROBOT, OCU, b"\x01\x02\x03", data_flags=DataFlags.MIDDLE)
    assert packet.message_code is None


@pytest.mark.parametrize(
    ("hexdata", "error", "text"),
    [
        ("", DecodeError, "empty datagram"),
        ("01000e0031", UnsupportedError, "version 1"),
        ("4a415553", UnsupportedError, "JAUS01.0"),
        ("07", DecodeError, "unknown JUDP version"),
        ("02", DecodeError, "no transport message"),
        ("0200110001c7017e00", DecodeError, "truncated"),
        ("02000d0001c7017e0001012a000000", DecodeError, "below the minimum"),
        ("0200ff0001c7017e0001012a00002b020500", DecodeError, "exceeds"),
        ("02c01100020301c7017e0001012a00002b020500", UnsupportedError, "header compression"),
        # a good message followed by a truncated one: the datagram is refused whole
        ("0200110001c7017e0001012a00002b02050000", DecodeError, "truncated"),
    ],
)
def test_malformed_datagrams_name_the_problem(hexdata: str, error: type, text: str) -> None:
    with pytest.raises(error, match=text) as info:
        unpack_datagram(bytes.fromhex(hexdata))
    assert info.value.offset is not None


def test_random_and_mutated_bytes_raise_only_decode_error() -> None:
    rng = random.Random(1)
    valid = bytes.fromhex("0200110001c7017e0001012a00002b0205000010000001c7017e0001012a0002200600")
    decoded = refused = 0
    for i in range(20_000):
        if i % 2:
            data = bytes([2]) + rng.randbytes(rng.randrange(0, 40))
        else:
            mutable = bytearray(valid)
            for _ in range(rng.randrange(1, 4)):
                mutable[rng.randrange(len(mutable))] = rng.randrange(256)
            data = bytes(mutable[: rng.randrange(len(mutable) + 1)] if i % 4 == 0 else mutable)
        try:
            unpack_datagram(data)
            decoded += 1
        except DecodeError:
            refused += 1
    # both outcomes occur; nothing but DecodeError ever escapes
    assert decoded > 100 and refused > 100


def test_sequence_wraps_and_payload_roundtrip() -> None:
    packet = Packet(ROBOT, OCU, bytes(range(256)) * 3, sequence=65535)
    assert packet.with_sequence(65536).sequence == 0
    assert unpack_datagram(pack_datagram([packet])) == [packet]


def test_a_forwarded_packet_leaves_as_the_bytes_it_arrived_as() -> None:
    # message type 5 and a sequence number the relay did not choose: re-sent untouched
    data = bytes.fromhex("02" "05" "1000" "81" "c7017e00" "01012a00" "0244" "3412")
    (packet,) = unpack_datagram(data)
    assert encode_packet(packet) == data[1:]
    assert pack_datagram([packet]) == data


def test_a_changed_copy_of_a_received_packet_is_encoded_anew() -> None:
    from dataclasses import replace

    data = bytes.fromhex("02" "00" "1000" "01" "c7017e00" "01012a00" "0244" "3412")
    (packet,) = unpack_datagram(data)
    renumbered = replace(packet, sequence=0x0101, priority=Priority.HIGH)
    (back,) = unpack_datagram(pack_datagram([renumbered]))
    assert (back.sequence, back.priority, back.payload) == (0x0101, Priority.HIGH, b"\x02\x44")
    # equal to a packet built by hand: the kept bytes are not part of its identity
    assert packet == Packet(ROBOT, OCU, b"\x02\x44", sequence=0x1234)


def test_a_decoded_packet_is_a_complete_frozen_packet() -> None:
    import dataclasses

    original = Packet(ROBOT, OCU, b"\x02\x44\x10", sequence=9, priority=Priority.HIGH,
                      broadcast=Broadcast.LOCAL, ack_nak=AckNak.REQUEST,
                      data_flags=DataFlags.LAST, message_type=3)
    (packet,) = unpack_datagram(pack_datagram([original]))
    assert type(packet) is Packet
    for f in dataclasses.fields(Packet):  # every field is set, none left empty
        if f.compare:
            assert getattr(packet, f.name) == getattr(original, f.name), f.name
    assert packet == original and hash(packet) == hash(original)
    with pytest.raises(dataclasses.FrozenInstanceError):
        packet.sequence = 10  # type: ignore[misc]
