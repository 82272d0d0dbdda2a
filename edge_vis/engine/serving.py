"""Which relay serves a vehicle: the decision every relay on a DDS domain takes alike. No I/O.

Relays that reach the same vehicle agree on one of them without talking to each other
beyond their ``RelayStatus`` samples: each relay publishes, per vehicle it reaches, a
*claim* (its score for the vehicle and whether it serves it), and each relay runs
:func:`choose_server` over the same claims. Because the function is deterministic and the
inputs are shared, they reach the same answer; the relay it names serves, the others
stand by. The rules, in order:

1. Only a relay that reaches the vehicle (score > 0) is a candidate.
2. A serving candidate (the *incumbent*) keeps the vehicle unless another candidate
   scores more than ``hysteresis`` above it: link quality that wobbles does not move a
   vehicle back and forth, a clearly better link or a profile preference does.
3. Two incumbents (two relays that decided before they saw each other): the better one,
   by score then by name, keeps it; the other yields.
4. No incumbent: the best candidate by score. Equal scores are broken by a hash of the
   vehicle's id and the relay's name (rendezvous hashing), then by the lower name: two
   relays started at the same instant with equal links name the same winner, and a
   fleet within reach of several relays spreads over them instead of piling on one.

A relay acts on the answer with two more rules kept by :mod:`~edge_vis.engine.duty`: it
starts serving only when no other live relay still claims the vehicle (so a hand-over
never has two servers), and an unclaimed vehicle only after its own claim has been out
for the settle time (so its peers have seen it; a relay with no peers, at once).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Claim:
    """One relay's standing for one vehicle, as its RelayStatus says."""

    relay: str
    #: profile preference plus link quality (0..1); 0 when the relay does not reach it
    score: float
    serving: bool = False


def tie_weight(vehicle_id: str, relay: str) -> int:
    """The rendezvous weight of ``relay`` for ``vehicle_id``: the same on every relay."""
    digest = hashlib.blake2b(f"{vehicle_id}\0{relay}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big")


def choose_server(claims: Iterable[Claim], hysteresis: float,
                  vehicle_id: str = "") -> str | None:
    """The relay that should serve ``vehicle_id``, or None when no relay reaches it."""
    candidates = [c for c in claims if c.score > 0]
    if not candidates:
        return None

    def better(claim: Claim) -> tuple[float, int, str]:  # for min(): best first
        return (-claim.score, -tie_weight(vehicle_id, claim.relay), claim.relay)

    best = min(candidates, key=better)
    incumbents = [c for c in candidates if c.serving]
    if not incumbents:
        return best.relay
    incumbent = min(incumbents, key=better)
    if best.score > incumbent.score + hysteresis:
        return best.relay
    return incumbent.relay


def link_quality(heard: int, probes: int, window: int) -> float:
    """Share of the last ``window`` liveness periods in which the vehicle was heard
    (``heard`` holds one bit per period, newest lowest); 1.0 before the first period."""
    if probes <= 0:
        return 1.0
    span = min(probes, window)
    return (heard & ((1 << span) - 1)).bit_count() / span


__all__ = ["Claim", "choose_server", "link_quality", "tie_weight"]
