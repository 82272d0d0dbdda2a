"""Hypothesis strategies for codec values, reusable by any test.

``values_for(field_type)`` and ``fields_for(message_def)`` generate only values the wire
can carry *exactly*, so that ``decode(encode(x)) == x`` holds with ``==``: a scaled real is
made from a raw integer the way the engine decodes it (``raw * scale + bias``), f32 values
are f32-representable, fixed strings have no trailing NULs (decoding strips them), and so
on. Optional record fields are present or absent at random; lists are short.

Import from a test module (the ``tests`` folder is not a package)::

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # .../tests
    from strategies import fields_for, values_for
"""

from __future__ import annotations

import random
import struct
from typing import Any

from hypothesis import strategies as st

from edge_vis.codec.bodies import scaling
from edge_vis.codec.layout import subfield_mask
from edge_vis.codec.reference import scaled_raw
from edge_vis.codec.types import (
    BitField,
    Enum,
    FieldType,
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

#: longest generated list / counted string or byte field (keeps examples small and fast)
MAX_LIST = 3
MAX_DATA = 24

LATIN1 = st.characters(min_codepoint=0, max_codepoint=255)


def scaled_value(ft: Scaled, raw: int) -> float:
    """The real the engine decodes from ``raw``, nudged to a value that re-encodes to itself.

    For wide integers (u64) or far-off biases ``raw * scale + bias`` may round to a float
    that encodes to a neighbouring integer; one or two steps reach a fixed point.
    """
    scale, bias = scaling(ft)
    value = raw * scale + bias
    for _ in range(4):
        again = scaled_raw(ft, value) * scale + bias
        if again == value:
            break
        value = again
    return value


def _fixed_point(ft: Scaled, value: float) -> bool:
    scale, bias = scaling(ft)
    return scaled_raw(ft, value) * scale + bias == value


def values_for(ft: FieldType) -> st.SearchStrategy[Any]:
    """Decoded-form values of ``ft`` that survive encode -> decode unchanged."""
    if isinstance(ft, Int):
        return st.integers(ft.min, ft.max)
    if isinstance(ft, Float):
        if ft.bits == 32:
            return st.floats(width=32, allow_nan=False)
        return st.floats(allow_nan=False)
    if isinstance(ft, Scaled):
        raw = ft.raw
        edges = st.sampled_from([raw.min, raw.max, (raw.min + raw.max) // 2])
        return (
            st.one_of(edges, st.integers(raw.min, raw.max))
            .map(lambda r: scaled_value(ft, r))
            .filter(lambda v: _fixed_point(ft, v))
        )
    if isinstance(ft, Enum):
        labelled = sorted(ft.labels)
        if labelled:
            return st.one_of(st.sampled_from(labelled), st.integers(ft.raw.min, ft.raw.max))
        return st.integers(ft.raw.min, ft.raw.max)
    if isinstance(ft, BitField):
        return st.fixed_dictionaries(
            {s.name: st.integers(0, subfield_mask(s.lo, s.hi)) for s in ft.subfields}
        )
    if isinstance(ft, FixedString):
        return st.text(LATIN1, max_size=ft.length).map(lambda s: s.rstrip("\x00"))
    if isinstance(ft, VarString):
        top = min(ft.count.max, MAX_DATA)
        if ft.max_length is not None:
            top = min(top, ft.max_length)
        return st.text(LATIN1, max_size=top)
    if isinstance(ft, FixedBytes):
        return st.binary(min_size=ft.length, max_size=ft.length)
    if isinstance(ft, VarBytes):
        return st.binary(max_size=min(ft.count.max, MAX_DATA))
    if isinstance(ft, JausMessage):
        return st.binary(min_size=2, max_size=min(ft.count.max, MAX_DATA))
    if isinstance(ft, VarFormat):
        return st.fixed_dictionaries(
            {
                "format": st.integers(ft.format.raw.min, ft.format.raw.max),
                "data": st.binary(max_size=min(ft.count.max, MAX_DATA)),
            }
        )
    if isinstance(ft, Record):
        mandatory = {f.name: values_for(f.type) for f in ft.fields if not f.optional}
        optional = {f.name: values_for(f.type) for f in ft.fields if f.optional}
        return st.fixed_dictionaries(mandatory, optional=optional)
    if isinstance(ft, List):
        return st.lists(values_for(ft.element), max_size=min(ft.count.max, MAX_LIST))
    if isinstance(ft, Variant):
        return st.one_of(
            [values_for(a.type).map(lambda v, n=a.name: {n: v}) for a in ft.alternatives]
        )
    raise TypeError(f"not a field type: {ft!r}")


def fields_for(defn: MessageDef) -> st.SearchStrategy[dict[str, Any]]:
    """Body dicts of ``defn`` that survive encode -> decode unchanged."""
    return values_for(defn.body)


def random_value(ft: FieldType, rng: random.Random, *, all_optional: bool = False) -> Any:
    """One value like :func:`values_for` draws, from a plain ``random.Random``.

    For loops outside hypothesis (fuzzing by mutation, benchmarks). With ``all_optional``
    every optional record field is present.
    """
    if isinstance(ft, Int):
        return rng.randint(ft.min, ft.max)
    if isinstance(ft, Float):
        value = rng.uniform(-1e6, 1e6)
        return struct.unpack("<f", struct.pack("<f", value))[0] if ft.bits == 32 else value
    if isinstance(ft, Scaled):
        return scaled_value(ft, rng.randint(ft.raw.min, ft.raw.max))
    if isinstance(ft, Enum):
        return rng.randint(ft.raw.min, ft.raw.max)
    if isinstance(ft, BitField):
        return {s.name: rng.randint(0, subfield_mask(s.lo, s.hi)) for s in ft.subfields}
    if isinstance(ft, FixedString | VarString):
        top = ft.length if isinstance(ft, FixedString) else min(ft.count.max, MAX_DATA)
        if isinstance(ft, VarString) and ft.max_length is not None:
            top = min(top, ft.max_length)
        text = "".join(chr(rng.randint(32, 255)) for _ in range(rng.randint(0, top)))
        return text
    if isinstance(ft, FixedBytes):
        return rng.randbytes(ft.length)
    if isinstance(ft, VarBytes):
        return rng.randbytes(rng.randint(0, min(ft.count.max, MAX_DATA)))
    if isinstance(ft, JausMessage):
        return rng.randbytes(rng.randint(2, min(ft.count.max, MAX_DATA)))
    if isinstance(ft, VarFormat):
        size = rng.randint(0, min(ft.count.max, MAX_DATA))
        return {"format": rng.randint(ft.format.raw.min, ft.format.raw.max),
                "data": rng.randbytes(size)}
    if isinstance(ft, Record):
        return {
            f.name: random_value(f.type, rng, all_optional=all_optional)
            for f in ft.fields
            if not f.optional or all_optional or rng.random() < 0.5
        }
    if isinstance(ft, List):
        n = rng.randint(0, min(ft.count.max, MAX_LIST))
        return [random_value(ft.element, rng, all_optional=all_optional) for _ in range(n)]
    if isinstance(ft, Variant):
        alt = rng.choice(ft.alternatives)
        return {alt.name: random_value(alt.type, rng, all_optional=all_optional)}
    raise TypeError(f"not a field type: {ft!r}")


def random_fields(
    defn: MessageDef, rng: random.Random, *, all_optional: bool = False
) -> dict[str, Any]:
    """One body dict of ``defn`` (see :func:`random_value`)."""
    return random_value(defn.body, rng, all_optional=all_optional)
