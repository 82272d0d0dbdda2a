"""Large-message reassembly: cost per fragment under floods and in normal use.

Run: ``.venv/bin/python bench/reassembly.py [--impl PATH] [--count N] [--repeat R]``.
Prints µs per fragment (best of ``--repeat`` runs); asserts nothing about timing.

* ``first-fragment flood, many sources``: ``--count`` first fragments of 1 kB, each from a
  new source, into a reassembler with a 256 kB byte cap (as tests/test_limits.py does):
  from the 257th on, every fragment evicts the oldest run held;
* ``first-fragment flood, one source``: the same from one source (new sequence numbers),
  so the per-source set cap (8) evicts;
* ``8-fragment messages, shuffled``: whole messages from 20 sources, fragments of each
  message in random order, every message completed.

``--duplicates N`` adds a known weak spot instead: N duplicates sent into one run of
``--count`` MIDDLE fragments (each duplicate rebuilds the runs around it: cost grows with
their length).

``--impl`` times another copy of ``edge_vis/jaus/fragments.py`` (e.g. an older revision
taken with ``git show REV:edge_vis/jaus/fragments.py > /tmp/fragments_before.py``).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import random
import sys
import time
from collections.abc import Callable
from types import ModuleType

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import DataFlags, Packet

DST = JausAddress(200, 1, 1)


def _load(path: str | None) -> ModuleType:
    if path is None:
        import edge_vis.jaus.fragments as module

        return module
    spec = importlib.util.spec_from_file_location("fragments_under_test", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _source(i: int) -> JausAddress:
    return JausAddress(1000 + i % 60000, 1 + i // 60000, 1)


def many_sources(count: int) -> list[Packet]:
    chunk = b"\x02\x42" + b"\xaa" * 1000
    return [Packet(DST, _source(i), chunk, data_flags=DataFlags.FIRST, sequence=1)
            for i in range(count)]


def one_source(count: int) -> list[Packet]:
    chunk = b"\x02\x42" + b"\xaa" * 1000
    return [Packet(DST, _source(0), chunk, data_flags=DataFlags.FIRST, sequence=(2 * i) % 65536)
            for i in range(count)]


def shuffled_messages(count: int) -> list[Packet]:
    rng = random.Random(1)
    out: list[Packet] = []
    seqs = [0] * 20
    while len(out) < count:
        s = rng.randrange(20)
        flags = [DataFlags.FIRST] + [DataFlags.MIDDLE] * 6 + [DataFlags.LAST]
        parts = [Packet(DST, _source(s), b"\x55" * 500, data_flags=f,
                        sequence=(seqs[s] + i) % 65536) for i, f in enumerate(flags)]
        seqs[s] = (seqs[s] + 8) % 65536
        rng.shuffle(parts)
        out.extend(parts)
    return out[: count - count % 8]


def run(module: ModuleType, packets: list[Packet], repeat: int) -> tuple[float, object]:
    best = float("inf")
    stats: object = None
    for _ in range(repeat):
        reassembler = module.Reassembler(max_bytes=256 * 1024, timeout=5.0)
        feed = reassembler.feed
        t0 = time.perf_counter()
        for i, packet in enumerate(packets):
            feed(packet, 0.0001 * i)
        best = min(best, time.perf_counter() - t0)
        stats = reassembler.stats
    return best / len(packets) * 1e6, stats


def long_run_duplicates(module: ModuleType, length: int, duplicates: int) -> None:
    reassembler = module.Reassembler()
    source = _source(1)
    t0 = time.perf_counter()
    for i in range(length):
        reassembler.feed(Packet(DST, source, b"\x55" * 100, data_flags=DataFlags.MIDDLE,
                                sequence=i), i * 1e-5)
    t1 = time.perf_counter()
    for k in range(duplicates):
        reassembler.feed(Packet(DST, source, b"\x55" * 100, data_flags=DataFlags.MIDDLE,
                                sequence=k * 7919 % length), 1.0 + k * 1e-5)
    t2 = time.perf_counter()
    print(f"one run of {length:,} MIDDLE fragments: {(t1 - t0) / length * 1e6:,.1f} µs per "
          f"fragment; then {duplicates:,} duplicates: {(t2 - t1) / duplicates * 1e6:,.0f} µs "
          f"each (load average {os.getloadavg()[0]:.2f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--impl", help="path of another fragments.py to time")
    parser.add_argument("--count", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--duplicates", type=int, default=0)
    args = parser.parse_args()
    module = _load(args.impl)
    if args.duplicates:
        long_run_duplicates(module, args.count, args.duplicates)
        return
    cases: list[tuple[str, Callable[[int], list[Packet]]]] = [
        ("first-fragment flood, many sources", many_sources),
        ("first-fragment flood, one source", one_source),
        ("8-fragment messages, shuffled", shuffled_messages),
    ]
    print(f"implementation: {args.impl or module.__file__}; {args.count} fragments per case, "
          f"best of {args.repeat}; load average {os.getloadavg()[0]:.2f}")
    print("| case | µs/fragment | completed | dropped (byte cap / set cap) |")
    print("| --- | ---: | ---: | ---: |")
    for name, make in cases:
        us, stats = run(module, make(args.count), args.repeat)
        print(f"| {name} | {us:,.1f} | {stats.completed:,} | "  # type: ignore[attr-defined]
              f"{stats.dropped_byte_cap:,} / {stats.dropped_set_cap:,} |")  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
