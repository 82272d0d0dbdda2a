"""The rate all lanes of a transfer keep to together, table-driven: single decisions, then
whole transfers through a modelled radio (a rate, a bounded queue, random loss)."""

from __future__ import annotations

import random

import pytest

from links.udt.lane_run import SharedRate
from links.udt.rate_probe import RateProbe, filled_shares, final_shares, lane_share

BASE = 0.040  # the path's own round trip


class Drive:
    """Runs a probe step by step on a clock of its own, as the lane coordinator does."""

    def __init__(self, probe: RateProbe) -> None:
        self.probe, self.now, self.acked = probe, 0.0, 0.0
        probe.sample(0.0, 0)

    def __call__(self, steps: list[tuple[float, list[float]]], smoothed: bool = False
                 ) -> list[float]:
        """Each step (the start's shorter ones while it lasts): (bit/s the receiver
        acknowledged during it, round trips seen in it: answers to manifests, or with
        ``smoothed`` the lanes' own smoothed round trips); returns the rate after each."""
        rates = []
        for delivered, trips in steps:
            for rtt in trips:
                (self.probe.smoothed if smoothed else self.probe.round_trip)(rtt)
            step = self.probe.startup_step if self.probe.phase == "startup" else self.probe.step
            self.now += step
            self.acked += delivered * step / 8
            rates.append(self.probe.sample(self.now, int(self.acked)))
        return rates


def drive(probe: RateProbe, steps: list[tuple[float, list[float]]],
          smoothed: bool = False) -> list[float]:
    return Drive(probe)(steps, smoothed)


CLEAR = [BASE, BASE + 0.002]
QUEUE = [BASE + 0.030, BASE + 0.045]  # every answer waits behind a standing queue
START = {"initial_bps": 4e6, "startup": 1.5, "startup_step": 0.25}  # round figures


@pytest.mark.parametrize(("steps", "expected", "phase"), [
    # the start: up by half each step, within twice the delivery once half a span is seen
    ([(4e6, CLEAR), (6e6, CLEAR), (9e6, CLEAR)], [6e6, 9e6, 2 * (4e6 + 6e6 + 9e6) / 3],
     "startup"),
    # the first standing queue ends the start: what two steps delivered (the second
    # most of those seen, one burst of late acknowledgements is not the radio), less
    # what brings the queue (30 ms) to the target (5 ms) within 0.35 s
    ([(4e6, CLEAR), (6e6, CLEAR), (5e6, QUEUE)],
     [6e6, 9e6, (4e6 + 6e6) / 2 * (1 - 0.025 / 0.35)], "paced"),
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
    probe = RateProbe(**START)
    assert drive(probe, steps) == pytest.approx(expected)
    assert probe.phase == phase


@pytest.mark.parametrize(("queued", "factor"), [
    (0.005, 1.0),                  # at the target: what the radio delivers
    (0.040, 1 - 0.035 / 0.35),     # above it: less, to drain within about 0.35 s
    (0.200, 0.85),                 # far above: at most 15 % less a step
])
def test_a_full_radio_is_paced_at_what_it_delivers_toward_the_target_queue(queued, factor):
    """The lanes' smoothed round trips say the queue every step: above ``room`` the
    radio is full, and its delivery, not the rate asked, is what it carries."""
    probe = RateProbe(**START)
    run = Drive(probe)
    run([(4e6, [BASE]), (6e6, [BASE]), (9e6, [BASE + 0.010])], smoothed=True)
    assert probe.phase == "paced"
    rates = run([(9e6, [BASE + queued])] * 8, smoothed=True)
    if queued > probe.room:
        assert rates[-1] == pytest.approx(9e6 * factor)
    else:
        assert rates[-1] >= 9e6


@pytest.mark.parametrize(("sent", "again", "overrun"), [
    (400, 120, True),   # 30 % sent again: the radio's queue drops what exceeds it
    (400, 40, False),   # 10 %: still a lossy radio's own losses
    (40, 20, False),    # too few packets to say
])
def test_lanes_sending_much_again_say_an_over_run_radio(sent, again, overrun):
    """The lanes' connections do not slow down for losses (links.udt.udt_cc), so a rate
    above the radio's shows in the packets they send again, whatever the round trips
    say: the start ends, and the rate comes down by 15 % a step while it lasts."""
    probe = RateProbe(**START)
    run = Drive(probe)
    run([(4e6, CLEAR), (6e6, CLEAR)])
    assert probe.rate_bps == 9e6
    probe.sent(sent, again)
    (rate,) = run([(7e6, CLEAR)])
    if overrun:
        assert probe.phase == "paced"
        assert rate == pytest.approx(0.85 * 9e6)
    else:
        assert probe.phase == "startup" and rate > 9e6
    probe.sent(400, 12)  # counted afresh after a step judged; too few carry over
    assert probe.resent_share() == pytest.approx(
        0.03 if sent >= probe.counted else (again + 12) / (sent + 400))


def test_smoothed_round_trips_end_the_start_at_a_short_queue():
    """Answers need a 20 ms queue in two of them; the connections' own smoothed round
    trip, a few milliseconds, before the radio's 64 KiB queue (52 ms at 10 Mbit/s) can
    overflow."""
    by_answers = RateProbe(**START)
    drive(by_answers, [(4e6, [BASE]), (6e6, [BASE + 0.008, BASE + 0.009])])
    smoothed = RateProbe(**START)
    drive(smoothed, [(4e6, [BASE]), (6e6, [BASE + 0.008])], smoothed=True)
    assert (by_answers.phase, smoothed.phase) == ("startup", "paced")


def test_paced_rate_returns_at_once_to_what_the_radio_carried_then_follows_delivery():
    """Lanes held back by UDT's own loss reaction: with the queue clear the rate goes
    back at once to the most the radio delivered over the last two seconds (no creep
    from the low), and once that is older, within reach of what the lanes deliver, so
    they do not all take a piled-up rate at once."""
    probe = RateProbe(initial_bps=8e6, startup_step=0.25)
    run = Drive(probe)
    run([(8e6, CLEAR)] * 2 + [(8e6, QUEUE)] + [(8e6, CLEAR)] * 8)
    assert probe.phase == "paced"
    rates = run([(3e6, CLEAR)] * 16)
    assert rates[0] == pytest.approx(8e6, rel=0.02)
    assert max(rates[12:]) <= 1.1 * 3e6 + 1


def test_budget_is_a_ceiling_and_its_delivery_is_not_slowed_by_a_queue():
    probe = RateProbe(**START, budget_bps=5e6)
    rates = drive(probe, [(4e6, CLEAR)] + [(5e6, CLEAR)] * 4 + [(5e6, QUEUE)] * 4)
    assert max(rates) == 5e6
    assert rates[-1] == 5e6


def test_under_a_budget_neither_a_queue_nor_a_slow_delivery_take_the_rate_below_near_it():
    probe = RateProbe(**START, budget_bps=5e6)
    rates = drive(probe, [(4e6, CLEAR)] + [(3e6, QUEUE)] * 40 + [(2e6, CLEAR)] * 8)
    assert min(rates[1:]) == pytest.approx(0.8 * 5e6)


def test_floor():
    probe = RateProbe(initial_bps=1e6, floor_bps=300e3)
    rates = drive(probe, [(1e6, CLEAR), (1e6, QUEUE)] + [(1e5, QUEUE)] * 120)
    assert min(rates) == 300e3


def radio(probe: RateProbe, capacity: float, loss: float, seconds: float, seed: int = 1,
          smoothed: bool = False, excess: float = 0.0, after: float = 1.0,
          stall: tuple[float, float] = (0.0, 0.0), lag: float = 0.0
          ) -> tuple[list[float], dict[str, float]]:
    """A transfer through a radio of ``capacity`` bit/s with a 64 KiB queue: the lanes
    send at the probe's rate (``excess`` more: a lane that starts a segment takes its
    share before the others give theirs up), the queue fills with what exceeds the radio
    and drains otherwise, beyond 64 KiB it drops. The probe sees three manifests answered
    per step, waiting behind the queue (``loss`` delays an answer by a retransmission),
    or with ``smoothed`` the connections' smoothed round trip. Returns the rate after
    each step, and bits delivered and dropped, and seconds the radio idled, from
    ``after`` seconds on. ``stall`` (from, seconds): the path carries nothing meanwhile
    (a busy machine at either end, a dead spell), and its queue fills. ``lag``: the
    smoothed round trip says the queue as it stood ``lag`` seconds before (UDT smooths it
    at both ends), and the probe sees the answers as well."""
    rng = random.Random(seed)
    queue, limit = 0.0, 64 * 1024 * 8
    run = Drive(probe)
    rates: list[float] = []
    seen = {"delivered": 0.0, "dropped": 0.0, "idle": 0.0}
    queues: list[tuple[float, float]] = []  # (when, the queue then)
    while run.now < seconds:
        step = probe.startup_step if probe.phase == "startup" else probe.step
        queues.append((run.now, queue))
        answers = [BASE + queue / capacity + (0.25 if rng.random() < 3 * loss else 0.0)
                   for _ in range(3)]
        if lag:
            for trip in answers:
                probe.round_trip(trip)
        if smoothed:
            then = next((q for t, q in reversed(queues) if t <= run.now - lag), queues[0][1])
            trips = [BASE + then / capacity]
        else:
            trips = answers
        sent = probe.rate_bps * (1 + excess) * step
        stalled = stall[0] <= run.now < stall[0] + stall[1]
        carried = 0.0 if stalled else min(capacity * step, queue + sent)
        queue += sent - carried
        if run.now >= after:
            seen["delivered"] += carried * (1 - loss)
            seen["dropped"] += max(0.0, queue - limit)
            seen["idle"] += (capacity * step - carried) / capacity
        queue = min(queue, limit)
        rates += run([(carried / step * (1 - loss), trips)], smoothed)
    return rates, seen


@pytest.mark.parametrize(("capacity", "loss"), [(10e6, 0.0), (10e6, 0.02), (2e6, 0.0),
                                                 (50e6, 0.01)])
def test_finds_the_radio_and_keeps_to_it(capacity, loss):
    """From 6 Mbit/s, whatever the radio, with the answers alone: after the start the
    rate averages within a few percent of the radio's and never stands far above it."""
    rates, _ = radio(RateProbe(), capacity, loss, seconds=30)
    settled = rates[len(rates) // 3:]
    assert 0.9 * capacity <= sum(settled) / len(settled) <= 1.08 * capacity
    assert max(settled) <= 1.2 * capacity


@pytest.mark.parametrize(("capacity", "after", "excess", "drops"), [
    (10e6, 1.0, 0.0, 0.0), (10e6, 1.0, 0.08, 0.0), (2e6, 1.0, 0.0, 0.0),
    (2e6, 1.0, 0.08, 0.0),
    # 64 KiB are 10 ms at 50 Mbit/s: a quarter second's 2 % above it overflows them, and
    # lanes that send 8 % more than the rate would overflow them all along
    (50e6, 3.0, 0.0, 0.01)])
def test_with_smoothed_round_trips_the_radio_stays_busy_and_its_queue_does_not_overflow(
        capacity, after, excess, drops):
    """What 95 % of a radio needs: once the start found it (within a second from 6
    Mbit/s to 10; 50 takes longer) it does not idle and its queue does not drop, even
    while the lanes send more than the rate says."""
    rates, seen = radio(RateProbe(), capacity, 0.0, seconds=20, smoothed=True,
                        excess=excess, after=after)
    assert seen["delivered"] >= 0.99 * capacity * (20 - after)
    assert seen["dropped"] <= drops * seen["delivered"]
    settled = rates[len(rates) // 3:]
    assert max(settled) * (1 + excess) <= 1.1 * capacity


@pytest.mark.parametrize(("seconds", "busy"), [(0.5, 0.97), (1.0, 0.97), (2.0, 0.95),
                                               (4.0, 0.75)])
def test_after_a_stall_the_radio_is_soon_busy_again(seconds, busy):
    """A path that carries nothing for a while with its queue full reads as a full radio
    that delivers nothing: following that delivery took the rate to a tenth of the
    radio's, and the climb back took longer than most transfers. A stall of up to
    ``hold`` leaves the rate where it was; a longer one takes it down by at most 15 % a
    step (a radio that really carries less) and the climb back takes a little longer:
    over the 4.5 s from half a second after the path carries again, the radio is busy
    ``busy`` of the time (the code that followed the delivery down: a fifth or less
    after a stall of two seconds or more)."""
    end = 5.0 + seconds
    rates, seen = radio(RateProbe(), 10e6, 0.0, seconds=end + 5, smoothed=True,
                        after=end + 0.5, stall=(5.0, seconds))
    assert seen["delivered"] >= busy * 10e6 * 4.5
    if seconds <= RateProbe.hold:
        assert min(rates) >= 0.5 * 10e6


@pytest.mark.parametrize(("capacity", "loss", "busy"), [(10e6, 0.0, 0.8), (10e6, 0.02, 0.75),
                                                      (50e6, 0.0, 0.45)])
def test_a_start_cut_short_does_not_leave_the_rate_crawling(capacity, loss, busy):
    """A tenth of a second in which the path carries nothing ends the start at 5-6
    Mbit/s. With no queue after it, the rate grew only as fast as the delivery it lags
    (a step takes it at most 5 % above the last second's): at 2 % loss it was still
    under 7 Mbit/s on a 10 Mbit/s radio 6 s later (over the first 8 s the radio was
    busy 71 % of the time without loss, 62 % at 2 % loss, and 16 % at 50 Mbit/s). Once
    the radio shows no queue for a second while the delivery grows, the delivery follows
    the rate and the rate climbs without waiting for it."""
    _, seen = radio(RateProbe(), capacity, loss, seconds=8, smoothed=True, after=0.0,
                    stall=(0.25, 0.1))
    assert seen["delivered"] >= busy * capacity * (1 - loss) * 8


@pytest.mark.parametrize("loss", [0.0, 0.02])
def test_a_smoothed_round_trip_that_lags_the_queue_does_not_idle_the_radio(loss):
    """UDT smooths its round trip at both ends, so it says a draining queue a few tenths
    of a second late (on the emulated radio the answers to manifests showed a queue gone
    while the smoothed round trip still said 9-16 ms). Read alone, it held the rate under
    the radio's after the start's first queue, and then above it: with a lag of 0.3 s the
    radio idled 0.25 s (0.32 s at 2 % loss) from 1 s to 8 s and the rate reached 1.5 (1.7)
    times the radio's. The answers waited behind the queue as it stood, so the least of
    them and the smoothed round trip says the queue."""
    capacity = 10e6
    rates, seen = radio(RateProbe(), capacity, loss, seconds=8, smoothed=True, lag=0.3)
    assert seen["idle"] <= 0.1
    assert max(rates[len(rates) // 3:]) <= 1.1 * capacity


@pytest.mark.parametrize(("rate", "sending", "share"), [
    (9.6e6, 16, 0.6e6), (9.6e6, 3, 3.2e6), (9.6e6, 0, 9.6e6)])
def test_lane_share(rate, sending, share):
    assert lane_share(rate, sending) == pytest.approx(share)


def test_the_last_lanes_share_the_rate_by_what_each_has_left_and_finish_together():
    """Once no segment is left to hand out, a lane with three times the bytes left gets
    three times the rate, the shares add up to the rate, and so every lane's last byte
    leaves at the same moment: the radio is not left to one slow lane at the end."""
    left = [300_000, 100_000, 100_000]
    shares = final_shares(9.6e6, left)
    assert sum(shares) == pytest.approx(9.6e6)
    finish = [bytes_left * 8 / share for bytes_left, share in zip(left, shares, strict=True)]
    assert max(finish) == pytest.approx(min(finish))
    # equal shares would have left the first lane alone on the radio for its last 2/3
    assert max(finish) < 300_000 * 8 / lane_share(9.6e6, 3)


@pytest.mark.parametrize(("left", "least"), [
    ([1_000_000, 0], 9.6e6 / 2 / 4),   # nothing counted as left: still a quarter share
    ([0, 0], 9.6e6 / 2),               # nothing known: even shares
    ([-5, 10], 9.6e6 / 2 / 4)])        # a count ahead of the segment's length
def test_no_last_lane_is_starved_by_a_count_that_lags(left, least):
    assert min(final_shares(9.6e6, left)) == pytest.approx(least)


@pytest.mark.parametrize(("ceilings", "shares"), [
    # none held back: even shares
    ([0.6e6] * 4 + [None] * 12, [0.6e6] * 16),
    # four held back to a quarter of theirs: they keep an even share to climb back into,
    # the other twelve take what they leave
    ([0.15e6] * 4 + [0.6e6] * 12, [0.6e6] * 4 + [0.75e6] * 12),
    # all held back: nobody to take more
    ([0.3e6] * 16, [0.6e6] * 16),
    # fifteen held back to nothing: the last one takes at most as much again
    ([0.0] * 15 + [0.6e6], [0.6e6] * 15 + [1.2e6]),
])
def test_lanes_held_back_by_udt_leave_their_share_to_the_others(ceilings, shares):
    """At 2 % loss UDT's loss reaction held two to five of sixteen lanes to a fifth to
    four fifths of their share, and an even split left that part of the rate unsent
    (the radio idled while the rate probe saw no queue). What the lanes can send
    together comes to the rate again, unless too many are held back."""
    got = filled_shares(9.6e6, ceilings)
    assert got == pytest.approx(shares)
    held = [c is not None and c < 0.9 * 0.6e6 for c in ceilings]
    if 0 < sum(held) <= 4:
        sent = sum(c if h else cap for cap, c, h in zip(got, ceilings, held, strict=True))
        assert sent == pytest.approx(9.6e6)


class _Lane:
    """What :class:`SharedRate` reads of a lane's sender, for one connection at a time."""

    def __init__(self) -> None:
        self.conn, self.sent, self.again = object(), 0, 0

    def round_trip(self) -> None:
        return None

    def ceiling(self) -> None:
        return None

    def packets(self) -> tuple[object, int, int]:
        return self.conn, self.sent, self.again


def test_the_lanes_packets_sent_again_reach_the_probe_across_reconnections():
    """Each connection counts from its opening: what a lane sent before it reconnected
    is counted once, and its new connection's from zero."""
    shared = SharedRate()
    one, two = _Lane(), _Lane()
    lanes = {1: one, 2: two}
    one.sent, one.again, two.sent, two.again = 100, 2, 100, 3
    shared.caps(0.0, 0, lanes, lanes)
    one.sent, one.again = 300, 60
    two.conn, two.sent, two.again = object(), 50, 40  # reconnected
    shared.caps(0.05, 0, lanes, lanes)
    assert shared.control.resent_share() == pytest.approx((60 + 43) / (300 + 150))
