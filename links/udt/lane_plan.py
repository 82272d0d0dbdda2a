"""How many parallel lanes the next fetch uses, learnt from the fetches before. Pure logic.

UDT reads random radio loss as congestion, so one connection settles far below a lossy
link's rate; parallel lanes each settle there and add up. How many pay off depends on
the loss and delay of that radio, which nobody configuring a relay knows. So the plan
climbs: it starts at ``start`` lanes, and after each file it compares that file's
goodput with the best seen at other lane counts - one more lane while each added lane
raised goodput by at least ``gain``, one fewer when the last one did not. Files too small to split
(``min_lane_bytes`` per lane) go on one lane and teach nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from links.udt.protocol import MAX_LANES, MAX_SEGMENTS

MIN_LANE_BYTES = 1 << 20


@dataclass
class LanePlan:
    """Lane count for the next file; :meth:`observe` feeds back each file's goodput."""

    start: int = 4
    maximum: int = 12
    gain: float = 0.05
    min_lane_bytes: int = MIN_LANE_BYTES
    current: int = 0
    #: best goodput (bytes/s) seen per lane count
    seen: dict[int, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not 1 <= self.start <= self.maximum:
            raise ValueError("lanes: need 1 <= start <= maximum")
        self.current = self.current or self.start

    def lanes_for(self, size: int) -> int:
        """Lanes for a file of ``size`` bytes."""
        return max(1, min(self.current, size // self.min_lane_bytes))

    def observe(self, lanes: int, size: int, seconds: float) -> int:
        """Record a file sent on ``lanes`` lanes; return the lane count for the next one."""
        if lanes != self.current or seconds <= 0 or size < lanes * self.min_lane_bytes:
            return self.current
        rate = size / seconds
        self.seen[lanes] = max(rate, self.seen.get(lanes, 0.0))
        up, down = self.seen.get(lanes + 1), self.seen.get(lanes - 1)
        if down is not None and rate < down * (1 + self.gain):
            self.current = lanes - 1  # the last lane added did not pay: go back
        elif up is None and lanes < self.maximum and (down is None or
                                                      rate > down * (1 + self.gain)):
            self.current = lanes + 1  # still climbing: try one more
        elif up is not None and up > rate * (1 + self.gain):
            self.current = lanes + 1
        return self.current


# --------------------------------------------------------------------------- within a transfer

SEGMENT_BYTES = 64 * 1024
"""Smallest segment worth a manifest/receipt exchange of its own (two round trips)."""
SPLIT_BYTES = 1 << 20
"""Smaller files go whole on one connection: kept open across a batch, it is already
past UDT's slow start, which new lanes would each pay again."""


def segments_for(size: int, maximum: int = MAX_SEGMENTS) -> int:
    """How many segments a file of ``size`` bytes is cut into: a function of the size
    only, so a transfer resumed with another lane count finds its segments in the spool."""
    if size < SPLIT_BYTES:
        return 1
    return max(1, min(maximum, size // SEGMENT_BYTES))


@dataclass
class LaneController:
    """How many lanes a transfer runs now, from the queueing delay it observes.

    Each lane is a UDT connection taking the file's segments one after another. UDT
    slows a connection down at every loss, so on a lossy radio one lane moves a fraction
    of the link and lanes add up; on a clean link one or two fill it and more only
    queue. Nobody knows which radio this is, so the controller watches the one thing
    that tells a full link from a lossy one: the round trip of each segment's manifest
    and its answer, which waits behind the data queued at the radio. Its minimum is the
    path's own delay (``base``); while the least round trip of a ``window`` stays within
    ``room`` of it the link has room and the controller adds lanes (half as many again);
    once it stands ``full`` above it, the queue is standing and one lane goes. Goodput
    (bytes the receiver acknowledged) is measured per window too: with a budget the
    climb stops within ``near`` of it (pacing keeps the lanes there). Noisy samples do
    not matter: a full link delays every answer, a lossy one only some.
    Pure: the caller passes the clock, the round trips and the acknowledged bytes.
    """

    start: int = 8
    maximum: int = MAX_LANES
    window: float = 1.0
    settle: float = 0.5
    room: float = 0.25
    full: float = 0.75
    floor: float = 0.010
    near: float = 0.92
    budget_bps: float | None = None
    lanes: int = 0
    base: float | None = None
    #: every change: (time, lanes from then on, goodput of the window before in bytes/s)
    history: list[tuple[float, int, float]] = field(default_factory=list)
    _changed_at: float | None = None
    _mark: tuple[float, int] | None = None
    _least: float | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.start <= self.maximum:
            raise ValueError("lanes: need 1 <= start <= maximum")
        self.lanes = self.lanes or self.start

    def round_trip(self, seconds: float) -> None:
        """A manifest's answer came ``seconds`` after the manifest left."""
        if seconds <= 0:
            return
        self.base = seconds if self.base is None else min(self.base, seconds)
        self._least = seconds if self._least is None else min(self._least, seconds)

    def sample(self, now: float, acknowledged: int) -> int:
        """Feed the bytes acknowledged so far at ``now``; return the lanes to run."""
        if self._changed_at is None:
            self._changed_at = now
        if now - self._changed_at < self.settle:
            self._least = None  # round trips of the lanes before the change
            return self.lanes
        if self._mark is None:
            self._mark = (now, acknowledged)
            return self.lanes
        since, before = self._mark
        if now - since < self.window:
            return self.lanes
        rate = (acknowledged - before) / (now - since)
        self._mark, least, self._least = (now, acknowledged), self._least, None
        if least is None or self.base is None:
            return self.lanes  # no segment started in the window: nothing learnt
        queued = least - self.base
        if self.budget_bps and rate * 8 >= self.near * self.budget_bps:
            return self.lanes
        if queued <= max(self.floor, self.room * self.base) and self.lanes < self.maximum:
            return self._set(self.lanes + max(1, self.lanes // 2), now, rate)
        if queued >= max(2 * self.floor, self.full * self.base) and self.lanes > 1:
            return self._set(self.lanes - 1, now, rate)
        return self.lanes

    def _set(self, lanes: int, now: float, rate: float) -> int:
        self.lanes = max(1, min(self.maximum, lanes))
        self._changed_at, self._mark, self._least = now, None, None
        self.history.append((now, self.lanes, rate))
        return self.lanes


@dataclass
class Pace:
    """A rate budget shared by all lanes of a transfer: how long to wait before handing
    ``n`` more bytes to UDT so that together they keep to ``rate_bps`` (with up to
    ``burst`` bytes ahead). Pure: the caller passes the clock and does the waiting."""

    rate_bps: float
    burst: int = 128 * 1024
    _due: float = 0.0

    def delay(self, n: int, now: float) -> float:
        """Seconds to wait before sending ``n`` bytes (and count them as sent then)."""
        allowance = self.burst * 8 / self.rate_bps
        self._due = max(self._due, now)
        wait = max(0.0, self._due - now - allowance)
        self._due += n * 8 / self.rate_bps
        return wait


def straggler(started: dict[int, float], durations: list[float], now: float,
              factor: float = 2.0, least: float = 1.0) -> int | None:
    """Which lane's segment to send again on a fresh connection once nothing is left to
    hand out: the one running longest, if it has taken ``factor`` times the median
    segment so far (and at least ``least`` seconds). A lane stalls when UDT loses the
    last packets of a segment and waits for its retransmission timer; the whole file
    waits for that lane. ``started``: lane -> when its current segment began."""
    if not started or not durations:
        return None
    ordered = sorted(durations)
    median = ordered[len(ordered) // 2]
    lane, since = min(started.items(), key=lambda item: item[1])
    return lane if now - since > max(least, factor * median) else None
