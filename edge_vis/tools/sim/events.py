"""The provider side of the JAUS Events service for one component. No I/O.

Holds the event subscriptions of one component and decides, for a given ``now``, which
periodic events are due and which have expired. What a report contains is the vehicle's
business: this table only stores the query to evaluate.

Rules (AS5710A Events 1.1, as real providers behave):

* a CreateEvent from the same client for the same query code and event type updates the
  existing event and confirms the same event id;
* event ids are u8, allocated round-robin and never two live events with one id;
* each event has its own 8-bit sequence number, wrapping 255 -> 0;
* an event not renewed (UpdateEvent, or CreateEvent again) within the event timeout
  (minutes, 0 = never) is dropped silently, the way a provider forgets a client that
  went away;
* a periodic event that falls behind (the vehicle was busy or silent) skips the missed
  reports instead of bursting them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from edge_vis.jaus.address import JausAddress

PERIODIC = 0
EVERY_CHANGE = 1


@dataclass(slots=True)
class Subscription:
    """One live event."""

    event_id: int
    subscriber: JausAddress
    event_type: int
    rate: float
    query_name: str
    query_fields: dict[str, Any]
    query_payload: bytes
    renewed: float
    next_due: float = 0.0
    sequence: int = 0
    last_report: Any = None
    sent: int = 0

    def next_sequence(self) -> int:
        """The sequence number for the next Event message (then advance it)."""
        value = self.sequence
        self.sequence = (self.sequence + 1) & 0xFF
        self.sent += 1
        return value


class EventTable:
    """The events of one component."""

    def __init__(self, timeout_minutes: int) -> None:
        self.timeout_minutes = timeout_minutes
        self._events: dict[int, Subscription] = {}
        self._next_id = 1
        self.expired = 0

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(list(self._events.values()))

    def __len__(self) -> int:
        return len(self._events)

    def get(self, event_id: int) -> Subscription | None:
        """The event with ``event_id``, or None."""
        return self._events.get(event_id)

    def find(self, subscriber: JausAddress, query_payload: bytes,
             event_type: int) -> Subscription | None:
        """An event of ``subscriber`` for the same query code and event type."""
        code = query_payload[:2]
        for sub in self._events.values():
            if (sub.subscriber == subscriber and sub.event_type == event_type
                    and sub.query_payload[:2] == code):
                return sub
        return None

    def create(self, subscriber: JausAddress, event_type: int, rate: float, query_name: str,
               query_fields: dict[str, Any], query_payload: bytes,
               now: float) -> Subscription | None:
        """A new event, or an update of the matching one; None when all 256 ids are taken."""
        sub = self.find(subscriber, query_payload, event_type)
        if sub is not None:
            self.update(sub, rate, query_fields, query_payload, now)
            return sub
        if len(self._events) >= 256:
            return None
        while self._next_id in self._events:
            self._next_id = (self._next_id + 1) & 0xFF
        event_id = self._next_id
        self._next_id = (self._next_id + 1) & 0xFF
        sub = Subscription(event_id, subscriber, event_type, rate, query_name,
                           dict(query_fields), bytes(query_payload), renewed=now)
        sub.next_due = now + (1.0 / rate if event_type == PERIODIC and rate > 0 else 0.0)
        self._events[event_id] = sub
        return sub

    def update(self, sub: Subscription, rate: float, query_fields: dict[str, Any],
               query_payload: bytes, now: float) -> None:
        """Change the rate and query of ``sub`` and renew it."""
        if sub.event_type == PERIODIC and rate > 0 and rate != sub.rate:
            sub.next_due = now + 1.0 / rate
        sub.rate = rate
        sub.query_fields = dict(query_fields)
        sub.query_payload = bytes(query_payload)
        sub.renewed = now

    def cancel(self, event_id: int) -> Subscription | None:
        """Remove an event; return it, or None if there was none."""
        return self._events.pop(event_id, None)

    def clear(self) -> None:
        """Forget every event (a reboot)."""
        self._events.clear()

    def expire(self, now: float) -> list[Subscription]:
        """Drop and return the events not renewed within the timeout."""
        if self.timeout_minutes <= 0:
            return []
        limit = self.timeout_minutes * 60.0
        gone = [s for s in self._events.values() if now - s.renewed >= limit]
        for sub in gone:
            del self._events[sub.event_id]
        self.expired += len(gone)
        return gone

    def due(self, now: float) -> list[Subscription]:
        """The periodic events due at ``now`` (their next time is advanced)."""
        out = []
        for sub in self._events.values():
            if sub.event_type != PERIODIC or sub.rate <= 0 or now < sub.next_due:
                continue
            period = 1.0 / sub.rate
            sub.next_due += period
            if sub.next_due <= now:  # fell behind: skip, do not burst
                sub.next_due = now + period
            out.append(sub)
        return out

    def changes(self) -> list[Subscription]:
        """The every-change events (the caller compares reports)."""
        return [s for s in self._events.values() if s.event_type == EVERY_CHANGE]

    def next_deadline(self) -> float | None:
        """The earliest periodic due time or expiry, or None."""
        times = [s.next_due for s in self._events.values()
                 if s.event_type == PERIODIC and s.rate > 0]
        if self.timeout_minutes > 0:
            times += [s.renewed + self.timeout_minutes * 60.0 for s in self._events.values()]
        return min(times) if times else None
