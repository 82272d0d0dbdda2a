"""JAUS event subscriptions for one report from one component. No I/O, explicit ``now``.

Theory of operation
-------------------
For each report a translator wants, the engine asks the providing component for a JAUS
*event* (AS5710 Events service): CreateEvent carrying the complete query message, the
event type and the rate. The provider answers ConfirmEventRequest (with the event ID it
chose) or RejectEventRequest, then sends Event messages wrapping the report.

Rule 1: an event is identified by (provider, event ID, report name), never by the event ID
alone: JAUS++ hands out the same event ID for different report types.

Rule 2: events time out (core v1.1). The provider's timeout is asked once per provider
(QueryEventTimeout) and the event is refreshed at half of it by re-sending the same
CreateEvent, which providers treat as an update of the existing event. Providers that do
not answer are refreshed every ``default_refresh``.

Rule 3: if the provider rejects the event, or leaves ``attempts`` requests unanswered (the
JTS example ignores CreateEvent), the report is *polled*: the query is sent at the rate.

Rule 4: a periodic event that goes quiet (no Event for ``STALE_PERIODS`` periods, at least
twice the response timeout) was lost by the provider - a restart shorter than the silence
timeout, say: it is created again. If that happens ``MAX_STALE`` times in a row the
provider confirms but does not deliver, and the report is polled instead.

Rule 5: when interest ends (relay stopping), CancelEvent with the event ID.

Rule 6: a new planned rate (the link's bandwidth plan changed) updates an active event in
place with UpdateEvent (same event ID, no gap in the data). A provider that rejects the
update gets the event created again at the new rate; one that ignores it is refreshed at
the new rate after the response timeout. A rate planned while CreateEvent is in flight is
sent as UpdateEvent once the event is confirmed.

=============  ======================================  ============  ======================
state          input                                   new state     output
=============  ======================================  ============  ======================
NEW            start                                   CREATING      CreateEvent
CREATING       ConfirmEventRequest(request id)         ACTIVE        -
CREATING       RejectEventRequest / attempts exhausted POLLING       query at the rate
CREATING       no answer (response_timeout)            CREATING      CreateEvent (again)
ACTIVE         refresh due                             ACTIVE        CreateEvent
ACTIVE         no Event for a while (periodic)         CREATING      CreateEvent
ACTIVE         quiet again after MAX_STALE re-creates  POLLING       query at the rate
POLLING        period elapsed                          POLLING       query
ACTIVE         cancel                                  CANCELLING    CancelEvent
ACTIVE         new planned rate                        ACTIVE        UpdateEvent
CANCELLING     ConfirmEventRequest / timeout           DONE          -
any            vehicle lost                            NEW           -
=============  ======================================  ============  ======================
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from edge_vis.config import EventsProfile
from edge_vis.jaus.address import JausAddress

#: periods without an Event after which a periodic event counts as lost
STALE_PERIODS = 5
#: re-creations of a quiet event before polling instead
MAX_STALE = 2


class SubscriptionState(enum.Enum):
    """Life cycle of one subscription."""

    NEW = "new"
    CREATING = "creating"
    ACTIVE = "active"
    POLLING = "polling"
    CANCELLING = "cancelling"
    DONE = "done"


@dataclass(frozen=True, slots=True)
class Request:
    """A message this subscription wants sent to its provider."""

    name: str
    fields: Mapping[str, Any]
    #: the message set of ``name`` when two sets use it (a query a report spec names)
    service_set: str | None = None


class Subscription:
    """One wanted report from one provider component (see module docstring).

    ``encode_query`` turns (query name, fields) into the complete query payload bytes that
    CreateEvent carries; ``next_request_id`` hands out the vehicle's request IDs (u8).
    """

    def __init__(
        self,
        provider: JausAddress,
        report: str,
        query: str,
        query_fields: Mapping[str, Any],
        rate: float,
        on_change: bool,
        profile: EventsProfile,
        encode_query: Callable[[str, Mapping[str, Any]], bytes],
        next_request_id: Callable[[], int],
        service_set: str | None = None,
    ) -> None:
        self.provider = provider
        self.report = report
        self.query = query
        self.query_fields = dict(query_fields)
        #: the message set of the query and report (None: the name is enough)
        self.service_set = service_set
        self.rate = rate
        self.on_change = on_change
        self.profile = profile
        self._encode_query = encode_query
        self._next_request_id = next_request_id
        self.state = SubscriptionState.NEW
        self.event_id: int | None = None
        self.request_id: int | None = None
        self.confirmed_rate: float | None = None
        self.attempts = 0
        self.deadline: float | None = None
        self.refresh_period: float = profile.default_refresh
        self.events_received = 0
        #: Events the provider numbered but that never arrived (gaps in sequence numbers)
        self.events_missed = 0
        self.last_sequence: int | None = None
        self.last_event: float | None = None
        self.reason = ""
        self.stale_deadline: float | None = None
        self.stale_count = 0
        #: a CancelEvent that timed out
        self.unanswered = False
        #: the rate the last CreateEvent/UpdateEvent asked for
        self.requested_rate: float | None = None
        self._updating = False
        self.updates_sent = 0
        #: cancelled while CreateEvent was in flight: cancel the event once confirmed
        self._cancel_when_confirmed = False
        #: the provider answered queries only (since the last loss): plans count the query
        self.polls = False

    # -- queries -----------------------------------------------------------------------

    def next_deadline(self) -> float | None:
        """Earliest time :meth:`poll` has something to do."""
        times = [t for t in (self.deadline, self.stale_deadline) if t is not None]
        return min(times) if times else None

    def matches_event(self, event_id: int, report: str) -> bool:
        """True when an Event(event_id) carrying ``report`` belongs to this subscription."""
        return (
            self.state in (SubscriptionState.ACTIVE, SubscriptionState.CANCELLING)
            and self.event_id == event_id
            and self.report == report
        )

    # -- inputs ------------------------------------------------------------------------

    def start(self, now: float, events: bool = True) -> list[Request]:
        """Begin (or, after a loss, begin again); poll at once when the provider is known
        to offer no Events service (``events=False``)."""
        self.attempts = 0
        return self._create(now) if events else self._start_polling(now)

    def on_confirm(self, event_id: int, rate: float, now: float) -> list[Request]:
        """ConfirmEventRequest for our current request ID."""
        self.request_id = None
        self._updating = False
        if self.state is SubscriptionState.CANCELLING:
            if self._cancel_when_confirmed:  # the event we no longer want now exists
                self._cancel_when_confirmed = False
                self.event_id = event_id
                self.request_id = self._next_request_id()
                self.deadline = now + self.profile.response_timeout
                return [Request("CancelEvent", {"request_id": self.request_id,
                                                "event_id": event_id})]
            self._done()
            return []
        first = self.state is not SubscriptionState.ACTIVE
        self.state = SubscriptionState.ACTIVE
        # a new or re-created event may number from anywhere: count gaps from the next one
        self.last_sequence = None
        self.event_id = event_id
        self.confirmed_rate = rate
        self.attempts = 0
        self.deadline = now + self.refresh_period
        if first and not self.on_change:
            self.stale_deadline = now + self._stale_after()
        if (first and not self.on_change and self.requested_rate is not None
                and abs(self.requested_rate - self.rate) > 1e-9):
            return self._update(now)  # the plan changed while CreateEvent was in flight
        return []

    def on_reject(self, code: int | None, now: float) -> list[Request]:
        """RejectEventRequest for our current request ID: poll instead."""
        self.request_id = None
        if self.state is SubscriptionState.CANCELLING:
            self._done()
            return []
        if self._updating and self.state is SubscriptionState.ACTIVE:
            self._updating = False  # the provider does not update events: create it again
            self.attempts = 0
            return self._create(now, refresh=True)
        self.reason = f"event rejected (response code {code})"
        return self._start_polling(now)

    def on_event(self, sequence: int, now: float) -> int:
        """An Event of this subscription arrived (bursts and repeats are harmless).

        Returns how many Events its 8-bit sequence number says were lost on the way: a
        jump forward by less than half the number space (a repeat or a late duplicate is
        not a loss).
        """
        missed = 0
        last = self.last_sequence
        step = 1 if last is None else (sequence - last) & 0xFF
        if 0 < step < 0x80:  # forward (0: a repeat; 0x80 and more: an older one, late)
            missed = step - 1
            self.last_sequence = sequence
        self.events_missed += missed
        self.events_received += 1
        self.last_event = now
        self.stale_count = 0
        if self.stale_deadline is not None:
            self.stale_deadline = now + self._stale_after()
        return missed

    def set_event_timeout(self, minutes: int, now: float) -> None:
        """ReportEventTimeout from the provider: refresh at half of it (0 = never)."""
        self.refresh_period = minutes * 60.0 / 2.0 if minutes else float("inf")
        if self.state is SubscriptionState.ACTIVE:
            self.deadline = (now + self.refresh_period if minutes else None)

    def cancel(self, now: float) -> list[Request]:
        """Interest ended: cancel an active event, stop polling."""
        if self.state is SubscriptionState.ACTIVE and self.event_id is not None:
            self.state = SubscriptionState.CANCELLING
            self.request_id = self._next_request_id()
            self.deadline = now + self.profile.response_timeout
            return [Request("CancelEvent", {"request_id": self.request_id,
                                            "event_id": self.event_id})]
        if self.state is SubscriptionState.CREATING and self.request_id is not None:
            # a confirm may still come: keep its request ID and cancel what it creates
            self.state = SubscriptionState.CANCELLING
            self._cancel_when_confirmed = True
            self.stale_deadline = None
            self.deadline = now + self.profile.response_timeout
            return []
        self._done()
        return []

    def set_rate(self, rate: float, now: float) -> list[Request]:
        """A new rate (profile reloaded): update an active event, re-time polling."""
        self.rate = rate
        if self.state is SubscriptionState.ACTIVE and not self.on_change:
            self.attempts = 0
            if self.stale_deadline is not None:
                self.stale_deadline = now + self._stale_after()
            return self._create(now, refresh=True)
        if self.state is SubscriptionState.POLLING:
            self.deadline = now + self._period()
        return []

    def update_rate(self, rate: float, now: float) -> list[Request]:
        """A new planned rate: UpdateEvent for an active event, re-time polling (Rule 6)."""
        if abs(rate - self.rate) < 1e-9:
            return []
        self.rate = rate
        if self.state is SubscriptionState.ACTIVE and not self.on_change \
                and self.event_id is not None:
            if self.stale_deadline is not None:
                self.stale_deadline = now + self._stale_after()
            return self._update(now)
        if self.state is SubscriptionState.POLLING:
            self.deadline = now + self._period()
        return []

    def _update(self, now: float) -> list[Request]:
        self.request_id = self._next_request_id()
        self._updating = True
        self.requested_rate = self.rate
        self.updates_sent += 1
        # unanswered: the refresh at this deadline re-creates the event at the new rate
        self.deadline = now + self.profile.response_timeout
        return [Request("UpdateEvent", {
            "request_id": self.request_id,
            "event_type": 1 if self.on_change else 0,
            "requested_periodic_rate": 0.0 if self.on_change else self.rate,
            "event_id": self.event_id,
            "query_message": self._encode_query(self.query, self.query_fields),
        })]

    def on_lost(self) -> None:
        """The provider went silent: its events are gone; start over when it returns."""
        self.polls = False  # it may come back with events (a restart, a new version)
        self.state = SubscriptionState.NEW
        self.event_id = None
        self.request_id = None
        self.deadline = None
        self.stale_deadline = None
        self.stale_count = 0

    def poll(self, now: float) -> list[Request]:
        """Do whatever is due at ``now``."""
        if self.stale_deadline is not None and now >= self.stale_deadline:
            self.stale_deadline = None
            if self.state is SubscriptionState.ACTIVE:
                self.stale_count += 1
                self.event_id = None
                if self.stale_count > MAX_STALE:
                    self.reason = "confirmed events never arrive"
                    return self._start_polling(now)
                self.reason = "events stopped; created again"
                self.attempts = 0
                return self._create(now)
        if self.deadline is None or now < self.deadline:
            return []
        self.deadline = None
        if self.state is SubscriptionState.CREATING:
            if self.attempts >= max(self.profile.attempts, 1):
                self.reason = f"no answer to {self.attempts} CreateEvent requests"
                self.request_id = None
                return self._start_polling(now)
            return self._create(now)
        if self.state is SubscriptionState.ACTIVE:
            self.attempts = 0
            return self._create(now, refresh=True)
        if self.state is SubscriptionState.POLLING:
            self.deadline = now + self._period()
            return [Request(self.query, self.query_fields, self.service_set)]
        if self.state is SubscriptionState.CANCELLING:
            self.unanswered = True
            self._done()
        return []

    # -- internals ---------------------------------------------------------------------

    def _period(self) -> float:
        return 1.0 / self.rate if self.rate > 0 else 1.0

    def _stale_after(self) -> float:
        return max(STALE_PERIODS * self._period(), 2 * self.profile.response_timeout)

    def _create(self, now: float, refresh: bool = False) -> list[Request]:
        if not refresh:
            self.state = SubscriptionState.CREATING
        self.attempts += 1
        self._updating = False
        self.requested_rate = self.rate
        self.request_id = self._next_request_id()
        self.deadline = now + (self.profile.response_timeout if not refresh
                               else self.refresh_period)
        fields = {
            "request_id": self.request_id,
            "event_type": 1 if self.on_change else 0,
            "requested_periodic_rate": 0.0 if self.on_change else self.rate,
            "query_message": self._encode_query(self.query, self.query_fields),
        }
        return [Request("CreateEvent", fields)]

    def resume(self, now: float) -> list[Request]:
        """Start again after :meth:`cancel`: poll right away if the provider only polls."""
        self._cancel_when_confirmed = False
        return self._start_polling(now) if self.polls else self.start(now)

    def _start_polling(self, now: float) -> list[Request]:
        self.polls = True
        self.state = SubscriptionState.POLLING
        self.event_id = None
        self.stale_deadline = None
        self.deadline = now + self._period()
        return [Request(self.query, self.query_fields, self.service_set)]

    def _done(self) -> None:
        self.state = SubscriptionState.DONE
        self.deadline = None
        self.stale_deadline = None
        self.request_id = None
