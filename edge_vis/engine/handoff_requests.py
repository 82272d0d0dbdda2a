"""Hand-off of a vehicle between operators (IOP EnhancedAccessControl / HandoffController).

No I/O. The relay plays the IOP HandoffController for the operator holding a vehicle:

* an operator that does not hold the vehicle publishes ``HandoffRequest`` (``action``
  REQUEST, or CANCEL to withdraw); another JAUS client asking the vehicle's
  EnhancedAccessControl for control reaches the relay as ``RequestReleaseControl``;
* the holder sees every request in ``HandoffStatus`` and answers with ``HandoffResponse``
  (GRANTED, DENIED or WAIT); a request to another JAUS client is answered on the wire with
  ``ConfirmReleaseControl``;
* the decisions, and the timeouts, are :class:`~edge_vis.engine.arbitration.Handoffs` on
  the vehicle's arbitration, so a grant moves the one holder and the old holder's queued
  commands are void, exactly as when control changes through ``ControlRequest``.

A vehicle with EnhancedAccessControl is asked its hand-off and re-assert timeouts once
found (QueryHandoffTimeout, QueryEnhancedTimeout); requests from other JAUS clients lapse
after the vehicle's hand-off timeout. Translators are told ``"handoff"`` when a request
changes, and ``"control"`` when a grant moved the holder.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from edge_vis.engine.access import Access
from edge_vis.engine.arbitration import HandoffEntry
from edge_vis.engine.discovery import pick
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import HandoffView

log = logging.getLogger(__name__)

ENHANCED_ACCESS_CONTROL = "urn:jaus:jss:iop:EnhancedAccessControl"
#: ConfirmReleaseControl response codes (HandoffController)
RELEASE_CODES = {"GRANTED": 0, "DENIED": 1, "WAIT": 2}
#: the topics operators publish
TOPICS = ("HandoffRequest", "HandoffResponse")


def _text(value: Any) -> str:
    """An enum member, its name or a string, upper case."""
    return str(getattr(value, "name", value) or "").strip().upper()


class HandoffRequests:
    """Applies HandoffRequest/HandoffResponse samples and the vehicle's hand-off messages."""

    def __init__(self, state: EngineState, access: Access, changed: Changed) -> None:
        self._state = state
        self._access = access
        self._changed = changed

    # -- DDS -------------------------------------------------------------------------------

    def on_sample(self, topic: str, sample: Mapping[str, Any], now: float) -> None:
        """One HandoffRequest or HandoffResponse sample at ``now``."""
        state = self._state
        vehicle = state.by_id.get(str(sample.get("vehicle_id", "")))
        if vehicle is None:
            state.counters["handoff_unknown_vehicle"] += 1
            return
        state.touch(vehicle)
        operator = str(sample.get("operator_id", ""))
        if topic == "HandoffRequest":
            self._request(vehicle, operator, sample, now)
        else:
            self._response(vehicle, operator, sample, now)

    def _request(self, vehicle: Vehicle, operator: str, sample: Mapping[str, Any],
                 now: float) -> None:
        control = self._state.profile.control
        handoffs = vehicle.handoffs
        if _text(sample.get("action", "REQUEST")) == "CANCEL":
            if handoffs.cancel(operator):
                self._changed(vehicle, "handoff", now)
            return
        authority = int(sample.get("authority", 0))
        refusal = self._state.profile.operators.refusal(operator, authority)
        entry = handoffs.ask(vehicle.arbitration, operator, authority,
                             str(sample.get("explanation", "")), now,
                             control.handoff_timeout, control.handoff_reassert_timeout)
        if refusal:  # not in the profile's allowlist (edge_vis.config.operators)
            handoffs.resolve(entry, "INSUFFICIENT_AUTHORITY", refusal)
            self._state.counters["handoff_requests_refused"] += 1
        self._changed(vehicle, "handoff", now)

    def _response(self, vehicle: Vehicle, operator: str, sample: Mapping[str, Any],
                  now: float) -> None:
        state = self._state
        arb = vehicle.arbitration
        previous = arb.holder
        response = _text(sample.get("response", ""))
        entry, refusal = vehicle.handoffs.answer(
            arb, operator, int(sample.get("request_id", 0)), response, now,
            state.profile.control.handoff_timeout)
        if entry is None:
            state.counters["handoff_responses_refused"] += 1
            arb.last_rejection = refusal
            self._changed(vehicle, "control", now)
            return
        if entry.source is not None:
            # another JAUS client asked through the vehicle: the vehicle decides, the
            # operator only answers; a granted vehicle is another client's from now on
            state.send(entry.source, "ConfirmReleaseControl", {"release_control_list": [
                {"id": entry.jaus_id, "response_code": RELEASE_CODES[response]}]}, "control")
            if response == "GRANTED":
                arb.holder = None
        self._holder_moved(vehicle, previous, now)
        self._changed(vehicle, "handoff", now)

    # -- JAUS ------------------------------------------------------------------------------

    def on_release_request(self, vehicle: Vehicle, source: JausAddress,
                           fields: Mapping[str, Any], now: float) -> None:
        """RequestReleaseControl: the vehicle lists the JAUS clients asking for control."""
        arb = vehicle.arbitration
        if arb.holder is None:  # nobody here to ask: the vehicle's own timer answers
            self._state.counters["handoff_release_unheld"] += 1
            return
        handoffs = vehicle.handoffs
        timeout = vehicle.handoff_timeouts[0]
        answer_within = timeout if timeout is not None else \
            self._state.profile.control.handoff_timeout
        listed: dict[str, set[int]] = {}
        for item in pick(fields, "request_release_control_list", []) or []:
            requester = "jaus:{}.{}.{}".format(*(int(item.get(k, 0)) for k in (
                "src_subsystem_id", "src_node_id", "src_component_id")))
            jaus_id = int(item.get("id", 0))
            listed.setdefault(requester, set()).add(jaus_id)
            known = next((e for e in handoffs.open() if e.source == source
                          and e.jaus_id == jaus_id and e.requester == requester), None)
            if known is None:
                handoffs.ask(arb, requester, int(item.get("authority_code", 0)),
                             str(item.get("explanation", "")), now, answer_within, 0.0,
                             source=source, jaus_id=jaus_id)
        for entry in handoffs.open():  # no longer listed: withdrawn or decided elsewhere
            if entry.source == source and entry.jaus_id not in listed.get(entry.requester,
                                                                          set()):
                handoffs.resolve(entry, "CANCELLED", "no longer listed by the vehicle")
        self._changed(vehicle, "handoff", now)

    def on_timeouts(self, vehicle: Vehicle, name: str, fields: Mapping[str, Any],
                    now: float) -> None:
        """ReportHandoffTimeout / ReportEnhancedTimeout: the vehicle's timeouts (s)."""
        value = float(pick(fields, "timeout", 0))
        handoff, reassert = vehicle.handoff_timeouts
        vehicle.handoff_timeouts = (value, reassert) if name == "ReportHandoffTimeout" \
            else (handoff, value)
        self._changed(vehicle, "handoff", now)

    # -- timer -----------------------------------------------------------------------------

    def poll(self, vehicle: Vehicle, now: float) -> None:
        """Timeouts that are due; the vehicle's timeouts asked once after it is found."""
        state = self._state
        if vehicle.online and vehicle.services_known and not state.shutting_down \
                and vehicle.handoff_round != vehicle.times_lost:
            vehicle.handoff_round = vehicle.times_lost
            for address in vehicle.providers(ENHANCED_ACCESS_CONTROL)[:1]:
                state.send(address, "QueryHandoffTimeout", {}, "telemetry")
                state.send(address, "QueryEnhancedTimeout", {}, "telemetry")
        due = vehicle.handoffs.next_deadline()
        if due is not None and now >= due:
            for entry in vehicle.handoffs.expire(now):
                log.info("vehicle %s: hand-off request %d from %s: %s", vehicle.vehicle_id,
                         entry.request_id, entry.requester, entry.reason)
            self._changed(vehicle, "handoff", now)

    def settle(self, vehicle: Vehicle, now: float) -> None:
        """Control changed through ControlRequest: requests follow the new holder."""
        if vehicle.handoffs.settle(vehicle.arbitration):
            self._changed(vehicle, "handoff", now)

    def _holder_moved(self, vehicle: Vehicle, previous: Any, now: float) -> None:
        holder = vehicle.arbitration.holder
        if (previous is None) != (holder is None) or (
                previous is not None and holder is not None
                and previous.operator_id != holder.operator_id):
            for slot in vehicle.commands.values():  # the old holder's intent is void
                self._state.counters["commands_dropped"] += slot.clear()
            log.info("vehicle %s handed off: %s -> %s", vehicle.vehicle_id,
                     previous.operator_id if previous else "nobody",
                     holder.operator_id if holder else "another JAUS client")
        self._access.update(vehicle, now)
        self._changed(vehicle, "control", now)


def handoff_view(entry: HandoffEntry) -> HandoffView:
    """What a translator sees of one request (``VehicleView.handoffs``)."""
    return HandoffView(entry.request_id, entry.requester, entry.authority, entry.explanation,
                       entry.state, entry.reason,
                       str(entry.source) if entry.source is not None else "")
