"""Lanes within a transfer, table-driven: segments, shared pacing, stalls."""

from __future__ import annotations

import itertools

import pytest

from links.udt.lane_plan import SPLIT_BYTES, Pace, segments_for, straggler
from links.udt.protocol import MAX_SEGMENTS, segment_bounds


@pytest.mark.parametrize(("rate", "sends", "waits"), [
    # 8 Mbit/s = 1 MB/s: 128 KiB ahead of the rate go at once, then each 64 KiB waits
    (8e6, [65536] * 5, [0.0, 0.0, 0.0, 0.065536, 0.131072]),
    (4e6, [131072, 65536], [0.0, 0.0]),
])
def test_pace_keeps_lanes_together_to_the_budget(rate, sends, waits):
    pace = Pace(rate)
    got = [pace.delay(n, 10.0) for n in sends]
    assert got == pytest.approx(waits)


def test_pace_long_run_holds_the_rate():
    pace, now, sent = Pace(5e6), 0.0, 0
    while now < 10.0:
        now += pace.delay(65536, now)  # a caller that waits as told
        sent += 65536
    assert 5e6 / 8 * now <= sent <= 5e6 / 8 * now + pace.burst + 65536


@pytest.mark.parametrize(("started", "durations", "now", "lane"), [
    ({1: 0.0, 2: 5.0}, [1.0, 1.2, 0.9], 6.0, 1),    # lane 1 six times the median: take over
    ({1: 5.5, 2: 5.0}, [1.0, 1.2, 0.9], 6.0, None),  # all within twice the median
    ({1: 0.0}, [], 6.0, None),                       # no segment finished yet: no yardstick
    ({1: 5.0}, [0.1, 0.1], 5.5, None),               # short segments: at least a second
    ({}, [1.0], 6.0, None),
])
def test_straggler(started, durations, now, lane):
    assert straggler(started, durations, now) == lane


@pytest.mark.parametrize(("size", "count"), [
    (SPLIT_BYTES - 1, 1),           # small files go whole on one connection
    (SPLIT_BYTES, 16),              # 64 KiB segments
    (8 << 20, MAX_SEGMENTS),
    (1 << 30, MAX_SEGMENTS),
])
def test_segments_depend_on_size_only(size, count):
    assert segments_for(size) == count
    bounds = [segment_bounds(size, i, count) for i in range(count)]
    assert bounds[0][0] == 0 and bounds[-1][1] == size
    assert all(a[1] == b[0] for a, b in itertools.pairwise(bounds))
