"""What the relay counted, as data, and which counts are losses. No I/O, no clock.

Every count is a :class:`Tally`: its ``kind`` (a relay counter, an engine counter, a
link's traffic or drops, samples published, a translator's failures), the counter's
``name`` (or a drop's reason) and its ``subject`` (a link, topic or translator). The
flat names of the ``totals:`` log line are made from tallies (:meth:`Tally.label`), never
the other way round: the loss policy (:func:`is_loss`) reads fields, not text.

A loss is something the relay had accepted and then failed to pass on: a publish, send,
encode or delivery error, a link or queue drop other than refused input (garbage on the
wire is refused, not lost), and a report a translator failed on. What a translator drops
on purpose (a part of a message it cannot use, with its reason) is refused input too.

:class:`LogLimiter` keeps the log readable under a flood of one fault (bad input from the
network, a translator that raises on every message): a few lines per key and minute,
then one line saying the rest is suppressed; time is an argument.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum

#: relay counters that mean something accepted was lost
LOSS_COUNTERS = frozenset({"publish errors", "send errors", "encode errors", "delivery failed"})
#: drop reasons of input refused on arrival (garbage on the wire): counted, not losses
REFUSED_INPUT = ("malformed",)


class Kind(Enum):
    """Where a count comes from."""

    RELAY = "relay"
    ENGINE = "engine"
    LINK_TRAFFIC = "link traffic"
    LINK_DROP = "link drop"
    PUBLISHED = "published"
    TRANSLATOR_ERROR = "translator error"
    TRANSLATOR_DROP = "translator drop"


@dataclass(frozen=True, order=True, slots=True)
class Tally:
    """One counter: ``kind``, ``name`` (counter or drop reason) and ``subject``."""

    kind: Kind
    name: str
    subject: str = ""

    def label(self) -> str:
        """The flat name in totals and logs (``link radio dropped: queue full (...)``)."""
        if self.kind is Kind.LINK_TRAFFIC:
            return f"link {self.subject} {self.name}"
        if self.kind is Kind.LINK_DROP:
            return f"link {self.subject} dropped: {self.name}"
        if self.kind is Kind.PUBLISHED:
            return f"published {self.subject}"
        if self.kind is Kind.TRANSLATOR_ERROR:
            return f"translator {self.subject} {self.name}"
        if self.kind is Kind.TRANSLATOR_DROP:
            return f"translator {self.subject} dropped: {self.name}"
        return self.name


def is_loss(tally: Tally) -> bool:
    """True when ``tally`` counts something the relay had accepted and then lost."""
    if tally.kind is Kind.RELAY:
        return tally.name in LOSS_COUNTERS
    if tally.kind is Kind.LINK_DROP:
        return not tally.name.startswith(REFUSED_INPUT)
    return tally.kind is Kind.TRANSLATOR_ERROR


def totals(tallies: Mapping[Tally, int]) -> dict[str, int]:
    """Flat ``{label: count}``, sorted by label (what the ``totals:`` line shows)."""
    out: dict[str, int] = {}
    for tally, count in tallies.items():
        out[tally.label()] = out.get(tally.label(), 0) + count
    return dict(sorted(out.items()))


def losses(tallies: Mapping[Tally, int]) -> dict[str, int]:
    """The non-zero losses in ``tallies``, by label."""
    return totals({t: n for t, n in tallies.items() if n and is_loss(t)})


def refused(tallies: Mapping[Tally, int]) -> int:
    """How much input was refused on arrival (link drops that are not losses)."""
    return sum(n for t, n in tallies.items() if t.kind is Kind.LINK_DROP and not is_loss(t))


def tallies_of(kind: Kind, counters: Mapping[str, int], subject: str = "") -> dict[Tally, int]:
    """``counters`` (name -> count) as tallies of one kind and subject."""
    return {Tally(kind, name, subject): int(count) for name, count in counters.items()}


class LogLimiter:
    """At most ``burst`` log lines per key and ``window`` seconds, then one line saying
    the rest is suppressed until the window ends."""

    def __init__(self, logger: logging.Logger, burst: int = 5, window: float = 60.0) -> None:
        self._log = logger
        self._burst = burst
        self._window_s = window
        self._windows: dict[str, tuple[float, int]] = {}

    def warning(self, key: str, now: float, msg: str, *args: object) -> bool:
        """Log ``msg`` unless ``key`` has had its burst this window; True if logged."""
        start, count = self._windows.get(key, (now, 0))
        if now - start > self._window_s:
            start, count = now, 0
        self._windows[key] = (start, count + 1)
        if count < self._burst:
            self._log.warning(msg, *args)
            return True
        if count == self._burst:
            self._log.warning("%s: further messages of this kind suppressed for %.0f s", key,
                              self._window_s)
        return False
