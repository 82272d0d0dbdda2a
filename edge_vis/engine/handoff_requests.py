"""Hand-off of a vehicle between operators (IOP EnhancedAccessControl / HandoffController).

No I/O. The relay plays the IOP HandoffController for the operator holding a vehicle:

* an operator that does not hold the vehicle publishes ``HandoffRequest`` (``action``
  REQUEST, or CANCEL to withdraw); another JAUS client asking the vehicle's
  EnhancedAccessControl for control reaches the relay as ``RequestReleaseControl``;
* the holder sees every request in ``HandoffStatus`` and answers with ``HandoffResponse``
  (GRANTED, DENIED or WAIT); a request to another JAUS client is answered on the wire with
  ``ConfirmReleaseControl``;
* an operator asking for a vehicle nobody here holds but another JAUS client does (its
  components with EnhancedAccessControl report that client in ReportControl) makes the
  relay ask the vehicle with RequestHandoff; the vehicle answers with
  ConfirmHandoffRequest (QUEUED, DEFERRED, then GRANTED, DENIED, TIMEOUT ...), and once
  GRANTED the relay holds the component and the requester holds the vehicle here; a
  CANCEL sends RemoveHandoffRequest;
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
from edge_vis.engine.arbitration import HandoffEntry, Holder
from edge_vis.engine.discovery import pick
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import HandoffView

log = logging.getLogger(__name__)

ENHANCED_ACCESS_CONTROL = "urn:jaus:jss:iop:EnhancedAccessControl"
#: ConfirmReleaseControl response codes (HandoffController)
RELEASE_CODES = {"GRANTED": 0, "DENIED": 1, "WAIT": 2}
#: ConfirmHandoffRequest response codes (EnhancedAccessControl)
CONFIRM_CODES = {0: "GRANTED", 1: "NOT_AVAILABLE", 2: "TIMEOUT", 3: "DENIED", 4: "QUEUED",
                 5: "DEFERRED", 6: "INSUFFICIENT_AUTHORITY"}
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
            asked = [e for e in handoffs.open() if e.outbound and e.requester == operator]
            for entry in asked:  # withdrawn at the vehicle too
                assert entry.source is not None
                self._state.send(entry.source, "RemoveHandoffRequest", {"id": entry.jaus_id},
                                 "control")
                handoffs.resolve(entry, "CANCELLED", "withdrawn by the requester")
            if handoffs.cancel(operator) or asked:
                self._changed(vehicle, "handoff", now)
            return
        authority = int(sample.get("authority", 0))
        refusal = self._state.profile.operators.refusal(operator, authority)
        held = self._held_elsewhere(vehicle)
        if vehicle.arbitration.holder is None and held and not refusal:
            timeout = vehicle.handoff_timeouts
            entry = handoffs.ask_vehicle(
                operator, authority, str(sample.get("explanation", "")), now,
                timeout[0] if timeout[0] is not None else control.handoff_timeout,
                timeout[1] if timeout[1] is not None else control.handoff_reassert_timeout,
                held[0])
            for address in held:  # asked again: the service's re-assertion
                self._state.send(address, "RequestHandoff", {
                    "authority_code": authority, "explanation": entry.explanation}, "control")
            self._changed(vehicle, "handoff", now)
            return
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

    def on_confirm_handoff(self, vehicle: Vehicle, source: JausAddress,
                           fields: Mapping[str, Any], now: float) -> None:
        """ConfirmHandoffRequest: the vehicle's answer to the relay's RequestHandoff."""
        handoffs = vehicle.handoffs
        asked = [e for e in handoffs.open() if e.outbound]
        entry = next((e for e in asked if e.source == source), asked[0] if asked else None)
        if entry is None:
            self._state.counters["handoff_answers_unasked"] += 1
            return
        answer = CONFIRM_CODES.get(int(pick(fields, "response_code", 3)), "DENIED")
        arb = vehicle.arbitration
        if answer == "GRANTED" and arb.holder is None:
            previous = arb.holder
            arb.holder = Holder(entry.requester, entry.authority)
            handoffs.resolve(entry, "GRANTED", f"granted by {source}")
            self._holder_moved(vehicle, previous, now)  # the relay confirms its control
        elif answer == "GRANTED":
            handoffs.resolve(entry, "DENIED", f"{arb.holder.operator_id if arb.holder else ''}"
                                              " took the vehicle meanwhile")
        elif answer in ("QUEUED", "DEFERRED"):
            entry.state = "PENDING" if answer == "QUEUED" else "DEFERRED"
            entry.jaus_id = int(pick(fields, "id", 0))
            entry.reason = f"{answer.lower()} by {source}"
        else:
            handoffs.resolve(entry, answer, f"{source} answered {answer}")
        self._changed(vehicle, "handoff", now)

    def _held_elsewhere(self, vehicle: Vehicle) -> list[JausAddress]:
        """Components with EnhancedAccessControl another JAUS client controls."""
        return [a for a in vehicle.providers(ENHANCED_ACCESS_CONTROL)
                if (h := vehicle.holders.get(a)) is not None and h.controller is not None
                and not h.is_relay]

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
