"""How a file is cut into segments for parallel lanes, a budget shared by the lanes, and
which stalled segment to send again. Pure logic.
"""

from __future__ import annotations

from dataclasses import dataclass

from links.udt.protocol import MAX_SEGMENTS

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
