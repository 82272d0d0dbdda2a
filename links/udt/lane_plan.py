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

from links.udt.protocol import MAX_SEGMENTS

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
