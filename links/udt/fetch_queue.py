"""Which announced image to fetch next, and when to try again. Pure logic: no I/O, no clock.

Vehicles announce images over JAUS; the relay pulls them over UDT one at a time (each
fetch may use several lanes) so the image it wants most arrives first:

* **priority** - ``confidence`` (highest ATR confidence first, then oldest capture),
  ``oldest`` or ``newest`` capture first;
* **one image per vehicle at a time**; other vehicles' images go on while one is away;
* **out of reach** (connection lost or refused) - that vehicle waits with exponential
  backoff (``initial`` doubling to ``maximum``), reset when a fetch from it makes progress;
* **mismatch** (not the announced SHA-256, or data failing it) - fetched again after a
  short delay, at most ``max_mismatches`` times, then given up with the reason;
* **not found** - the vehicle may not have written the file yet: retried with backoff,
  at most ``max_not_found`` times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

Priority = Literal["confidence", "oldest", "newest"]
PRIORITIES: tuple[str, ...] = ("confidence", "oldest", "newest")


@dataclass(frozen=True, slots=True)
class Wanted:
    """An announced image: where to fetch it and what it must hash to."""

    vehicle_id: str
    image_id: str
    name: str
    sha256: str
    size: int | None
    source: tuple[str, int]
    confidence: float = 0.0
    capture_time: float = 0.0


@dataclass(slots=True)
class _Entry:
    wanted: Wanted
    order: int
    not_before: float = 0.0
    mismatches: int = 0
    not_found: int = 0
    busy: bool = False


@dataclass(slots=True)
class _Vehicle:
    not_before: float = 0.0
    failures: int = 0


@dataclass(frozen=True, slots=True)
class Verdict:
    """What :meth:`FetchQueue.finished` decided: ``done``, ``retry`` at ``at``, or ``given_up``."""

    action: Literal["done", "retry", "given_up"]
    at: float = 0.0
    reason: str = ""


@dataclass
class FetchQueue:
    """Announced images waiting to be fetched (see module doc)."""

    priority: Priority = "confidence"
    initial: float = 0.5
    maximum: float = 30.0
    mismatch_delay: float = 0.5
    max_mismatches: int = 5
    max_not_found: int = 8
    max_entries: int = 10_000
    _entries: dict[str, _Entry] = field(default_factory=dict)
    _vehicles: dict[str, _Vehicle] = field(default_factory=dict)
    _count: int = 0
    #: images dropped because the queue was full
    overflow: int = 0

    def __post_init__(self) -> None:
        if self.priority not in PRIORITIES:
            raise ValueError(f"priority must be one of {', '.join(PRIORITIES)}")

    def __len__(self) -> int:
        return len(self._entries)

    def add(self, wanted: Wanted) -> bool:
        """Queue ``wanted`` unless the same image (SHA-256) is queued; False if not added."""
        if wanted.sha256 in self._entries:
            return False
        if len(self._entries) >= self.max_entries:
            self.overflow += 1
            return False
        self._count += 1
        self._entries[wanted.sha256] = _Entry(wanted, self._count)
        return True

    def discard(self, sha256: str) -> None:
        """The image arrived another way (pushed): nothing to fetch."""
        entry = self._entries.get(sha256)
        if entry is not None and not entry.busy:
            del self._entries[sha256]

    def _rank(self, e: _Entry) -> tuple[float, float, int]:
        w = e.wanted
        if self.priority == "confidence":
            return (-w.confidence, w.capture_time, e.order)
        if self.priority == "oldest":
            return (w.capture_time, 0.0, e.order)
        return (-w.capture_time, 0.0, e.order)

    def take(self, now: float) -> Wanted | None:
        """The image to fetch now (marked busy until :meth:`finished`), or None."""
        busy = {e.wanted.vehicle_id for e in self._entries.values() if e.busy}
        ready = [e for e in self._entries.values()
                 if not e.busy and e.not_before <= now and e.wanted.vehicle_id not in busy
                 and self._vehicles.get(e.wanted.vehicle_id, _Vehicle()).not_before <= now]
        if not ready:
            return None
        best = min(ready, key=self._rank)
        best.busy = True
        return best.wanted

    def next_due(self, now: float) -> float | None:
        """When :meth:`take` may next return something (None: nothing is waiting)."""
        times = [max(e.not_before, self._vehicles.get(e.wanted.vehicle_id, _Vehicle()).not_before)
                 for e in self._entries.values() if not e.busy]
        return max(now, min(times)) if times else None

    def finished(self, wanted: Wanted, outcome: str, now: float, reason: str = "",
                 progressed: bool = False) -> Verdict:
        """Record how a fetch of ``wanted`` ended (a :class:`FetchOutcome` state)."""
        entry = self._entries.get(wanted.sha256)
        if entry is None:
            return Verdict("done")
        entry.busy = False
        vehicle = self._vehicles.setdefault(wanted.vehicle_id, _Vehicle())
        if outcome in ("verified",):
            del self._entries[wanted.sha256]
            vehicle.failures, vehicle.not_before = 0, 0.0
            return Verdict("done")
        if outcome == "mismatch":
            vehicle.failures, vehicle.not_before = 0, 0.0
            entry.mismatches += 1
            if entry.mismatches >= self.max_mismatches:
                del self._entries[wanted.sha256]
                return Verdict("given_up", reason=f"{entry.mismatches} mismatches: {reason}")
            entry.not_before = now + self.mismatch_delay
            return Verdict("retry", entry.not_before, reason)
        if outcome == "not_found":
            vehicle.failures, vehicle.not_before = 0, 0.0
            entry.not_found += 1
            if entry.not_found >= self.max_not_found:
                del self._entries[wanted.sha256]
                return Verdict("given_up", reason=f"not served after {entry.not_found} "
                               f"requests: {reason}")
            entry.not_before = now + min(self.maximum, self.initial * 2 ** entry.not_found)
            return Verdict("retry", entry.not_before, reason)
        # lost, refused, stored (a lane fetch that did not finish the file): out of reach
        if progressed:
            vehicle.failures = 0
        delay = min(self.maximum, self.initial * 2 ** vehicle.failures)
        vehicle.failures += 1
        vehicle.not_before = now + delay
        return Verdict("retry", vehicle.not_before, reason)
