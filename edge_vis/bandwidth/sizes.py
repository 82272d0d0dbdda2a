"""How many bytes a message costs on a link, from its catalogue definition. No I/O.

The planner needs sizes before any message was seen, so they are computed from the
declarative definition: every field the query's presence vector asks for is counted as
present (a vehicle may leave some out; the plan then errs on the safe side), variable
lengths count their length prefix plus :data:`NOMINAL_VARIABLE` bytes, lists one element.
A packet on the link adds the JAUS transport header (:data:`HEADER_BYTES`, as counted in
the header's data size) and the link's framing ``overhead``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from edge_vis.codec.types import (
    BitField,
    Enum,
    FixedBytes,
    FixedString,
    Float,
    Int,
    JausMessage,
    List,
    MessageDef,
    Record,
    Scaled,
    VarBytes,
    VarFormat,
    Variant,
    VarString,
)

#: JAUS transport header bytes per packet (the data size counts them with the payload)
HEADER_BYTES = 14
#: bytes assumed for a variable-length string or byte field
NOMINAL_VARIABLE = 16
#: Event wrapper around a report: event ID, sequence number, u32 length of the report
EVENT_WRAPPER = 1 + 1 + 4


def type_size(ft: Any, presence: int | None = None) -> int:
    """Encoded bytes of a value of ``ft`` with all (or the ``presence``-selected) fields."""
    if isinstance(ft, Int | Float):
        return ft.size
    if isinstance(ft, Scaled | Enum | BitField):
        return ft.raw.size
    if isinstance(ft, FixedString | FixedBytes):
        return ft.length
    if isinstance(ft, VarString):
        nominal = NOMINAL_VARIABLE if ft.max_length is None else min(NOMINAL_VARIABLE,
                                                                    ft.max_length)
        return ft.count.size + nominal
    if isinstance(ft, VarBytes):
        return ft.count.size + NOMINAL_VARIABLE
    if isinstance(ft, VarFormat):
        return ft.format.raw.size + ft.count.size + NOMINAL_VARIABLE
    if isinstance(ft, JausMessage):
        return ft.count.size + 2 + NOMINAL_VARIABLE
    if isinstance(ft, List):
        return ft.count.size + type_size(ft.element)
    if isinstance(ft, Variant):
        return ft.tag.size + max((type_size(a.type) for a in ft.alternatives), default=0)
    if isinstance(ft, Record):
        total = ft.pv.size if ft.pv is not None else 0
        bit = 0
        for fld in ft.fields:
            if fld.optional:
                wanted = presence is None or bool(presence >> bit & 1)
                bit += 1
                if not wanted:
                    continue
            total += type_size(fld.type)
        return total
    raise TypeError(f"not a field type: {ft!r}")


def presence_of(query_fields: Mapping[str, Any]) -> int | None:
    """The presence vector a query asks for (None: every field)."""
    value = query_fields.get("presence_vector")
    return int(value) if isinstance(value, int) and not isinstance(value, bool) else None


def payload_size(defn: MessageDef, query_fields: Mapping[str, Any] | None = None) -> int:
    """Payload bytes (2-byte code + body) of ``defn`` with the requested fields present."""
    presence = presence_of(query_fields or {})
    return 2 + type_size(defn.body, presence)


def packet_bytes(payload: int, overhead: int, mtu: int = 4079) -> int:
    """Bytes on the link for a message of ``payload`` bytes, fragments included."""
    packets = max(1, math.ceil(payload / mtu))
    return payload + packets * (HEADER_BYTES + overhead)


def event_payload(report_payload: int) -> int:
    """Payload of the Event message carrying a report of ``report_payload`` bytes."""
    return 2 + EVENT_WRAPPER + report_payload
