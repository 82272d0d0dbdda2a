"""How fast all lanes of one transfer send together, from the queue they build at the
radio and what the receiver acknowledges. Pure logic: the caller passes the clock, round
trips and acknowledged bytes.

UDT's own congestion control reads every radio loss as congestion, and parallel lanes,
each unaware of the others, over-run the radio's queue together (the tail drops cost
each lane another back-off). So the lanes are paced as one, at a rate found the way
delay-based congestion control finds it: a round trip waits behind whatever the radio
has queued, and its least value is the path's own delay (``base``). Two kinds of round
trip come in: the lanes' connections' own smoothed round trip (:meth:`smoothed`, read
every look at the lanes: dense, and no lost packet delays it), and the answers to the
segments' manifests (:meth:`round_trip`, a few a second; a lost packet delays some of
them, a full queue all of them, so the least of two or more says the queue). UDT
smooths its round trip at both ends, so it says a draining queue a few tenths of a
second late; each answer waited behind the queue as it stood, so a step's queue is the
least of its answers and the smoothed round trip.

* The start: from ``initial_bps``, up by ``startup`` every ``startup_step`` seconds while
  no queue shows, within ``ahead`` times what the receiver acknowledged. It ends at the
  first queue (``room`` seconds by the smoothed round trip, ``full`` by two answers or
  more), or when delivery stops growing by ``growth`` for three quarters of a second.
* Then, while a queue stands, the radio is full and delivers what it carries: the rate
  is that delivery times a factor that brings the queue to ``target`` seconds within
  about ``settle`` seconds (between ``cut`` and ``lead``). Right after the start the
  delivery is taken over the last two steps, or the most delivered over two steps
  lately if more (a lane held back by the start's losses does not pull it down); after
  that, a step takes at most ``cut`` off the rate itself, however late the delivery.
* A queue while the radio delivers less than ``stall`` times what it carried over the
  last ``memory`` seconds (:meth:`carried_bps`) is no full radio but a stall: a busy
  machine at either end or a dead spell on the path holds the data back and inflates
  the round trips, which then lag the stall by half a second. The rate holds for up to
  ``hold`` seconds, then follows by at most ``cut`` a step (a radio that really carries
  less): followed at once, it reached a tenth of the radio's within two seconds and took
  longer than most transfers to climb back.
* While no queue stands the radio has room: up by ``up`` a step within ``lead`` times
  what the receiver acknowledged (lanes held back by UDT's own loss reaction must not
  all take a piled-up rate at once), and at once back to the most the radio delivered
  lately (:meth:`peak_bps`) rather than by a creep; within ``memory`` seconds of a
  stall, also up as fast as the start climbs, as far as the radio carried before it.
  Once no queue has shown for ``span`` seconds while the delivery grew by ``grow`` over
  them, the delivery follows the rate, and a second's delivery lagging a rising rate
  would hold it to a crawl (a start cut short by a late reading left it at 5-7 Mbit/s
  for seconds on a 10 Mbit/s radio): up by ``climb`` a step, not waiting for it.

* The lanes' connections do not slow down for losses (:mod:`links.udt.udt_cc`), so a
  rate above the radio's is also read from the packets they send again: more than
  ``overrun`` of a step's (at least ``counted`` packets; several times what a radio losing
  2 % each way costs) is no lossy radio but its queue dropping the excess. The start
  ends, and the rate comes down by ``cut`` a step while it lasts (cut at once to what the
  receiver acknowledged, the queue drops of a start left it far below the radio's for a
  while). Without it, once in a dozen pushes at 2 % loss the start ran on to 14 Mbit/s
  and the lanes' resent packets took the radio for seconds.

The rate never falls below ``floor_bps``; with a budget it stays between ``near`` times
the budget and the budget (the budget is the operator's word on what the radio carries
for bulk data: the receiver's own delays in answering must not undercut it; below that,
UDT's own back-off still answers real congestion).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass
class RateProbe:
    """The pacing rate (bit/s of file data) for the lanes of one transfer."""

    step: float = 0.25
    startup_step: float = 0.125
    span: float = 1.0
    initial_bps: float = 6e6
    startup: float = 1.14
    growth: float = 1.1
    up: float = 1.04
    climb: float = 1.14
    grow: float = 1.05
    drain: float = 0.95
    room: float = 0.006
    full: float = 0.020
    ahead: float = 2.0
    lead: float = 1.05
    near: float = 0.8
    target: float = 0.005
    window: float = 2.0
    memory: float = 10.0
    stall: float = 0.5
    hold: float = 1.0
    settle: float = 0.35
    cut: float = 0.85
    overrun: float = 0.15
    counted: int = 64
    floor_bps: float = 256e3
    budget_bps: float | None = None
    rate_bps: float = 0.0
    base: float | None = None
    #: queueing delay (s) seen in the last step
    queued: float = 0.0
    #: "startup" until the first queue, then "paced"
    phase: str = "startup"
    #: every rate change: (time, rate in bit/s, phase)
    history: list[tuple[float, float, str]] = field(default_factory=list)
    _least: float | None = None
    _marks: deque[tuple[float, int]] = field(default_factory=deque)
    _next: float | None = None
    _answers: int = 0
    _best: float = 0.0
    _flat: int = 0
    _smoothed: float | None = None
    _paced_at: float = 0.0
    _peaks: deque[tuple[float, float]] = field(default_factory=deque)
    _stalled: float | None = None
    _stall_began: float | None = None
    _clear_since: float | None = None
    _deliveries: deque[tuple[float, float]] = field(default_factory=deque)
    _sent: int = 0
    _resent: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.startup_step <= self.step <= self.span or self.initial_bps <= 0 \
                or not self.room < self.full:
            raise ValueError("rate probe: need 0 < startup_step <= step <= span, a positive "
                             "initial rate and room < full")
        self._set(self._clamp(self.initial_bps), 0.0)

    def round_trip(self, seconds: float) -> None:
        """A manifest's answer came ``seconds`` after the manifest left."""
        if seconds <= 0:
            return
        self.base = seconds if self.base is None else min(self.base, seconds)
        self._least = seconds if self._least is None else min(self._least, seconds)
        self._answers += 1

    def sent(self, packets: int, again: int) -> None:
        """The lanes sent ``packets`` data packets since the last call, ``again`` of them
        sent again (lost on the way)."""
        self._sent += packets
        self._resent += again

    def resent_share(self) -> float | None:
        """Of the data packets sent since the last step, the part sent again; None below
        ``counted`` packets (too few to say)."""
        return self._resent / self._sent if self._sent >= self.counted else None

    def smoothed(self, seconds: float) -> None:
        """The lanes' connections' own smoothed round trip, now (the least of theirs):
        no loss delays it, so the latest says the queue as it stands."""
        if seconds <= 0:
            return
        self.base = seconds if self.base is None else min(self.base, seconds)
        self._smoothed = seconds

    def delivered_bps(self, over: float | None = None) -> float:
        """Acknowledged bit/s over the last ``over`` seconds (``span`` by default; 0
        before half of that is seen)."""
        over = over or self.span
        now, last = self._marks[-1]
        since, before = next(((t, a) for t, a in reversed(self._marks) if now - t >= over),
                             self._marks[0])
        if now - since < over / 2:
            return 0.0
        return max(0, last - before) * 8 / (now - since)

    def peak_bps(self, now: float) -> float:
        """The most the receiver acknowledged in two steps within the last ``window``
        seconds: once the radio was full, what it carries (a lane held back by a loss
        does not lower it)."""
        recent = self.delivered_bps(2 * self.step)
        if recent:
            self._peaks.append((now, recent))
        while self._peaks and now - self._peaks[0][0] > max(self.window, self.memory):
            self._peaks.popleft()
        return self._second(now, self.window)

    def carried_bps(self, now: float) -> float:
        """As :meth:`peak_bps` (after it), over the last ``memory`` seconds."""
        return self._second(now, self.memory)

    def _second(self, now: float, over: float) -> float:
        # the second most: one sample that caught a burst of late acknowledgements is
        # not the radio's rate
        ranked = sorted(rate for at, rate in self._peaks if now - at <= over)
        return ranked[-2] if len(ranked) > 1 else 0.0

    def sample(self, now: float, acknowledged: int) -> float:
        """Feed the bytes acknowledged so far at ``now``; return the rate to pace at."""
        self._marks.append((now, acknowledged))
        while len(self._marks) > 2 and now - self._marks[1][0] >= self.span:
            self._marks.popleft()
        if self._next is None:
            self._next = now + self.step
        if now < self._next:
            return self.rate_bps
        starting = self.phase == "startup"
        self._next = now + (self.startup_step if starting else self.step)
        least, answers, self._least, self._answers = self._least, self._answers, None, 0
        smoothed, self._smoothed = self._smoothed, None
        resent = self.resent_share()
        if resent is not None:  # judged: count afresh (too few carry over)
            self._sent = self._resent = 0
        if self.base is None or (least is None and smoothed is None):
            return self.rate_bps  # no round trip this step: nothing learnt
        self.queued = min(trip for trip in (least, smoothed) if trip is not None) - self.base
        rate, delivered = self.rate_bps, self.delivered_bps()
        peak = self.peak_bps(now)
        at_budget = bool(self.budget_bps) and delivered >= self.near * (self.budget_bps or 0)
        queue = not at_budget and (self.queued > self.room if smoothed is not None
                                   else self.queued >= self.full and answers >= 2)
        self._deliveries.append((now, delivered))
        while now - self._deliveries[0][0] > 2 * self.span:
            self._deliveries.popleft()
        if self.queued > self.room:
            self._clear_since = None
        elif self._clear_since is None:
            self._clear_since = now
        if starting and delivered and not at_budget:
            if delivered > self._best * self.growth:
                self._best, self._flat = delivered, 0
            else:
                self._flat += 1
        if resent is not None and resent > self.overrun:
            # The lanes send more of their packets again than a lossy radio loses: the
            # radio's queue drops what they send beyond what it carries (their
            # connections do not slow down for losses: links.udt.udt_cc).
            self.phase = "paced"
            if starting:
                self._paced_at = now
            rate *= self.cut
        elif starting and self._flat * self.startup_step >= 3 * self.step:
            # Delivery stopped growing with the rate: the radio is full (a queue too
            # short to show in the round trips).
            self.phase, self._paced_at = "paced", now
            rate = self.drain * min(rate, self._best)
        elif starting and queue:
            # The first queue: the radio is full and carried what it delivered lately.
            self.phase, self._paced_at = "paced", now
            rate = min(rate, peak or delivered or rate) * self._toward_target()
        elif queue:
            # Full: pace at what the radio delivers (over what came since the start
            # ended, at least two steps), less while the queue stands above the target.
            since = self.delivered_bps(min(self.span, max(2 * self.step, now - self._paced_at)))
            # A queue while the radio carries under half of what it carried lately is no
            # full radio but a stall (a busy machine, a dead spell on the path), and the
            # round trips it inflated lag it by half a second: following the delivery
            # down would leave the rate there for seconds.
            stalled = since < self.stall * self.carried_bps(now)
            began = self._stall_began if stalled and self._stall_began is not None else now
            self._stall_began = began if stalled else None
            if now - self._paced_at < self.span:  # still covering the start's losses
                rate = max(since, peak) * self._toward_target()
            else:
                if stalled:
                    self._stalled = now
                if not stalled or now - began >= self.hold:  # held for up to ``hold``,
                    # then by at most ``cut`` a step, however late the delivery
                    rate = max((since or delivered or rate) * self._toward_target(),
                               self.cut * rate)
        elif self.queued <= self.room:
            if starting:
                rate *= self.startup
                if delivered:
                    rate = min(rate, max(self.initial_bps, self.ahead * delivered))
            elif delivered:
                if self._roomy(now):  # delivery follows the rate: no need to wait for it
                    rate *= self.climb
                else:
                    rate = min(rate * self.up, self.lead * delivered)
                rate = max(rate, peak, self.floor_bps)
                if self._stalled is not None and now - self._stalled <= self.memory:
                    # after a stall: back up as the start climbs, as far as the radio
                    # carried before it
                    rate = max(rate, min(self.rate_bps * self.startup ** (
                        self.step / self.startup_step), self.carried_bps(now)))
            else:
                rate *= self.up
        return self._set(self._clamp(rate), now)

    def _roomy(self, now: float) -> bool:
        """Whether the radio has shown no queue for ``span`` seconds while the delivery
        grew by ``grow`` over it: the rate, not the radio, holds the delivery back."""
        if self._clear_since is None or now - self._clear_since < self.span:
            return False
        before = next((d for t, d in self._deliveries if now - t <= self.span), 0.0)
        return before > 0 and self._deliveries[-1][1] >= self.grow * before

    def _toward_target(self) -> float:
        """The factor on what the radio delivers that brings the queue to ``target``
        seconds within about ``settle`` seconds."""
        return min(self.lead, max(self.cut, 1 + (self.target - self.queued) / self.settle))

    def _clamp(self, rate: float) -> float:
        if self.budget_bps:  # the operator's word on what the radio carries for bulk data
            return min(max(rate, self.near * self.budget_bps, self.floor_bps), self.budget_bps)
        return max(rate, self.floor_bps)

    def _set(self, rate: float, now: float) -> float:
        if rate != self.rate_bps:
            self.rate_bps = rate
            self.history.append((now, rate, self.phase))
        return rate


def lane_share(rate_bps: float, sending: int) -> float:
    """Each sending lane's cap so that together they keep to ``rate_bps``."""
    return rate_bps / max(1, sending)


HELD = 0.9
"""A lane whose connection UDT lets send under this part of an even share is held back
by UDT's own loss reaction (:func:`filled_shares`)."""


def filled_shares(rate_bps: float, ceilings: Sequence[float | None]) -> list[float]:
    """Each sending lane's cap when some are held back: UDT's congestion control reads
    every radio loss as congestion and slows a connection below its share (at 2 % loss,
    two to five of sixteen lanes at a fifth to four fifths of theirs), and an even
    split left that part of the rate unsent while the radio idled. ``ceilings``: the
    file bit/s UDT lets each lane send now (None: not known). A lane held back (under
    ``HELD`` of an even share) keeps an even share to climb back into; what it leaves
    goes to the others, at most as much again as an even share each (lanes held back
    that recover together must not pile more than that onto the radio before the next
    look at the lanes)."""
    even = lane_share(rate_bps, len(ceilings))
    held = [c is not None and c < HELD * even for c in ceilings]
    free = len(ceilings) - sum(held)
    if not free or free == len(ceilings):
        return [even] * len(ceilings)
    spare = sum(even - c for c, h in zip(ceilings, held, strict=True) if h and c is not None)
    more = even + min(even, spare / free)
    return [even if h else more for h in held]


def final_shares(rate_bps: float, remaining: Sequence[int]) -> list[float]:
    """Each sending lane's cap once no segment is left to hand out: in proportion to the
    bytes it has still to deliver, so that the lanes finish together. With even shares
    the lanes finish one by one and the last few, each held to its share until the next
    look at the lanes, leave the radio idle at the very end. No lane gets less than a
    quarter of an even share (a count that lags must not stall it)."""
    even = lane_share(rate_bps, len(remaining))
    total = sum(max(0, left) for left in remaining)
    if total <= 0:
        return [even] * len(remaining)
    return [max(even / 4, rate_bps * max(0, left) / total) for left in remaining]
