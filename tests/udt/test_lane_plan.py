"""Adaptive lanes within a transfer, table-driven: lane counts, shared pacing, stalls."""

from __future__ import annotations

import itertools

import pytest

from links.udt.lane_plan import SPLIT_BYTES, LaneController, Pace, segments_for, straggler
from links.udt.protocol import MAX_SEGMENTS, segment_bounds


def drive(control: LaneController, windows: list[tuple[float, list[float]]]) -> list[int]:
    """Run ``control`` window by window: (goodput in bytes/s, round trips seen in it);
    return the lane count after each window."""
    now, acked = 0.0, 0.0
    control.sample(now, 0)
    lanes = []
    for rate, trips in windows:
        for step in (control.settle, 0.01):  # settled (after a change): the window starts
            now += step
            acked += rate * step
            control.sample(now, int(acked))
        for rtt in trips:
            control.round_trip(rtt)
        now += control.window
        acked += rate * control.window
        lanes.append(control.sample(now, int(acked)))
    return lanes


BASE = 0.040


@pytest.mark.parametrize(("windows", "expected"), [
    # lossy radio: answers come back at the path's own delay, lanes add up to the maximum
    ([(1e5, [BASE, BASE + 0.01])] * 4, [12, 16, 16, 16]),
    # a full link: every answer waits behind a standing queue, one lane goes per window
    ([(1e5, [BASE])] + [(1.2e6, [BASE + 0.06, BASE + 0.09])] * 3, [12, 11, 10, 9]),
    # in between (some queueing, not standing): hold
    ([(1e5, [BASE])] + [(1.2e6, [BASE + 0.02])] * 2, [12, 12, 12]),
    # a window without any segment handshake teaches nothing
    ([(1e5, [])] * 2, [8, 8]),
])
def test_lanes_follow_the_queueing_delay(windows, expected):
    assert drive(LaneController(start=8), windows) == expected


def test_lanes_stop_climbing_at_the_budget():
    control = LaneController(start=4, budget_bps=8e6)
    # 0.6 MB/s = 4.8 Mbit/s, below 92 % of the budget: climb; 1 MB/s = 8 Mbit/s: stay
    assert drive(control, [(6e5, [BASE]), (1e6, [BASE]), (1e6, [BASE])]) == [6, 6, 6]


def test_controller_records_its_decisions():
    control = LaneController(start=4, maximum=6)
    drive(control, [(1e5, [BASE])] * 3)
    assert [lanes for _, lanes, _ in control.history] == [6]


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
