"""Property tests: encode -> decode -> encode is the identity, for every known message.

The values come from ``tests/strategies.py`` and are exactly representable on the wire,
so ``decode(encode(x)) == x`` holds with ``==`` and the bytes of a second encoding are
identical. The compiled fast path must agree with the reference walker and must not
need it for valid input (``fallbacks`` stays 0).
"""

from __future__ import annotations

from typing import Any

import pytest
from codec_defs import ALL, catalogue_defs, ident
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from strategies import fields_for

from edge_vis.catalogue import default_catalogue
from edge_vis.codec import reference
from edge_vis.codec.bodies import compile_message, decode_body, encode_body
from edge_vis.codec.types import MessageDef

QUICK = settings(
    max_examples=15,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
THOROUGH = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def check_round_trip(defn: MessageDef, value: dict[str, Any]) -> None:
    codec = compile_message(defn)
    before = codec.fallbacks
    body = encode_body(defn, value)
    assert body == reference.encode_body(defn, value)
    decoded = decode_body(defn, body)
    assert decoded == value
    assert decoded == reference.decode_body(defn, body)
    assert encode_body(defn, decoded) == body
    assert codec.fallbacks == before, "valid input went through the reference walker"


@pytest.mark.parametrize("defn", ALL, ids=ident)
def test_test_definitions_round_trip(defn: MessageDef) -> None:
    @THOROUGH
    @given(fields_for(defn))
    def run(value: dict[str, Any]) -> None:
        check_round_trip(defn, value)

    run()


@pytest.mark.parametrize("defn", catalogue_defs(), ids=ident)
def test_catalogue_messages_round_trip(defn: MessageDef) -> None:
    @QUICK
    @given(fields_for(defn))
    def run(value: dict[str, Any]) -> None:
        check_round_trip(defn, value)

    run()


@THOROUGH
@given(st.data())
def test_payloads_round_trip_through_the_catalogue(data: st.DataObject) -> None:
    cat = default_catalogue()
    defs = list(cat)
    defn = data.draw(st.sampled_from(defs), label="message")
    value = data.draw(fields_for(defn), label="fields")
    payload = cat.encode(defn.code, value)
    assert payload[:2] == defn.code.to_bytes(2, "little")
    message = cat.decode(payload)
    assert (message.code, message.fields, message.definition) == (defn.code, value, defn)
    assert message.payload == payload
