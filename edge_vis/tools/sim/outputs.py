"""What the sans-I/O vehicle logic asks its adapter to do. No I/O.

The logic never encodes transport packets itself: it returns :class:`Send` actions naming
a catalogue message and its fields, and :class:`Restarted` when a simulated reboot means
the transport must forget its sequence numbers.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from edge_vis.jaus.address import JausAddress


@dataclass(frozen=True, slots=True)
class Send:
    """Send message ``name`` with ``fields`` from one of the vehicle's components.

    ``corrupt`` names a deliberate defect the adapter applies to the encoded bytes
    (fault injection); empty for a good message.
    """

    source: JausAddress
    destination: JausAddress
    name: str
    fields: Mapping[str, Any] = field(default_factory=dict)
    corrupt: str = ""


@dataclass(frozen=True, slots=True)
class Restarted:
    """The vehicle rebooted: transport sequence numbers start again from 1."""

    vehicle: str


Action = Send | Restarted
