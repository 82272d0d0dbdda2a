"""JAUS addresses (subsystem.node.component) and wildcard matching. No I/O.

A JAUS ID is 32 bits: ``subsystem << 16 | node << 8 | component``, sent little-endian.
65535 (subsystem) and 255 (node, component) are wildcards that match anything and make a
destination a broadcast.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

SUBSYSTEM_WILDCARD = 0xFFFF
NODE_WILDCARD = 0xFF
COMPONENT_WILDCARD = 0xFF


@dataclass(frozen=True, slots=True, order=True)
class JausAddress:
    """A JAUS component address. Text form ``S.N.C`` (decimal), e.g. ``126.1.199``."""

    subsystem: int
    node: int
    component: int

    def __post_init__(self) -> None:
        if not 0 <= self.subsystem <= 0xFFFF:
            raise ValueError(f"subsystem {self.subsystem} out of range 0..65535")
        if not 0 <= self.node <= 0xFF:
            raise ValueError(f"node {self.node} out of range 0..255")
        if not 0 <= self.component <= 0xFF:
            raise ValueError(f"component {self.component} out of range 0..255")

    @classmethod
    def parse(cls, text: str) -> JausAddress:
        """Parse ``S.N.C``; ``*`` stands for the wildcard of that position."""
        parts = text.strip().split(".")
        if len(parts) != 3:
            raise ValueError(f"JAUS address {text!r} is not of the form S.N.C")
        wild = (SUBSYSTEM_WILDCARD, NODE_WILDCARD, COMPONENT_WILDCARD)
        try:
            values = [w if p == "*" else int(p, 10) for p, w in zip(parts, wild, strict=True)]
        except ValueError:
            raise ValueError(f"JAUS address {text!r} has a non-numeric part") from None
        return cls(*values)

    @classmethod
    def from_id(cls, value: int) -> JausAddress:
        """Build from the 32-bit integer ID (cached: every packet header carries two)."""
        if cls is JausAddress:
            return _from_id(value)
        return cls((value >> 16) & 0xFFFF, (value >> 8) & 0xFF, value & 0xFF)

    @property
    def id(self) -> int:
        """The 32-bit integer ID."""
        return (self.subsystem << 16) | (self.node << 8) | self.component

    @property
    def is_broadcast(self) -> bool:
        """True when any position is a wildcard."""
        return (
            self.subsystem == SUBSYSTEM_WILDCARD
            or self.node == NODE_WILDCARD
            or self.component == COMPONENT_WILDCARD
        )

    def matches(self, other: JausAddress) -> bool:
        """True when ``other`` is addressed by ``self`` (wildcards in ``self`` match anything)."""
        return (
            (self.subsystem in (SUBSYSTEM_WILDCARD, other.subsystem))
            and (self.node in (NODE_WILDCARD, other.node))
            and (self.component in (COMPONENT_WILDCARD, other.component))
        )

    def __hash__(self) -> int:
        # the 32-bit ID: equal exactly when the addresses are equal, and half the cost of
        # the generated hash of a tuple (the router hashes several addresses per packet)
        return (self.subsystem << 16) | (self.node << 8) | self.component

    def __str__(self) -> str:
        return f"{self.subsystem}.{self.node}.{self.component}"


@functools.lru_cache(maxsize=4096)
def _from_id(value: int) -> JausAddress:
    return JausAddress((value >> 16) & 0xFFFF, (value >> 8) & 0xFF, value & 0xFF)


#: addresses decoded so far, by ID: the packet decoder looks them up inline (a dict
#: lookup costs a fraction of a call through ``lru_cache``); bounded by
#: :func:`address_from_id`, which fills it
ADDRESSES: dict[int, JausAddress] = {}


def address_from_id(value: int) -> JausAddress:
    """:meth:`JausAddress.from_id`, remembered in :data:`ADDRESSES` (at most 4,096)."""
    address = ADDRESSES.get(value)
    if address is None:
        if len(ADDRESSES) >= 4096:
            ADDRESSES.clear()
        address = ADDRESSES[value] = _from_id(value)
    return address


BROADCAST = JausAddress(SUBSYSTEM_WILDCARD, NODE_WILDCARD, COMPONENT_WILDCARD)
