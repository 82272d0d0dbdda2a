"""Large data sets: split to an MTU, reassembled in any order, within fixed bounds."""

from __future__ import annotations

import itertools
import random

import pytest

from edge_vis.errors import EncodeError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.fragments import Reassembler, fragment
from edge_vis.jaus.transport import DataFlags, Packet, pack_datagram, unpack_datagram

SRC = JausAddress(126, 1, 199)
DST = JausAddress(42, 1, 1)


def big_packet(size: int, seq: int = 100, source: JausAddress = SRC) -> Packet:
    body = bytes(random.Random(size).randrange(256) for _ in range(size))
    return Packet(DST, source, b"\x14\x48" + body, sequence=seq)


def test_three_fragment_set_golden_bytes_and_any_order() -> None:
    # A 10-byte payload over an MTU of 4: fragments of 4, 4 and 2 bytes with flags
    # FIRST (0x41: prio 1, df 1), MIDDLE (0x81), LAST (0xC1) and sequence 7, 8, 9.
    packet = Packet(DST, SRC, bytes(range(10)), sequence=7)
    parts = fragment(packet, 4)
    datagrams = [pack_datagram([p]).hex() for p in parts]
    assert datagrams == [
        "02" "00" "1200" "41" "01012a00" "c7017e00" "00010203" "0700",
        "02" "00" "1200" "81" "01012a00" "c7017e00" "04050607" "0800",
        "02" "00" "1000" "c1" "01012a00" "c7017e00" "0809" "0900",
    ]
    for order in itertools.permutations(range(3)):
        r = Reassembler()
        results = [r.feed(unpack_datagram(bytes.fromhex(datagrams[i]))[0], now=0.0) for i in order]
        assert results[:2] == [None, None]
        whole = results[2]
        assert whole is not None
        assert whole.payload == bytes(range(10))
        assert whole.data_flags == DataFlags.SINGLE
        assert whole.sequence == 7
        assert whole.message_code == 0x0100
        assert r.bytes_held == 0 and r.pending_sets() == 0


def test_sequence_wraps_inside_a_set() -> None:
    packet = big_packet(10_000, seq=65534)
    parts = fragment(packet, 4079)
    assert [p.sequence for p in parts] == [65534, 65535, 0]
    r = Reassembler()
    assert r.feed(parts[2], 0) is None
    assert r.feed(parts[0], 0) is None
    assert r.feed(parts[1], 0).payload == packet.payload  # type: ignore[union-attr]


def test_interleaved_sets_from_two_sources_and_single_packets_pass_through() -> None:
    a = fragment(big_packet(9000, seq=1, source=JausAddress(1, 1, 1)), 4000)
    b = fragment(big_packet(7000, seq=1, source=JausAddress(2, 1, 1)), 4000)
    r = Reassembler()
    small = Packet(DST, SRC, b"\x02\x40\x01\x00\x00\x00\x00", sequence=5)
    assert r.feed(small, 0) is small
    out = [r.feed(p, 0) for p in (a[0], b[1], a[2], b[0], a[1])]
    done = [p for p in out if p is not None]
    assert [len(p.payload) for p in done] == [7002, 9002]


def test_adjacent_sets_do_not_merge() -> None:
    first = fragment(big_packet(9000, seq=10), 4000)  # seq 10, 11, 12
    second = fragment(big_packet(5000, seq=13), 4000)  # seq 13, 14
    r = Reassembler()
    got = [r.feed(p, 0) for p in [*second, *first]]
    assert [len(p.payload) for p in got if p] == [5002, 9002]


def test_timeout_drops_incomplete_set_and_counts_it() -> None:
    parts = fragment(big_packet(9000), 4000)
    r = Reassembler(timeout=2.0)
    r.feed(parts[0], now=10.0)
    r.feed(parts[1], now=11.0)
    assert r.next_deadline() == 13.0
    assert r.expire(now=12.9) == 0
    assert r.expire(now=13.1) == 1
    assert r.stats.dropped_timeout == 1 and r.bytes_held == 0
    # the late last fragment alone never produces a message
    assert r.feed(parts[2], now=14.0) is None


def test_set_cap_per_source_drops_oldest() -> None:
    r = Reassembler(max_sets_per_source=2)
    sets = [fragment(big_packet(9000, seq=100 * i), 4000) for i in range(1, 4)]
    for i, parts in enumerate(sets):
        r.feed(parts[0], now=float(i))  # three incomplete sets from one source
    assert r.pending_sets(SRC) == 2
    assert r.stats.dropped_set_cap == 1
    # the oldest (first) set is gone: completing it yields nothing
    assert r.feed(sets[0][1], 5) is None and r.feed(sets[0][2], 5) is None
    # the newest survives and completes
    assert r.feed(sets[2][1], 5) is None
    assert r.feed(sets[2][2], 5) is not None


def test_byte_cap_bounds_memory_across_sources() -> None:
    r = Reassembler(max_bytes=10_000)
    for n in range(1, 6):
        parts = fragment(big_packet(9000, seq=1, source=JausAddress(n, 1, 1)), 4000)
        r.feed(parts[0], now=float(n))
        r.feed(parts[1], now=float(n))
        assert r.bytes_held <= 10_000
    assert r.stats.dropped_byte_cap >= 4


def test_duplicate_fragment_is_counted_not_doubled() -> None:
    parts = fragment(big_packet(9000), 4000)
    r = Reassembler()
    r.feed(parts[0], 0)
    r.feed(parts[0], 0)
    assert r.stats.duplicates == 1
    assert r.bytes_held == len(parts[0].payload)
    r.feed(parts[1], 0)
    assert r.feed(parts[2], 0).payload == parts[0].payload + parts[1].payload + parts[2].payload  # type: ignore[union-attr]


def test_broadcast_too_large_is_refused() -> None:
    with pytest.raises(EncodeError, match="broadcast"):
        fragment(Packet(BROADCAST, SRC, bytes(5000)), 4079)


def test_random_fragment_soup_never_raises_and_stays_bounded() -> None:
    rng = random.Random(7)
    r = Reassembler(max_sets_per_source=4, max_bytes=50_000, timeout=1.0)
    for i in range(3000):
        packet = Packet(
            DST, JausAddress(rng.randrange(1, 4), 1, 1), rng.randbytes(rng.randrange(0, 3000)),
            sequence=rng.randrange(0, 40), data_flags=rng.randrange(1, 4),
        )
        r.feed(packet, now=i * 0.01)
        r.expire(now=i * 0.01)
        assert r.bytes_held <= 50_000
        assert r.pending_sets(packet.source) <= 4
