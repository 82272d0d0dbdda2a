"""The reassembler decides exactly as the plain scan-everything algorithm does.

``ScanReassembler`` below is that algorithm, kept here only as the reference: it finds
runs by walking the held fragments on every call (clear, but its cost grows with what is
held). Random fragment streams (in and out of order, duplicates, fragments rewritten with
other flags, sequence numbers wrapping at 65,535, floods over every cap, timeouts, ties in
arrival time) go to both; every returned message, counter, size and deadline must agree.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import Reassembler
from edge_vis.jaus.transport import DataFlags, Packet

_MOD = 0x10000
DST = JausAddress(42, 1, 1)
FIRST, MIDDLE, LAST = DataFlags.FIRST, DataFlags.MIDDLE, DataFlags.LAST


@dataclass
class _Held:
    packet: Packet
    arrived: float


class ScanReassembler:
    """Reference: runs found by scanning every held fragment of every source."""

    def __init__(self, max_sets_per_source: int, max_bytes: int, timeout: float) -> None:
        self.max_sets, self.max_bytes, self.timeout = max_sets_per_source, max_bytes, timeout
        self.sources: dict[JausAddress, dict[int, _Held]] = {}
        self.held = 0
        self.counts = dict.fromkeys(
            ("completed", "fragments", "duplicates", "dropped_timeout", "dropped_set_cap",
             "dropped_byte_cap", "dropped_fragments"), 0)

    def feed(self, packet: Packet, now: float) -> Packet | None:
        if packet.data_flags == DataFlags.SINGLE:
            return packet
        self.counts["fragments"] += 1
        frags = self.sources.setdefault(packet.source, {})
        old = frags.get(packet.sequence)
        if old is not None:
            self.counts["duplicates"] += 1
            self.held -= len(old.packet.payload)
        frags[packet.sequence] = _Held(packet, now)
        self.held += len(packet.payload)
        seqs = self.run_of(frags, packet.sequence)
        if frags[seqs[0]].packet.data_flags == FIRST and frags[seqs[-1]].packet.data_flags == LAST:
            parts = [frags.pop(s) for s in seqs]
            self.held -= sum(len(p.packet.payload) for p in parts)
            if not frags:
                del self.sources[packet.source]
            self.counts["completed"] += 1
            return replace(parts[0].packet, payload=b"".join(p.packet.payload for p in parts),
                           data_flags=DataFlags.SINGLE)
        keep = seqs[0]
        while len(self.starts(frags)) > self.max_sets:
            victim = self.oldest(frags, keep)
            if victim is None:
                break
            self.drop(frags, victim[1])
            self.counts["dropped_set_cap"] += 1
        while self.held > self.max_bytes:
            best = None
            for other in self.sources.values():
                found = self.oldest(other, keep if other is frags else None)
                if found is not None and (best is None or found[0] < best[0]):
                    best = (found[0], other, found[1])
            if best is None:
                self.drop(frags, self.run_of(frags, keep))
                self.counts["dropped_byte_cap"] += 1
                break
            self.drop(best[1], best[2])
            self.counts["dropped_byte_cap"] += 1
        for source in [s for s, f in self.sources.items() if not f]:
            del self.sources[source]
        return None

    def expire(self, now: float) -> int:
        dropped = 0
        for source in list(self.sources):
            frags = self.sources[source]
            for start in self.starts(frags):
                seqs = self.run_of(frags, start)
                if now - max(frags[s].arrived for s in seqs) > self.timeout:
                    self.drop(frags, seqs)
                    self.counts["dropped_timeout"] += 1
                    dropped += 1
            if not frags:
                del self.sources[source]
        return dropped

    def next_deadline(self) -> float | None:
        newest = [max(f[s].arrived for s in self.run_of(f, start))
                  for f in self.sources.values() for start in self.starts(f)]
        return min(newest) + self.timeout if newest else None

    def pending_sets(self, source: JausAddress | None = None) -> int:
        stores = [self.sources[source]] if source is not None else self.sources.values()
        return sum(len(self.starts(f)) for f in stores)

    @staticmethod
    def joined(frags: dict[int, _Held], before: int, after: int) -> bool:
        return (before in frags and after in frags
                and frags[before].packet.data_flags != LAST
                and frags[after].packet.data_flags != FIRST)

    def run_of(self, frags: dict[int, _Held], seq: int) -> list[int]:
        start = seq
        while self.joined(frags, (start - 1) % _MOD, start):
            start = (start - 1) % _MOD
        seqs = [start]
        while self.joined(frags, seqs[-1], (seqs[-1] + 1) % _MOD):
            seqs.append((seqs[-1] + 1) % _MOD)
        return seqs

    def starts(self, frags: dict[int, _Held]) -> list[int]:
        return [s for s in frags if not self.joined(frags, (s - 1) % _MOD, s)]

    def oldest(
        self, frags: dict[int, _Held], exclude: int | None
    ) -> tuple[float, list[int]] | None:
        best = None
        for start in self.starts(frags):
            if start != exclude:
                seqs = self.run_of(frags, start)
                age = min(frags[s].arrived for s in seqs)
                if best is None or age < best[0]:
                    best = (age, seqs)
        return best

    def drop(self, frags: dict[int, _Held], seqs: list[int]) -> None:
        for s in seqs:
            self.held -= len(frags.pop(s).packet.payload)
            self.counts["dropped_fragments"] += 1


def _stream(rng: random.Random, sources: list[JausAddress]) -> list[tuple[str, object, float]]:
    """A random schedule of ``("feed", packet, now)`` and ``("expire"/"deadline", None, now)``."""
    events: list[tuple[str, object, float]] = []
    now = 0.0
    seqs = {s: rng.choice([0, rng.randrange(_MOD), _MOD - rng.randrange(1, 6)]) for s in sources}
    pending: list[Packet] = []
    for _ in range(rng.randrange(20, 120)):
        source = rng.choice(sources)
        count = rng.choice([1, 2, 3, 4, 6])
        parts = []
        for i in range(count):
            flags = FIRST if i == 0 else LAST if i == count - 1 else MIDDLE
            if count == 1:
                flags = rng.choice([FIRST, MIDDLE, LAST])  # a stray fragment
            size = rng.choice([1, 5, 20, 60])
            parts.append(Packet(DST, source, bytes([i]) * size, data_flags=flags,
                                sequence=(seqs[source] + i) % _MOD))
        seqs[source] = (seqs[source] + count + rng.choice([0, 0, 0, 1, 3])) % _MOD
        kept = [p for p in parts if rng.random() > 0.15]  # some fragments are lost
        dupes = [p for p in kept if rng.random() < 0.15]
        rewritten = [replace(p, data_flags=rng.choice([FIRST, MIDDLE, LAST]), payload=b"r")
                     for p in kept if rng.random() < 0.05]  # same number, other flags
        pending.extend(kept + dupes + rewritten)
        if rng.random() < 0.5:
            rng.shuffle(pending)
        while pending and rng.random() < 0.7:
            packet = pending.pop(0)
            now += rng.choice([0.0, 0.0, 0.01, 0.1, 0.4])  # ties in age are common
            if rng.random() < 0.02:
                now -= 0.5  # a caller's clock may step back; decisions must still agree
            events.append(("feed", packet, now))
            if rng.random() < 0.1:
                events.append(("expire", None, now))
            if rng.random() < 0.1:
                events.append(("deadline", None, now))
    for packet in pending:
        events.append(("feed", packet, now))
    events.append(("expire", None, now + 0.5))
    events.append(("deadline", None, now + 0.5))
    events.append(("expire", None, now + 100.0))
    return events


def _compare(new: Reassembler, ref: ScanReassembler, events: list[tuple[str, object, float]],
             sources: list[JausAddress]) -> int:
    completed = 0
    for step, (kind, packet, now) in enumerate(events):
        where = f"step {step} ({kind} at {now})"
        if kind == "feed":
            assert isinstance(packet, Packet)
            got, want = new.feed(packet, now), ref.feed(packet, now)
            assert got == want, where
            completed += got is not None and got.data_flags == DataFlags.SINGLE
        elif kind == "expire":
            assert new.expire(now) == ref.expire(now), where
        else:
            assert new.next_deadline() == ref.next_deadline(), where
        counts = {name: getattr(new.stats, name) for name in ref.counts}
        assert counts == ref.counts, where
        assert new.bytes_held == ref.held, where
        assert new.pending_sets() == ref.pending_sets(), where
        for source in sources:
            if source in ref.sources:
                assert new.pending_sets(source) == ref.pending_sets(source), where
    return completed


@pytest.mark.parametrize("seed", range(120))
def test_same_messages_drops_and_counters_as_the_scanning_reference(seed: int) -> None:
    rng = random.Random(seed)
    sources = [JausAddress(100 + i, 1, 1) for i in range(rng.choice([1, 2, 4]))]
    caps = {"max_sets_per_source": rng.choice([0, 1, 2, 4, 8]),
            "max_bytes": rng.choice([40, 150, 400, 100_000]),
            "timeout": rng.choice([0.3, 1.0, 5.0])}
    new, ref = Reassembler(**caps), ScanReassembler(**caps)
    _compare(new, ref, _stream(rng, sources), sources)
    assert new.bytes_held == 0 and new.pending_sets() == 0 and new.next_deadline() is None


def test_streams_exercise_every_decision() -> None:
    """The random streams above do reach completions and every kind of drop."""
    totals = dict.fromkeys(("completed", "duplicates", "dropped_timeout", "dropped_set_cap",
                            "dropped_byte_cap"), 0)
    for seed in range(120):
        rng = random.Random(seed)
        sources = [JausAddress(100 + i, 1, 1) for i in range(rng.choice([1, 2, 4]))]
        caps = {"max_sets_per_source": rng.choice([0, 1, 2, 4, 8]),
                "max_bytes": rng.choice([40, 150, 400, 100_000]),
                "timeout": rng.choice([0.3, 1.0, 5.0])}
        ref = ScanReassembler(**caps)
        for kind, packet, now in _stream(rng, sources):
            if kind == "feed":
                assert isinstance(packet, Packet)
                ref.feed(packet, now)
            elif kind == "expire":
                ref.expire(now)
        for name in totals:
            totals[name] += ref.counts[name]
    assert all(count > 20 for count in totals.values()), totals


def test_a_first_fragment_flood_from_many_sources_agrees_with_the_reference() -> None:
    caps = {"max_sets_per_source": 2, "max_bytes": 2_000, "timeout": 1.0}
    new, ref = Reassembler(**caps), ScanReassembler(**caps)
    rng = random.Random(7)
    sources = [JausAddress(300 + i, 1, 1) for i in range(50)]
    events: list[tuple[str, object, float]] = []
    for i in range(1500):
        packet = Packet(DST, rng.choice(sources), b"\xaa" * rng.choice([10, 100]),
                        data_flags=FIRST, sequence=rng.choice([_MOD - 1, 0, rng.randrange(_MOD)]))
        events.append(("feed", packet, i * 0.001 // 0.01 * 0.01))  # runs of equal times
        if i % 200 == 199:
            events.append(("expire", None, i * 0.001))
    _compare(new, ref, events, sources)
    assert new.stats.dropped_byte_cap > 500 and new.stats.dropped_set_cap > 100
