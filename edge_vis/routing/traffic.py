"""Link scheduling rules the router applies to its per-link queues. No I/O, no clock.

The router (:mod:`edge_vis.routing.router`) already keeps one queue per JAUS header priority per
link, serves the highest first and paces a link with a byte budget. What this module adds:

* **traffic classes** - control and commands > liveness > telemetry > bulk. The engine
  tags every message with its class (``SendMessage.traffic_class``); the link profile maps
  each class to a JAUS header priority (:meth:`LinkSpec.priority_of`), so the router's
  queues serve them in that order and a full queue drops telemetry before a command.
* **latest wins** - a report, an Event or a query still waiting in a telemetry or bulk
  queue is replaced by a newer one for the same sender, receiver and report
  (:func:`latest_wins_key`): nothing stale waits, and a queue cannot grow faster than the
  number of distinct reports.
* **fragmentation** - messages larger than the link profile's MTU are cut into packets
  (the router does it at the link's MTU), and the queues pick the next packet after each
  one, so a command waits behind at most one fragment of a large message.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass

from edge_vis.jaus.transport import AckNak, DataFlags, Packet

#: Event (AS5710): wraps a report; the inner report's code follows a 6-byte prefix
EVENT_CODE = 0x41F1
_EVENT_INNER = 2 + 1 + 1 + 4
#: header priorities at or below this one are latest-wins (telemetry and bulk by default)
LATEST_WINS_MAX_PRIORITY = 1


def latest_wins_key(packet: Packet) -> Hashable | None:
    """What a newer packet supersedes in a queue, or None if it never replaces anything.

    Reports (0x4000-0x5FFF) and Events are keyed by sender, receiver and report code;
    queries (0x2000-0x3FFF) by sender, receiver and the whole payload (a query asking for
    something else is not the same query). Fragments and ACK-requested packets are never
    replaced: the receiver counts on every one of them.
    """
    if packet.data_flags != DataFlags.SINGLE or packet.ack_nak != AckNak.NONE:
        return None
    code = packet.message_code
    if code is None:
        return None
    ends = (packet.source.id, packet.destination.id)
    if code == EVENT_CODE:
        payload = packet.payload
        if len(payload) < _EVENT_INNER + 2:
            return None
        return (*ends, code, int.from_bytes(payload[_EVENT_INNER:_EVENT_INNER + 2], "little"))
    if 0x4000 <= code < 0x6000:
        return (*ends, code)
    if 0x2000 <= code < 0x4000:
        return (*ends, packet.payload)
    return None


def priority_for(traffic_class: str, requested: int, priorities: Mapping[str, int]) -> int:
    """The JAUS header priority of a message of ``traffic_class``.

    ``requested`` (the priority a translator asked for) is kept when higher: a
    safety-critical command stays safety-critical.
    """
    if not traffic_class or traffic_class not in priorities:
        return requested
    return max(requested, priorities[traffic_class])


def class_names(priority: int, priorities: Mapping[str, int]) -> str:
    """The traffic classes a header priority serves (``"control/command"``), for status."""
    names = [name for name, value in priorities.items() if value == priority]
    return "/".join(names) if names else f"priority {priority}"


@dataclass(frozen=True, order=True, slots=True)
class QueueDrop:
    """Why a link queue dropped a packet, as data: ``cause`` and the header priority it was
    queued at (None where the priority does not matter). Status names the traffic classes
    of that priority on the link's profile (:meth:`named`), never by rewriting text."""

    cause: str
    priority: int | None = None

    def __str__(self) -> str:
        return self.cause if self.priority is None else f"{self.cause} (priority {self.priority})"

    def named(self, priorities: Mapping[str, int]) -> str:
        """``queue full (telemetry)``: the cause with the classes its priority serves."""
        if self.priority is None:
            return self.cause
        return f"{self.cause} ({class_names(self.priority, priorities)})"
