"""How fast all lanes of one transfer send together, from the queue they build at the
radio. Pure logic: the caller passes the clock, round trips and acknowledged bytes.

UDT's own congestion control reads every radio loss as congestion, and parallel lanes,
each unaware of the others, over-run the radio's queue together (the tail drops cost
each lane another back-off). So the lanes are paced as one, at a rate found the way
delay-based congestion control finds it: the round trip of each segment's manifest and
its answer waits behind whatever the radio has queued. Its least value is the path's
own delay (``base``); every ``step`` seconds the least round trip of that step says
whether a queue stands. Below ``room`` seconds of queueing the rate goes up by ``up``
(by ``startup`` until the first queue is seen, or until three steps in a row deliver
less than ``growth`` times the best so far). Above ``full`` the radio is full: the
rate goes down by ``drain`` (the first time from what the receiver acknowledged over
the last two steps, which is what the radio carries, if that is less).
In between it holds - a short queue keeps the radio busy without overflowing it. Random
radio loss delays only some answers, a full queue all of them, so the least value
tells the two apart, given two answers or more in each of two steps in a row (four
right after a step down: the queue takes a while to drain). While
lanes do not use their share (UDT's own back-off after losses), the rate stays within
``lead`` times what the receiver acknowledged (``ahead`` times during the start), so
they cannot all take a piled-up rate at once. The rate never falls below
``floor_bps``; with a budget it stays between ``near`` times the budget and the budget
(the budget is the operator's word on what the radio carries for bulk data: the
receiver's own delays in answering must not undercut it; below that, UDT's own
back-off still answers real congestion).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field


@dataclass
class RateProbe:
    """The pacing rate (bit/s of file data) for the lanes of one transfer."""

    step: float = 0.25
    span: float = 1.0
    initial_bps: float = float(__import__("os").environ.get("XINIT", 4e6))
    startup: float = 1.3
    growth: float = 1.1
    up: float = 1.04
    drain: float = 0.95
    room: float = 0.006
    full: float = 0.020
    ahead: float = 2.0
    lead: float = 1.05
    near: float = 0.8
    target: float = float(__import__("os").environ.get("XTARGET", 0.015))
    window: float = 2.0
    settle: float = 0.5
    cut: float = 0.85
    floor_bps: float = 256e3
    budget_bps: float | None = None
    rate_bps: float = 0.0
    base: float | None = None
    #: queueing delay (s) seen in the last step
    queued: float = 0.0
    #: "startup" until the first standing queue, then "paced"
    phase: str = "startup"
    #: every rate change: (time, rate in bit/s, phase)
    history: list[tuple[float, float, str]] = field(default_factory=list)
    _least: float | None = None
    _marks: deque[tuple[float, int]] = field(default_factory=deque)
    _next: float | None = None
    _answers: int = 0
    _full_steps: int = 0
    _best: float = 0.0
    _flat: int = 0
    _smoothed: float | None = None
    _dense: bool = False
    _paced_at: float = 0.0
    _peaks: deque[tuple[float, float]] = field(default_factory=deque)

    def __post_init__(self) -> None:
        if not 0 < self.step <= self.span or self.initial_bps <= 0 or not self.room < self.full:
            raise ValueError("rate probe: need 0 < step <= span, a positive initial rate "
                             "and room < full")
        self._set(self._clamp(self.initial_bps), 0.0)

    def round_trip(self, seconds: float) -> None:
        """A manifest's answer came ``seconds`` after the manifest left."""
        if seconds <= 0:
            return
        self.base = seconds if self.base is None else min(self.base, seconds)
        self._least = seconds if self._least is None else min(self._least, seconds)
        self._answers += 1

    def smoothed(self, seconds: float) -> None:
        """The lanes' connections' own smoothed round trip, now (the least of theirs):
        no loss delays it, so the latest says the queue as it stands."""
        if seconds <= 0:
            return
        self.base = seconds if self.base is None else min(self.base, seconds)
        self._smoothed = seconds
        self._dense = True

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
        while self._peaks and now - self._peaks[0][0] > self.window:
            self._peaks.popleft()
        return max((rate for _, rate in self._peaks), default=0.0)

    def sample(self, now: float, acknowledged: int) -> float:
        """Feed the bytes acknowledged so far at ``now``; return the rate to pace at."""
        self._marks.append((now, acknowledged))
        while len(self._marks) > 2 and now - self._marks[1][0] >= self.span:
            self._marks.popleft()
        if self._next is None:
            self._next = now + self.step
        if now < self._next:
            return self.rate_bps
        # The start grows in half steps when the lanes' own round trips say the queue
        # at once: the first queue is seen before it overflows.
        fine = self.phase == "startup" and (self._dense or bool(__import__("os").environ.get("XFINE")))
        self._next = now + (self.step / 2 if fine else self.step)
        least, answers, self._least, self._answers = self._least, self._answers, None, 0
        smoothed, self._smoothed = self._smoothed, None
        if self.base is None or (least is None and smoothed is None):
            return self.rate_bps  # no round trip this step: nothing learnt
        # A smoothed round trip is as good as many answers: no lost packet delays it.
        self.queued = (least if smoothed is None else smoothed) - self.base
        sure = smoothed is not None or answers >= 2
        rate, delivered = self.rate_bps, self.delivered_bps()
        peak = self.peak_bps(now)
        at_budget = bool(self.budget_bps) and delivered >= self.near * (self.budget_bps or 0)
        standing = self.queued >= self.full and sure and not at_budget
        self._full_steps = self._full_steps + 1 if standing else 0
        if self.phase == "startup" and delivered and not at_budget:
            if delivered > self._best * self.growth:
                self._best, self._flat = delivered, 0
            else:
                self._flat += 1
        if self.phase == "startup" and self._flat >= (6 if fine else 3):
            # Delivery stopped growing with the rate: the radio is full (a queue too
            # short to show in the round trips).
            self.phase, self._full_steps, self._paced_at = "paced", 0, now
            rate = self.drain * min(rate, self._best)
        elif self.phase == "startup" and (self._full_steps or (
                smoothed is not None and self.queued > self.room and not at_budget)):
            # A queue: the radio is full; what it delivered lately is what it carries.
            self.phase, self._full_steps, self._paced_at = "paced", 0, now
            rate = min(rate, peak or delivered or rate) * self._toward_target()
        elif self.phase == "paced" and sure and self.queued > self.room and not at_budget:
            # The radio is full, so it delivers what it carries: pace at that, a little
            # less while the queue stands above the target, a little more below it.
            # (over what came since the start ended, at least two steps)
            since = self.delivered_bps(min(self.span, max(2 * self.step, now - self._paced_at)))
            if now - self._paced_at < self.span and __import__("os").environ.get("XPEAK"):
                since = max(since, peak)
            rate = (since or delivered or rate) * self._toward_target()
        elif self.queued <= self.room:
            rate *= (self.startup ** 0.5 if fine else self.startup) \
                if self.phase == "startup" else self.up
            if self.phase == "startup" and delivered:
                rate = min(rate, max(self.initial_bps, self.ahead * delivered))
            elif delivered:  # within reach of what the lanes deliver now, and back at
                # once to what the radio carried lately
                rate = max(min(rate, self.lead * delivered), peak, self.floor_bps)
        return self._set(self._clamp(rate), now)

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
