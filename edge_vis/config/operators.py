"""Who may command: the operator allowlist of a deployment. No I/O.

JAUS has no authentication, and neither does a DDS domain without DDS Security: any
participant on the data model can publish a ``ControlRequest`` under any operator id.
The allowlist is therefore a guard against mistakes and misconfigured stations (a
training console on the live partition, a second operator with too high an authority),
not against a hostile host on the network; that needs separate networks and DDS Security
(``[dds.security]``: each operator then writes only in its own partition, so the relay
knows who sent a command).

A deployment profile lists the operators allowed to request control, each with the
highest authority it may ask with::

    [[operators]]
    id = "op1"
    max_authority = 150

    [access]
    any_operator = false      # the default; true lets anyone request (loopback demos)

A profile file (``edge-vis run --profile``) that lists nobody and does not say
``any_operator = true`` refuses every control request: an omission fails closed. (A
profile built in code, e.g. by tests, is open unless it says otherwise.) A refused
request is counted, logged and kept as the vehicle's ``last_rejection`` (published in
``ControlStatus``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType


@dataclass(frozen=True, slots=True)
class OperatorPolicy:
    """The operators allowed to request control and their maximum authority (0..255).

    ``any_operator`` admits ids not listed (with ``default_max_authority``); listed ids
    keep their own maximum either way.
    """

    operators: Mapping[str, int] = field(default_factory=lambda: MappingProxyType({}))
    any_operator: bool = False
    default_max_authority: int = 255

    @classmethod
    def open(cls) -> OperatorPolicy:
        """Anyone may request control with any authority (tests, loopback demos)."""
        return cls(any_operator=True)

    def refusal(self, operator_id: str, authority: int) -> str:
        """Why ``operator_id`` may not request control with ``authority``; "" if it may."""
        if not operator_id:
            return "control request without an operator_id refused"
        limit = self.operators.get(operator_id)
        if limit is None:
            if not self.any_operator:
                if not self.operators:
                    return (f"{operator_id} refused: the profile allows no operator "
                            f"(list [[operators]] or set access.any_operator = true)")
                return f"{operator_id} refused: not in the profile's [[operators]]"
            limit = self.default_max_authority
        if authority > limit:
            return (f"{operator_id} refused: authority {authority} above its maximum "
                    f"{limit}")
        return ""

    @property
    def closed(self) -> bool:
        """True when every request would be refused (nobody listed, not open)."""
        return not self.operators and not self.any_operator


__all__ = ["OperatorPolicy"]
