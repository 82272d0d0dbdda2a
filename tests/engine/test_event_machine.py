"""Subscription (the relay's Events client) against its transition table.

The table is the one in :mod:`edge_vis.engine.subscriptions`, read against the Events
protocol behaviour of core v1.1 (``jsidl/urn.jaus.jss.core-v1.1/Events.xml``):

* CreateEvent is answered ConfirmEventRequest (with the provider's event ID) when
  supported, RejectEventRequest when not; a CreateEvent for an event that exists updates
  it (same event ID), and so does UpdateEvent, which is rejected for an unknown event;
* the provider cancels an event whose timer (ReportEventTimeout, minutes, 0 = none) runs
  out; CreateEvent and UpdateEvent reset that timer, so the client refreshes before it;
* CancelEvent is confirmed with ConfirmEventRequest, or rejected if the event is gone.

Each row starts from a state reached by a scripted history, feeds one input at a time of
the fake clock, and asserts the next state, the exact messages the relay sends (encoded
through the catalogue) and when the machine next wants to act. The relay polls the
report instead when events are rejected or never answered.
"""

from __future__ import annotations

from itertools import pairwise
from typing import Any

import pytest

from edge_vis.config import EventsProfile
from edge_vis.engine.subscriptions import MAX_STALE, Request, Subscription, SubscriptionState
from edge_vis.jaus.address import JausAddress

from .conftest import wire

PROFILE = EventsProfile(response_timeout=1.0, attempts=2, default_refresh=60.0)
PROVIDER = JausAddress(150, 1, 1)
QUERY_FIELDS = {"presence_vector": 0x1FF}
RATE = 10.0  # Hz: a periodic event is stale after max(5 periods, 2 response timeouts) = 2 s
EVENT_ID = 7

NEW = SubscriptionState.NEW
CREATING = SubscriptionState.CREATING
ACTIVE = SubscriptionState.ACTIVE
POLLING = SubscriptionState.POLLING
CANCELLING = SubscriptionState.CANCELLING
DONE = SubscriptionState.DONE

QUERY = object()  # stands for the encoded QueryGlobalPose inside CreateEvent/UpdateEvent
POLL = ("QueryGlobalPose", QUERY_FIELDS)

Input = tuple[Any, ...]


def create(request_id: int, rate: float = RATE, every_change: bool = False
           ) -> tuple[str, dict[str, Any]]:
    return ("CreateEvent", {"request_id": request_id, "event_type": 1 if every_change else 0,
                            "requested_periodic_rate": 0.0 if every_change else rate,
                            "query_message": QUERY})


def update(request_id: int, rate: float) -> tuple[str, dict[str, Any]]:
    return ("UpdateEvent", {"request_id": request_id, "event_type": 0,
                            "requested_periodic_rate": rate, "event_id": EVENT_ID,
                            "query_message": QUERY})


def cancel(request_id: int) -> tuple[str, dict[str, Any]]:
    return ("CancelEvent", {"request_id": request_id, "event_id": EVENT_ID})


def feed(sub: Subscription, event: Input, now: float) -> list[Request]:
    """Apply one input to the machine; what it wants sent."""
    kind, *args = event
    if kind == "start":
        return sub.start(now)
    if kind == "ConfirmEventRequest":
        return sub.on_confirm(args[0] if args else EVENT_ID, args[1] if len(args) > 1 else RATE,
                              now)
    if kind == "RejectEventRequest":
        return sub.on_reject(args[0], now)
    if kind == "Event":
        sub.on_event(args[0], now)
        return []
    if kind == "ReportEventTimeout":
        sub.set_event_timeout(args[0], now)
        return []
    if kind == "timer":
        return sub.poll(now)
    if kind == "cancel":
        return sub.cancel(now)
    if kind == "update_rate":
        return sub.update_rate(args[0], now)
    if kind == "set_rate":
        return sub.set_rate(args[0], now)
    if kind == "resume":
        return sub.resume(now)
    if kind == "lost":
        sub.on_lost()
        return []
    raise AssertionError(f"unknown input {kind}")


def describe(event: Input) -> str:
    kind, *args = event
    return f"{kind}({', '.join(map(str, args))})" if args else kind


START = ("start",)
CONFIRM = ("ConfirmEventRequest",)
#: name -> (every change?, (input, at) steps that reach it, the state they reach)
HISTORIES: dict[str, tuple[bool, list[tuple[Input, float]], SubscriptionState]] = {
    "new": (False, [], NEW),
    "creating": (False, [(START, 0.0)], CREATING),
    "creating, 2nd attempt": (False, [(START, 0.0), (("timer",), 1.0)], CREATING),
    "active": (False, [(START, 0.0), (CONFIRM, 0.0)], ACTIVE),
    "active, every change": (True, [(START, 0.0), (CONFIRM, 0.0)], ACTIVE),
    "active, timeout 1 min": (True, [(START, 0.0), (CONFIRM, 0.0),
                                     (("ReportEventTimeout", 1), 0.0)], ACTIVE),
    "updating": (False, [(START, 0.0), (CONFIRM, 0.0), (("update_rate", 5.0), 0.0)], ACTIVE),
    "polling": (False, [(START, 0.0), (("RejectEventRequest", 1), 0.0)], POLLING),
    "cancelling": (False, [(START, 0.0), (CONFIRM, 0.0), (("cancel",), 0.0)], CANCELLING),
    "cancelled while creating": (False, [(START, 0.0), (("cancel",), 0.0)], CANCELLING),
    "done": (False, [(START, 0.0), (CONFIRM, 0.0), (("cancel",), 0.0), (CONFIRM, 0.0)], DONE),
    "polling, dropped": (False, [(START, 0.0), (("RejectEventRequest", 1), 0.0),
                                 (("cancel",), 0.0)], DONE),
    "lost while active": (False, [(START, 0.0), (CONFIRM, 0.0), (("lost",), 0.0)], NEW),
    "lost while polling": (False, [(START, 0.0), (("RejectEventRequest", 1), 0.0),
                                   (("lost",), 0.0)], NEW),
}


class RequestIds:
    """The vehicle's request ID counter (u8)."""

    def __init__(self) -> None:
        self.last = 0

    def __call__(self) -> int:
        self.last = (self.last + 1) % 256
        return self.last


def machine(catalogue: Any, history: str, rate: float = RATE) -> Subscription:
    every_change, steps, reached = HISTORIES[history]
    sub = Subscription(PROVIDER, "ReportGlobalPose", "QueryGlobalPose", QUERY_FIELDS, rate,
                       every_change, PROFILE, catalogue.encode, RequestIds())
    for event, at in steps:
        feed(sub, event, at)
    assert sub.state is reached, f"history {history!r} did not reach {reached}"
    return sub



def expected(catalogue: Any, messages: list[tuple[str, dict[str, Any]]]
             ) -> list[tuple[str, dict[str, Any]]]:
    query = catalogue.encode("QueryGlobalPose", QUERY_FIELDS)
    return [(name, {k: query if v is QUERY else v for k, v in fields.items()})
            for name, fields in messages]


# (history, input, at) -> (next state, messages sent, next deadline)
TABLE = [
    # NEW
    ("new", START, 0.5, CREATING, [create(1)], 1.5),
    ("new", ("timer",), 10.0, NEW, [], None),
    ("new", ("cancel",), 0.5, DONE, [], None),
    # CREATING: CreateEvent (request 1) sent at 0, answer due within 1 s
    ("creating", CONFIRM, 0.5, ACTIVE, [], 2.5),  # next: the stale check, 2 s on
    ("creating", ("RejectEventRequest", 1), 0.5, POLLING, [POLL], 0.6),
    ("creating", ("RejectEventRequest", 5), 0.5, POLLING, [POLL], 0.6),
    ("creating", ("timer",), 0.5, CREATING, [], 1.0),
    ("creating", ("timer",), 1.0, CREATING, [create(2)], 2.0),  # unanswered: again
    ("creating", ("cancel",), 0.5, CANCELLING, [], 1.5),  # cancel what the confirm creates
    ("creating", ("update_rate", 5.0), 0.5, CREATING, [], 1.0),  # sent once confirmed
    ("creating", ("lost",), 0.5, NEW, [], None),
    ("creating, 2nd attempt", ("timer",), 2.0, POLLING, [POLL], 2.1),  # never answered
    ("creating, 2nd attempt", CONFIRM, 1.5, ACTIVE, [], 3.5),
    # ACTIVE, periodic: confirmed at 0; refresh at 60 s, stale check at 2 s
    ("active", ("Event", 1), 1.0, ACTIVE, [], 3.0),
    ("active", ("timer",), 1.9, ACTIVE, [], 2.0),
    ("active", ("timer",), 2.0, CREATING, [create(2)], 3.0),  # quiet: created again
    ("active", CONFIRM, 1.0, ACTIVE, [], 2.0),  # a refresh confirmed
    ("active", ("cancel",), 1.0, CANCELLING, [cancel(2)], 2.0),
    ("active", ("update_rate", 5.0), 1.0, ACTIVE, [update(2, 5.0)], 2.0),
    ("active", ("update_rate", RATE), 1.0, ACTIVE, [], 2.0),
    ("active", ("set_rate", 5.0), 1.0, ACTIVE, [create(2, 5.0)], 3.0),
    ("active", ("lost",), 1.0, NEW, [], None),
    # ACTIVE, every change: no stale check; refreshed by CreateEvent (same event updated)
    ("active, every change", ("timer",), 59.9, ACTIVE, [], 60.0),
    ("active, every change", ("timer",), 60.0, ACTIVE, [create(2, every_change=True)], 120.0),
    ("active, every change", ("ReportEventTimeout", 1), 10.0, ACTIVE, [], 40.0),
    ("active, every change", ("ReportEventTimeout", 0), 10.0, ACTIVE, [], None),
    ("active, every change", ("update_rate", 5.0), 10.0, ACTIVE, [], 60.0),
    # ACTIVE, the provider's event timeout is 1 min: refreshed at half of it
    ("active, timeout 1 min", ("timer",), 29.9, ACTIVE, [], 30.0),
    ("active, timeout 1 min", ("timer",), 30.0, ACTIVE, [create(2, every_change=True)], 60.0),
    # UpdateEvent (request 2) in flight since 0
    ("updating", ("ConfirmEventRequest", EVENT_ID, 5.0), 0.5, ACTIVE, [], 2.0),
    ("updating", ("RejectEventRequest", 6), 0.5, ACTIVE, [create(3, 5.0)], 2.0),
    ("updating", ("timer",), 1.0, ACTIVE, [create(3, 5.0)], 2.0),  # ignored: refresh
    # POLLING: the query at the rate (every 0.1 s)
    ("polling", ("timer",), 0.05, POLLING, [], 0.1),
    ("polling", ("timer",), 0.1, POLLING, [POLL], 0.2),
    ("polling", ("update_rate", 5.0), 0.05, POLLING, [], 0.25),
    ("polling", ("cancel",), 0.05, DONE, [], None),  # nothing at the provider to cancel
    ("polling", ("lost",), 0.05, NEW, [], None),
    # CANCELLING: CancelEvent (request 2) sent at 0
    ("cancelling", CONFIRM, 0.5, DONE, [], None),
    ("cancelling", ("RejectEventRequest", 6), 0.5, DONE, [], None),  # already gone
    ("cancelling", ("timer",), 0.5, CANCELLING, [], 1.0),
    ("cancelling", ("timer",), 1.0, DONE, [], None),
    ("cancelled while creating", CONFIRM, 0.5, CANCELLING, [cancel(2)], 1.5),
    ("cancelled while creating", ("RejectEventRequest", 1), 0.5, DONE, [], None),
    ("cancelled while creating", ("timer",), 1.0, DONE, [], None),
    # DONE: quiet until resumed (the bandwidth plan gives the report room again)
    ("done", ("timer",), 100.0, DONE, [], None),
    ("done", ("resume",), 5.0, CREATING, [create(3)], 6.0),
    ("polling, dropped", ("resume",), 5.0, POLLING, [POLL], 5.1),  # it only polls: poll
    # lost, then found: events are tried again, even where the provider had rejected them
    ("lost while active", START, 5.0, CREATING, [create(2)], 6.0),
    ("lost while polling", START, 5.0, CREATING, [create(2)], 6.0),
    ("lost while polling", ("resume",), 5.0, CREATING, [create(2)], 6.0),
]


@pytest.mark.parametrize(
    ("history", "event", "at", "state", "messages", "deadline"), TABLE,
    ids=[f"{row[0]}: {describe(row[1])} at {row[2]}" for row in TABLE],
)
def test_transition(catalogue: Any, history: str, event: Input, at: float,
                    state: SubscriptionState, messages: list[tuple[str, dict[str, Any]]],
                    deadline: float | None) -> None:
    sub = machine(catalogue, history)
    out = feed(sub, event, at)
    assert (sub.state, wire(catalogue, out), sub.next_deadline()) == (
        state, expected(catalogue, messages), deadline)


def test_every_state_and_input_kind_is_in_the_table() -> None:
    assert {HISTORIES[row[0]][2] for row in TABLE} == set(SubscriptionState)
    assert {row[1][0] for row in TABLE} >= {
        "start", "ConfirmEventRequest", "RejectEventRequest", "Event", "ReportEventTimeout",
        "timer", "cancel", "update_rate", "lost"}


@pytest.mark.parametrize(("history", "at", "reason"), [
    ("polling", 0.0, "event rejected (response code 1)"),
    ("creating, 2nd attempt", 2.0, "no answer to 2 CreateEvent requests"),
])
def test_why_a_report_is_polled(catalogue: Any, history: str, at: float, reason: str) -> None:
    sub = machine(catalogue, history)
    sub.poll(at)
    assert (sub.state, sub.polls, sub.reason) == (POLLING, True, reason)


def test_a_quiet_event_is_created_again_then_polled(catalogue: Any) -> None:
    """Rule 4: a confirmed periodic event that never delivers is re-created MAX_STALE
    times, then the report is polled."""
    sub = machine(catalogue, "active")
    now, names = 0.0, []
    for _ in range(MAX_STALE + 1):
        now = sub.next_deadline() or 0.0
        names += [r.name for r in sub.poll(now)]
        if sub.state is CREATING:
            sub.on_confirm(EVENT_ID, RATE, now)
    assert names == ["CreateEvent"] * MAX_STALE + ["QueryGlobalPose"]
    assert (sub.state, sub.reason) == (POLLING, "confirmed events never arrive")


@pytest.mark.parametrize(("event_id", "report", "matches"), [
    (EVENT_ID, "ReportGlobalPose", True),
    (EVENT_ID, "ReportVelocityState", False),  # JAUS++ reuses event IDs across reports
    (EVENT_ID + 1, "ReportGlobalPose", False),
])
def test_events_match_by_id_and_report(catalogue: Any, event_id: int, report: str,
                                       matches: bool) -> None:
    assert machine(catalogue, "active").matches_event(event_id, report) is matches
    assert machine(catalogue, "creating").matches_event(event_id, report) is False


@pytest.mark.parametrize(("sequence", "missed"), [
    ([1, 2, 3], 0), ([1, 4], 2), ([254, 255, 0, 1], 0), ([255, 2], 2),
    ([5, 5], 0), ([5, 3], 0),  # a repeat, a late one: not losses
])
def test_missed_events_from_sequence_numbers(catalogue: Any, sequence: list[int],
                                             missed: int) -> None:
    sub = machine(catalogue, "active")
    assert sum(sub.on_event(seq, 0.5) for seq in sequence) == missed == sub.events_missed


@pytest.mark.parametrize("minutes", [1, 2, 10, 255])
def test_events_are_refreshed_before_the_provider_times_them_out(catalogue: Any,
                                                                 minutes: int) -> None:
    """A provider per the JSIDL: CreateEvent resets the event's timer; if the timer runs
    out the event is cancelled. It confirms after 0.1 s, reports its timeout when asked
    (as the engine does once per provider), and sends an Event every second."""
    limit = minutes * 60.0
    latency = 0.1
    sub = machine(catalogue, "new", rate=1.0)
    now = 0.0
    arrivals: list[float] = []
    answers: list[tuple[float, Input]] = []
    next_event = 1.0

    def carry(out: list[Request]) -> None:
        for item in out:
            assert item.name == "CreateEvent", item  # never polled, never re-created
            arrivals.append(now + latency)
            answers.append((now + latency, CONFIRM))

    carry(sub.start(now))
    asked = False
    while now < 4 * limit:
        now = min(t for t in (sub.next_deadline(), next_event, *(t for t, _ in answers))
                  if t is not None)
        for _t, event in [a for a in answers if a[0] <= now]:
            carry(feed(sub, event, now))
            if not asked:  # QueryEventTimeout after the first confirm, answered at once
                asked = True
                sub.set_event_timeout(minutes, now)
        answers = [a for a in answers if a[0] > now]
        if now >= next_event:
            if sub.state is ACTIVE:
                sub.on_event(int(next_event) & 0xFF, now)
            next_event += 1.0
        carry(sub.poll(now))
        assert sub.state in (CREATING, ACTIVE)
    gaps = [b - a for a, b in pairwise(arrivals)]
    assert len(gaps) >= 6
    assert max(gaps) < limit  # each refresh reaches the provider before the event expires
