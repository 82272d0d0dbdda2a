"""Every report in the catalogue travels inside an Event (0x41F1) and comes out unchanged.

For each message with a code in 0x4000-0x5FFF, example bodies (every optional field
present with lists of two and edge values; then nothing optional, empty lists) are encoded,
wrapped with ``Catalogue.wrap_event``, checked byte for byte against the AS5710 Event layout
(event id u8, sequence number u8, report size u32, report incl. its code), decoded and
unwrapped with ``unwrap_event``. Generated values (``tests/strategies.py``, hypothesis)
add random bodies when that module offers a strategy per definition.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from typing import Any

import pytest

from edge_vis.catalogue import Catalogue, default_catalogue, unwrap_event
from edge_vis.codec.types import MessageDef

EVENT = 0x41F1

TESTS = Path(__file__).resolve().parents[1]
if str(TESTS) not in sys.path:
    sys.path.append(str(TESTS))


def _strategy_for() -> Any:
    """``tests/strategies.py``'s per-definition strategy, if it offers one."""
    try:
        module = importlib.import_module("strategies")
    except ImportError:
        return None
    for name in ("fields_for", "message_fields"):
        candidate = getattr(module, name, None)
        if callable(candidate):
            return candidate
    return None


# -- simple example values for any definition ------------------------------------------------

def example(t: Any, full: bool) -> Any:
    """A valid value of field type ``t``: edge values and everything present when ``full``."""
    kind = type(t).__name__
    if kind == "Int":
        return t.max if full else t.min
    if kind == "Float":
        return -1.5 if full else 0.0
    if kind == "Scaled":
        return float(t.upper if full else t.lower)
    if kind == "Enum":
        keys = sorted(t.labels) or [0]
        return keys[-1] if full else keys[0]
    if kind == "BitField":
        return {s.name: ((1 << (s.hi - s.lo + 1)) - 1 if full else 0) for s in t.subfields}
    if kind == "FixedString":
        return "R" * t.length if full else ""
    if kind == "VarString":
        text = "urn:edge-vis:test"
        if t.max_length is not None:
            text = text[: t.max_length]
        return text if full else ""
    if kind == "FixedBytes":
        return bytes(i % 256 for i in range(t.length))
    if kind == "VarBytes":
        return b"\x00\xff\x10" if full else b""
    if kind == "JausMessage":
        return b"\x02\x24\xff\x01" if full else b"\x02\x20"
    if kind == "VarFormat":
        return {"format": example(t.format, full), "data": b"abc" if full else b""}
    if kind == "Record":
        return {f.name: example(f.type, full) for f in t.fields if full or not f.optional}
    if kind == "List":
        return [example(t.element, full), example(t.element, full)] if full else []
    if kind == "Variant":
        alt = t.alternatives[-1] if full else t.alternatives[0]
        return {alt.name: example(alt.type, full)}
    raise TypeError(f"no example for {kind}")


def examples(defn: MessageDef) -> list[dict[str, Any]]:
    return [example(defn.body, True), example(defn.body, False)]


CATALOGUE = default_catalogue()
REPORTS = [d for d in CATALOGUE if 0x4000 <= d.code <= 0x5FFF]


def check_wrapped(catalogue: Catalogue, defn: MessageDef, fields: dict[str, Any],
                  event_id: int, sequence: int) -> None:
    payload = catalogue.encode(defn.code, fields)
    event = catalogue.wrap_event(event_id, sequence, payload)
    assert event[:2] == EVENT.to_bytes(2, "little")
    assert event[2] == event_id and event[3] == sequence
    assert int.from_bytes(event[4:8], "little") == len(payload)
    assert event[8:] == payload
    message = catalogue.decode(event)
    assert message.name == "Event"
    assert message.fields["report_message"] == payload
    inner = unwrap_event(message, catalogue)
    assert (inner.code, inner.name) == (defn.code, defn.name)
    assert inner.payload == payload
    assert inner.fields == catalogue.decode(payload).fields
    assert catalogue.encode(defn.code, inner.fields) == payload


def test_the_catalogue_has_reports() -> None:
    print(f"\n{len(REPORTS)} report messages (0x4000-0x5FFF) wrapped in Events")
    assert any(d.name == "ReportGlobalPose" for d in REPORTS)


@pytest.mark.parametrize("defn", REPORTS, ids=[f"{d.code:04X}-{d.name}" for d in REPORTS])
def test_report_round_trips_inside_an_event(defn: MessageDef) -> None:
    for index, fields in enumerate(examples(defn)):
        check_wrapped(CATALOGUE, defn, fields, event_id=index * 0xFF, sequence=0xFF - index)


def test_generated_reports_round_trip_inside_events() -> None:
    """Random bodies from ``tests/strategies.py`` (when it has a per-definition strategy)."""
    strategy_for = _strategy_for()
    if strategy_for is None:
        pytest.skip("tests/strategies.py offers no per-definition strategy")
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    @settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data: Any) -> None:
        defn = data.draw(st.sampled_from(REPORTS))
        fields = data.draw(strategy_for(defn))
        check_wrapped(CATALOGUE, defn, fields, data.draw(st.integers(0, 255)),
                      data.draw(st.integers(0, 255)))

    run()


def test_an_unknown_report_stays_raw_inside_an_event() -> None:
    free = next(c for c in range(0x5FFF, 0x4000, -1) if CATALOGUE.get(c) is None)
    report = free.to_bytes(2, "little") + b"\x01\x02\x03"
    inner = unwrap_event(CATALOGUE.decode(CATALOGUE.wrap_event(3, 4, report)), CATALOGUE)
    assert (inner.code, inner.name, inner.fields, inner.body) == (free, None, None,
                                                                   b"\x01\x02\x03")


def test_a_report_that_does_not_decode_is_named() -> None:
    """A truncated report inside a well-formed Event: the error names the report's code."""
    from edge_vis.errors import DecodeError

    pose = CATALOGUE.by_name("ReportGlobalPose")
    truncated = CATALOGUE.encode(pose.code, {"latitude": 1.0})[:-1]
    with pytest.raises(DecodeError) as caught:
        unwrap_event(CATALOGUE.decode(CATALOGUE.wrap_event(1, 1, truncated)), CATALOGUE)
    assert caught.value.code == pose.code
