"""Report delivery for a vehicle: JAUS events, with polling where events fail. No I/O.

The JAUS machine for one report from one component is
:class:`~edge_vis.engine.subscriptions.Subscription`; this module runs those machines for
a whole vehicle: it creates one per report a translator wants (once for all translators),
matches ConfirmEventRequest / RejectEventRequest / ReportEventTimeout to them, asks each
provider its event timeout once, unwraps Event messages and hands the report inside to
the ordinary message path, and polls their timers. A subscription that starts or stops
polling marks the bandwidth plan for recomputation, since a poll costs a query too.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from functools import partial
from typing import Any

from edge_vis.engine.discovery import CORE, pick
from edge_vis.engine.manager import TranslationManager
from edge_vis.engine.rates import MAX_RATE, Rates
from edge_vis.engine.state import EngineState, Handle
from edge_vis.engine.subscriptions import Subscription, SubscriptionState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress

log = logging.getLogger(__name__)

EVENTS = CORE + "Events"


class Reports:
    """Keeps every wanted report of a vehicle flowing (see the module docstring)."""

    def __init__(self, state: EngineState, manager: TranslationManager, rates: Rates,
                 handle: Handle) -> None:
        self._state = state
        self._manager = manager
        self._rates = rates
        self._handle = handle

    def setup(self, vehicle: Vehicle, now: float) -> None:
        """Subscribe to every wanted report the vehicle offers and is not subscribed to."""
        state = self._state
        starting = []
        for _tr, spec in self._manager.wanted_reports():
            providers = vehicle.providers(spec.service)
            if not providers:
                continue
            # a report two sets define (ReportActiveElement) is one subscription per set
            key = (providers[0], f"{spec.service_set}:{spec.report}" if spec.service_set
                   else spec.report)
            sub = vehicle.subscriptions.get(key)
            if sub is None:
                rate = state.profile.report_rate(spec.report, spec.rate, vehicle.profile)
                sub = Subscription(providers[0], spec.report, spec.query, spec.query_fields,
                                   min(rate, MAX_RATE), spec.on_change, state.profile.events,
                                   partial(state.encode_query,
                                           dialects=state.dialects(vehicle),
                                           service_set=spec.service_set),
                                   vehicle.next_request_id, spec.service_set)
                vehicle.subscriptions[key] = sub
            if sub.state is SubscriptionState.NEW:
                starting.append(sub)
        if starting and state.planner is not None:
            self._rates.replan(now)  # a vehicle joined: rates for it (and its link's others)
        for sub in starting:
            if sub.state is SubscriptionState.NEW \
                    and (vehicle.vehicle_id, sub.report) not in state.dropped:
                # a vehicle found by its hello or messages lists its services: one without
                # Events is polled from the start rather than after unanswered CreateEvents
                events = vehicle.announced_by is None or vehicle.offers(sub.provider, EVENTS)
                state.send_requests(sub.provider, sub.start(now, events))

    def poll(self, vehicle: Vehicle, now: float) -> None:
        """Refreshes, retries and polls that are due."""
        state = self._state
        for sub in vehicle.subscriptions.values():
            polled = sub.polls
            state.send_requests(sub.provider, sub.poll(now))
            if polled != sub.polls:
                state.plan_dirty = True  # a poll costs a query too: plan again

    def cancel(self, vehicle: Vehicle, now: float) -> None:
        """Interest ended (the relay is stopping): cancel every event, stop polling."""
        for sub in vehicle.subscriptions.values():
            self._state.send_requests(sub.provider, sub.cancel(now))

    def on_confirm(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                   now: float) -> None:
        """ConfirmEventRequest: to the subscription whose request ID it echoes."""
        state = self._state
        request_id = pick(fields, "request_id")
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.request_id == request_id:
                state.send_requests(source, sub.on_confirm(
                    int(pick(fields, "event_id", 0)),
                    float(pick(fields, "confirmed_periodic_rate", 0.0)), now))
                if (sub.state is SubscriptionState.ACTIVE
                        and source not in vehicle.event_timeout_asked):
                    vehicle.event_timeout_asked.add(source)
                    state.send(source, "QueryEventTimeout", {})
                return
        state.counters["event_confirms_unmatched"] += 1

    def on_reject(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                  now: float) -> None:
        """RejectEventRequest: that subscription polls instead (or gives up a cancel)."""
        request_id = pick(fields, "request_id")
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.request_id == request_id:
                polled = sub.polls
                self._state.send_requests(source,
                                          sub.on_reject(pick(fields, "response_code"), now))
                if polled != sub.polls:
                    self._state.plan_dirty = True
                return

    def on_event_timeout(self, vehicle: Vehicle, source: JausAddress,
                         fields: Mapping[str, Any], now: float) -> None:
        """ReportEventTimeout: every subscription to ``source`` refreshes within it."""
        minutes = int(pick(fields, "timeout", 0))
        for sub in vehicle.subscriptions.values():
            if sub.provider == source:
                sub.set_event_timeout(minutes, now)

    def on_event(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                 now: float) -> None:
        """Event: count it against its subscription, then handle the report inside."""
        counters = self._state.counters
        inner = self._unwrap(vehicle, fields)
        if inner is None:
            counters["events_undecodable"] += 1
            return
        name, inner_fields, service_set = inner
        event_id = int(pick(fields, "event_id", -1))
        for sub in vehicle.subscriptions.values():
            if sub.provider == source and sub.matches_event(event_id, name):
                missed = sub.on_event(int(pick(fields, "sequence_number", 0)), now)
                if missed:
                    counters["events_missed"] += missed
                break
        else:
            # data is data: deliver it, but count it (another client's event, or a burst
            # that raced our confirm)
            counters["events_unmatched"] += 1
        counters["events_received"] += 1
        self._handle(vehicle, source, name, inner_fields, now, service_set)

    def _unwrap(self, vehicle: Vehicle,
                fields: Mapping[str, Any]) -> tuple[str, Mapping[str, Any], str] | None:
        payload: Any = fields.get("report_message")
        if hasattr(payload, "name"):
            name, inner = payload.name, payload.fields
            service_set = set_of(payload)
        elif isinstance(payload, bytes | bytearray):
            try:
                dialects = self._state.dialects(vehicle)
                message = self._state.catalogue.decode(bytes(payload), dialects) \
                    if dialects else self._state.catalogue.decode(bytes(payload))
            except Exception as exc:  # a DecodeError from the remote: count and drop
                log.debug("undecodable report in Event: %s", exc)
                return None
            name, inner = message.name, message.fields
            service_set = set_of(message)
        else:
            return None
        if name is None:
            return None
        return name, inner or {}, service_set


def set_of(message: Any) -> str:
    """The message set of a decoded message ("" when not known)."""
    return str(getattr(getattr(message, "definition", None), "service_set", "") or "")
