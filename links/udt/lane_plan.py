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
