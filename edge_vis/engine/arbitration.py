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
