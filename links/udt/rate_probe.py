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
    initial_bps: float = 4e6
    startup: float = 1.3
    growth: float = 1.1
    up: float = 1.04
    drain: float = 0.95
    room: float = 0.006
    full: float = 0.020
    ahead: float = 2.0
    lead: float = 1.05
    near: float = 0.8
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

    def sample(self, now: float, acknowledged: int) -> float:
        """Feed the bytes acknowledged so far at ``now``; return the rate to pace at."""
        self._marks.append((now, acknowledged))
        while len(self._marks) > 2 and now - self._marks[1][0] >= self.span:
            self._marks.popleft()
        if self._next is None:
            self._next = now + self.step
        if now < self._next:
            return self.rate_bps
        self._next = now + self.step
        least, answers, self._least, self._answers = self._least, self._answers, None, 0
        if least is None or self.base is None:
            return self.rate_bps  # no answer this step: nothing learnt
        self.queued = least - self.base
        rate, delivered = self.rate_bps, self.delivered_bps()
        at_budget = bool(self.budget_bps) and delivered >= self.near * (self.budget_bps or 0)
        standing = self.queued >= self.full and answers >= 2 and not at_budget
        self._full_steps = self._full_steps + 1 if standing else 0
        if self.phase == "startup" and delivered and not at_budget:
            if delivered > self._best * self.growth:
                self._best, self._flat = delivered, 0
            else:
                self._flat += 1
        if self.phase == "startup" and self._flat >= 3:
            # Delivery stopped growing with the rate: the radio is full (a queue too
            # short to show in the round trips).
            self.phase, self._full_steps = "paced", 0
            rate = self.drain * min(rate, self._best)
        elif self._full_steps >= (1 if self.phase == "startup" else 2):
            # A standing queue: the radio is full; what it delivered is what it carries.
            if self.phase == "startup":  # what the radio carried since it filled up
                recent = self.delivered_bps(2 * self.step)
                self.phase, rate = "paced", min(rate, recent or delivered or rate)
            # The queue takes a while to drain: the next step down needs two more
            # queued steps in a row than this one did.
            self._full_steps = -2
            rate *= self.drain
        elif self.queued <= self.room:
            rate *= self.startup if self.phase == "startup" else self.up
            if self.phase == "startup" and delivered:
                rate = min(rate, max(self.initial_bps, self.ahead * delivered))
            elif delivered:
                rate = min(rate, max(self.floor_bps, self.lead * delivered))
        return self._set(self._clamp(rate), now)

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
