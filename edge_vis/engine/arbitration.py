"""Operator arbitration on the DDS side: who may command a vehicle. No I/O.

Theory of operation
-------------------
Many operators may share the data model, but a vehicle obeys one at a time, as in JAUS
access control: an operator sends ``ControlRequest {vehicle_id, operator_id, authority,
action}``; a free vehicle goes to the first requester; a request with a *higher*
authority than the holder's preempts it; equal or lower is refused. The holder
releases with ``action = "release"``. Commands from anyone else are refused and counted;
the last refusal is kept for ``ControlStatus``.

The relay itself holds JAUS control of the vehicle's components while (and only while)
some operator holds the vehicle here.
"""

from __future__ import annotations

from dataclasses import dataclass

from edge_vis.jaus.address import JausAddress


@dataclass(frozen=True, slots=True)
class Holder:
    """The operator holding a vehicle and the authority it asked with."""

    operator_id: str
    authority: int


@dataclass(frozen=True, slots=True)
class Decision:
    """Outcome of a control request or release: ``changed`` when the holder changed."""

    granted: bool
    changed: bool
    reason: str = ""
    preempted: str = ""


class Arbitration:
    """Operator arbitration for one vehicle."""

    def __init__(self) -> None:
        self.holder: Holder | None = None
        self.rejected_commands = 0
        self.last_rejection = ""

    def request(self, operator_id: str, authority: int) -> Decision:
        """``operator_id`` asks for control with ``authority`` (0..255)."""
        if self.holder is None:
            self.holder = Holder(operator_id, authority)
            return Decision(True, True)
        if self.holder.operator_id == operator_id:
            changed = self.holder.authority != authority
            self.holder = Holder(operator_id, authority)
            return Decision(True, changed)
        if authority > self.holder.authority:
            previous = self.holder.operator_id
            self.holder = Holder(operator_id, authority)
            return Decision(True, True, preempted=previous)
        reason = (f"{operator_id} (authority {authority}) refused: held by "
                  f"{self.holder.operator_id} (authority {self.holder.authority})")
        self.last_rejection = reason
        return Decision(False, False, reason)

    def release(self, operator_id: str) -> Decision:
        """``operator_id`` gives control back; releasing what one does not hold is a no-op."""
        if self.holder is not None and self.holder.operator_id == operator_id:
            self.holder = None
            return Decision(True, True)
        return Decision(False, False, f"{operator_id} does not hold control")

    def allows(self, operator_id: str) -> bool:
        """True when ``operator_id`` holds the vehicle."""
        return self.holder is not None and self.holder.operator_id == operator_id

    def reject(self, reason: str) -> None:
        """Count a refused command."""
        self.rejected_commands += 1
        self.last_rejection = reason


# ---------------------------------------------------------------------------------- hand-off
#
# IOP EnhancedAccessControl/HandoffController, on the same holder: an operator that does
# not hold the vehicle asks for it (HandoffRequest), the holder sees the request and
# answers GRANTED, DENIED or WAIT (HandoffResponse). GRANTED moves the holder in one step,
# so the vehicle never has two operators; at most one request is granted, the others are
# then denied. The service's two timeouts: the holder must answer within the hand-off
# timeout (WAIT restarts it), a requester must ask again within the re-assert ("enhanced")
# timeout; zero disables either. Another JAUS client asking the vehicle for control
# reaches the holder the same way (``source`` is the vehicle component that asked, ``jaus_id``
# the vehicle's own request ID). An ``outbound`` request goes the other way: an operator
# asks for a vehicle another JAUS client holds, and the vehicle decides.

#: states of a request still waiting for the holder
OPEN = ("PENDING", "DEFERRED")
#: resolved requests kept for operators to read their outcome
KEEP_RESOLVED = 8


@dataclass(slots=True)
class HandoffEntry:
    """One hand-off request and where it stands."""

    request_id: int
    requester: str
    authority: int
    explanation: str = ""
    state: str = "PENDING"
    reason: str = ""
    answer_by: float | None = None
    reassert_by: float | None = None
    source: JausAddress | None = None
    jaus_id: int = 0
    outbound: bool = False

    @property
    def open(self) -> bool:
        """True while the holder has not decided (PENDING or DEFERRED)."""
        return self.state in OPEN


class Handoffs:
    """The hand-off requests of one vehicle, decided against its :class:`Arbitration`."""

    def __init__(self) -> None:
        self.entries: list[HandoffEntry] = []
        self._next_id = 0

    def open(self) -> list[HandoffEntry]:
        """Requests waiting for the holder, oldest first."""
        return [e for e in self.entries if e.open]

    def find(self, request_id: int) -> HandoffEntry | None:
        """The open request ``request_id``, if any."""
        return next((e for e in self.entries if e.open and e.request_id == request_id), None)

    def ask(self, arb: Arbitration, requester: str, authority: int, explanation: str,
            now: float, answer_within: float, reassert_within: float,
            source: JausAddress | None = None, jaus_id: int = 0) -> HandoffEntry:
        """``requester`` asks for the vehicle: a new request, or its open one renewed."""
        entry = next((e for e in self.entries if e.open and e.requester == requester
                      and e.source == source), None)
        if entry is None:
            entry = HandoffEntry(self._fresh_id(), requester, authority, explanation,
                                 answer_by=now + answer_within if answer_within > 0 else None,
                                 source=source, jaus_id=jaus_id)
            self.entries.append(entry)
        entry.authority, entry.explanation, entry.jaus_id = authority, explanation, jaus_id
        entry.reassert_by = now + reassert_within if reassert_within > 0 else None
        if arb.holder is None:
            self.resolve(entry, "DENIED", "nobody holds the vehicle: ask with ControlRequest")
        elif arb.holder.operator_id == requester:
            arb.holder = Holder(requester, authority)
            self.resolve(entry, "GRANTED", "already the holder (authority updated)")
        self._trim()
        return entry

    def ask_vehicle(self, requester: str, authority: int, explanation: str, now: float,
                    answer_within: float, reassert_within: float,
                    source: JausAddress) -> HandoffEntry:
        """``requester`` asks for a vehicle another JAUS client holds: the vehicle's
        EnhancedAccessControl at ``source`` decides (a new request, or its open one)."""
        entry = next((e for e in self.open() if e.requester == requester and e.outbound),
                     None)
        if entry is None:
            entry = HandoffEntry(self._fresh_id(), requester, authority, explanation,
                                 answer_by=now + answer_within if answer_within > 0 else None,
                                 source=source, outbound=True)
            self.entries.append(entry)
        entry.authority, entry.explanation = authority, explanation
        entry.reassert_by = now + reassert_within if reassert_within > 0 else None
        entry.reason = entry.reason or f"asked {source}: held by another JAUS client"
        self._trim()
        return entry

    def answer(self, arb: Arbitration, operator_id: str, request_id: int, response: str,
               now: float, answer_within: float) -> tuple[HandoffEntry | None, str]:
        """The holder answers request ``request_id``: (the request, "" or why refused)."""
        if not arb.allows(operator_id):
            return None, f"{operator_id} does not hold the vehicle: cannot answer hand-offs"
        entry = self.find(request_id)
        if entry is None or entry.outbound:
            return None, f"no open hand-off request {request_id}"
        if response == "GRANTED":
            arb.holder = Holder(entry.requester, entry.authority)
            self.resolve(entry, "GRANTED", f"granted by {operator_id}")
            for other in self.open():
                self.resolve(other, "DENIED", f"request {request_id} was granted")
        elif response == "DENIED":
            self.resolve(entry, "DENIED", f"refused by {operator_id}")
        elif response == "WAIT":
            entry.state, entry.reason = "DEFERRED", f"{operator_id} will decide later"
            entry.answer_by = now + answer_within if answer_within > 0 else None
        else:
            return None, f"unknown hand-off response {response!r} (GRANTED, DENIED, WAIT)"
        self._trim()
        return entry, ""

    def cancel(self, requester: str, source: JausAddress | None = None,
               keep: frozenset[int] = frozenset()) -> bool:
        """``requester`` withdraws its open requests (those whose vehicle ID is not in
        ``keep``); True when one was open."""
        gone = [e for e in self.open() if e.requester == requester and e.source == source
                and e.jaus_id not in keep and not e.outbound]
        for entry in gone:
            self.resolve(entry, "CANCELLED", "withdrawn by the requester")
        return bool(gone)

    def expire(self, now: float) -> list[HandoffEntry]:
        """Requests whose holder did not answer, or whose requester did not ask again, in
        time: resolved TIMEOUT and returned."""
        late = [e for e in self.open()
                if (e.answer_by is not None and now >= e.answer_by)
                or (e.reassert_by is not None and now >= e.reassert_by)]
        for entry in late:
            who = "the holder did not answer" if entry.answer_by is not None and \
                now >= entry.answer_by else "the requester did not ask again"
            self.resolve(entry, "TIMEOUT", who + " in time")
        self._trim()
        return late

    def settle(self, arb: Arbitration) -> bool:
        """The holder changed by other means: a requester that now holds the vehicle is
        GRANTED; with nobody holding it every request is DENIED. True when one changed."""
        changed = False
        for entry in self.open():
            if entry.outbound:  # the vehicle decides those
                continue
            if arb.holder is None:
                self.resolve(entry, "DENIED", "released: ask with ControlRequest")
                changed = True
            elif arb.holder.operator_id == entry.requester and entry.source is None:
                self.resolve(entry, "GRANTED", "took control")
                changed = True
        return changed

    def next_deadline(self) -> float | None:
        """When the earliest open request times out."""
        times = [t for e in self.open() for t in (e.answer_by, e.reassert_by) if t is not None]
        return min(times) if times else None

    def clear(self) -> None:
        """The vehicle was lost: every open request is void."""
        for entry in self.open():
            self.resolve(entry, "NOT_AVAILABLE", "vehicle lost")

    def resolve(self, entry: HandoffEntry, state: str, reason: str) -> None:
        """Decide ``entry``: ``state`` (GRANTED, DENIED, TIMEOUT...) because ``reason``."""
        entry.state, entry.reason = state, reason
        entry.answer_by = entry.reassert_by = None

    def _fresh_id(self) -> int:
        taken = {e.request_id for e in self.open()}
        for _ in range(255):
            self._next_id = self._next_id % 255 + 1
            if self._next_id not in taken:
                return self._next_id
        raise ValueError("255 hand-off requests open")

    def _trim(self) -> None:
        resolved = [e for e in self.entries if not e.open]
        drop = {id(e) for e in resolved[:-KEEP_RESOLVED]}
        self.entries = [e for e in self.entries if id(e) not in drop]
