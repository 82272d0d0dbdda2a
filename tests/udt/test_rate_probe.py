"""The rate all lanes of a transfer keep to together, table-driven: single decisions, then
whole transfers through a modelled radio (a rate, a bounded queue, random loss)."""

from __future__ import annotations

import random

import pytest

from links.udt.rate_probe import RateProbe, lane_share

BASE = 0.040  # the path's own round trip


class Drive:
    """Runs a probe step by step on a clock of its own, as the lane coordinator does."""

    def __init__(self, probe: RateProbe) -> None:
        self.probe, self.now, self.acked = probe, 0.0, 0.0
        probe.sample(0.0, 0)

    def __call__(self, steps: list[tuple[float, list[float]]]) -> list[float]:
        """Each step: (bit/s the receiver acknowledged during it, round trips answered in
        it); returns the rate after each step."""
        rates = []
        for delivered, trips in steps:
            for rtt in trips:
                self.probe.round_trip(rtt)
            self.now += self.probe.step
            self.acked += delivered * self.probe.step / 8
            rates.append(self.probe.sample(self.now, int(self.acked)))
        return rates


def drive(probe: RateProbe, steps: list[tuple[float, list[float]]]) -> list[float]:
    return Drive(probe)(steps)


CLEAR = [BASE, BASE + 0.002]
QUEUE = [BASE + 0.030, BASE + 0.045]  # every answer waits behind a standing queue


@pytest.mark.parametrize(("steps", "expected", "phase"), [
    # the start: up by half each step, within twice the delivery once half a span is seen
    ([(4e6, CLEAR), (6e6, CLEAR), (9e6, CLEAR)], [6e6, 9e6, 2 * (4e6 + 6e6 + 9e6) / 3],
     "startup"),
    # the first standing queue ends the start: down to what the last two steps delivered,
    # less a step
    ([(4e6, CLEAR), (6e6, CLEAR), (5e6, QUEUE)], [6e6, 9e6, 0.95 * (6e6 + 5e6) / 2], "paced"),
    # one delayed answer is a lost packet, not a queue: the clear one counts, the rate rises
    ([(4e6, [BASE]), (6e6, [BASE + 0.3, BASE])], [6e6, 9e6], "startup"),
    # a lone late answer proves nothing either way: hold
    ([(4e6, [BASE]), (4e6, [BASE + 0.3])], [6e6, 6e6], "startup"),
    # some queueing but not standing: hold
    ([(4e6, [BASE]), (4e6, [BASE + 0.012, BASE + 0.015])], [6e6, 6e6], "startup"),
    # a step without any answer teaches nothing
    ([(4e6, [BASE]), (4e6, [])], [6e6, 6e6], "startup"),
])
def test_single_decisions(steps, expected, phase):
    probe = RateProbe(initial_bps=4e6, startup=1.5)
    assert drive(probe, steps) == pytest.approx(expected)
    assert probe.phase == phase


def test_a_step_down_waits_for_the_queue_to_drain_before_the_next():
    probe = RateProbe(initial_bps=8e6)
    run = Drive(probe)
    run([(8e6, CLEAR), (8e6, QUEUE)])  # the start is over: paced at 0.95 x 8 Mbit/s
    paced = probe.rate_bps
    # four queued steps in a row after a step down, two once the path was clear again
    rates = run([(paced, QUEUE)] * 4 + [(paced, CLEAR)] + [(paced, QUEUE)] * 2)
    down = paced * 0.95
    assert rates == pytest.approx([paced] * 3 + [down, down * 1.04, down * 1.04,
                                                 down * 1.04 * 0.95])


def test_paced_rate_stays_within_reach_of_what_the_lanes_deliver():
    """Lanes held back by UDT's own loss reaction do not pile up a rate they would all
    take at once when they recover."""
    probe = RateProbe(initial_bps=8e6)
    run = Drive(probe)
    run([(8e6, CLEAR), (8e6, QUEUE)])
    rates = run([(3e6, CLEAR)] * 12)
    assert max(rates[4:]) <= 1.1 * 3e6 + 1


def test_budget_is_a_ceiling_and_its_delivery_is_not_slowed_by_a_queue():
    probe = RateProbe(initial_bps=4e6, budget_bps=5e6)
    rates = drive(probe, [(4e6, CLEAR)] + [(5e6, CLEAR)] * 4 + [(5e6, QUEUE)] * 4)
    assert max(rates) == 5e6
    assert rates[-1] == 5e6


def test_under_a_budget_neither_a_queue_nor_a_slow_delivery_take_the_rate_below_near_it():
    probe = RateProbe(initial_bps=4e6, budget_bps=5e6)
    rates = drive(probe, [(4e6, CLEAR)] + [(3e6, QUEUE)] * 40 + [(2e6, CLEAR)] * 8)
    assert min(rates[1:]) == pytest.approx(0.8 * 5e6)


def test_floor():
    probe = RateProbe(initial_bps=1e6, floor_bps=300e3)
    rates = drive(probe, [(1e6, CLEAR), (1e6, QUEUE)] + [(1e5, QUEUE)] * 120)
    assert min(rates) == 300e3


def radio(probe: RateProbe, capacity: float, loss: float, seconds: float,
          seed: int = 1) -> list[float]:
    """A transfer through a radio of ``capacity`` bit/s with a 64 KiB queue: the lanes
    send at the probe's rate, the queue fills with what exceeds the radio and drains
    otherwise, three manifests answered per step wait behind it, and ``loss`` delays an
    answer by a retransmission. Returns the rate after each step."""
    rng = random.Random(seed)
    queue, limit = 0.0, 64 * 1024 * 8
    run = Drive(probe)
    rates: list[float] = []
    for _ in range(int(seconds / probe.step)):
        trips = [BASE + queue / capacity + (0.25 if rng.random() < 3 * loss else 0.0)
                 for _ in range(3)]
        rate = probe.rate_bps
        queue = min(limit, max(0.0, queue + (rate - capacity) * probe.step))
        rates += run([(min(rate, capacity) * (1 - loss), trips)])
    return rates


@pytest.mark.parametrize(("capacity", "loss"), [(10e6, 0.0), (10e6, 0.02), (2e6, 0.0),
                                                 (50e6, 0.01)])
def test_finds_the_radio_and_keeps_to_it(capacity, loss):
    """From 4 Mbit/s, whatever the radio: after the start the rate averages within a few
    percent of the radio's and never stands far above it."""
    rates = radio(RateProbe(), capacity, loss, seconds=30)
    settled = rates[len(rates) // 3:]
    assert 0.9 * capacity <= sum(settled) / len(settled) <= 1.08 * capacity
    assert max(settled) <= 1.2 * capacity


@pytest.mark.parametrize(("rate", "sending", "share"), [
    (9.6e6, 16, 0.6e6), (9.6e6, 3, 3.2e6), (9.6e6, 0, 9.6e6)])
def test_lane_share(rate, sending, share):
    assert lane_share(rate, sending) == pytest.approx(share)
