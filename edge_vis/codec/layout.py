"""Static facts about a field-type tree: scaling, sizes, tag tables, definition checks. No I/O.

Both codec paths (the compiled fast path in :mod:`edge_vis.codec.compiler` and the
reference walker in :mod:`edge_vis.codec.reference`) take these facts from here, so that
they cannot disagree on, for instance, the bias of a signed scaled integer.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from edge_vis.codec.types import (
    BitField,
    Enum,
    Field,
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

#: types that occupy a fixed number of bytes and decode without looking at other fields
PRIMITIVES = (Int, Float, Scaled, Enum, BitField, FixedString, FixedBytes)


def scaling(scaled: Scaled) -> tuple[float, float]:
    """``(scale, bias)`` of a scaled integer: ``real = raw * scale + bias``.

    ``scale = (upper - lower) / (2**bits - 1)`` (AS5684 scale_range). The bias is
    ``lower`` for an unsigned raw integer, so ``lower`` is raw 0 and ``upper`` is the largest
    raw value. For a signed raw integer the bias is the midpoint ``(upper + lower) / 2``,
    so raw 0 is the middle of the range. (The JAUS Toolset's generator uses ``bias = lower``
    for every type, which overflows a signed integer for the upper half of the range; no
    JSIDL field in the JSS or IOP sets combines a signed type with a scale range.)
    """
    raw = scaled.raw
    lower, upper = float(scaled.lower), float(scaled.upper)
    scale = (upper - lower) / ((1 << raw.bits) - 1)
    bias = (upper + lower) / 2 if raw.signed else lower
    return scale, bias


def subfield_mask(lo: int, hi: int) -> int:
    """Mask of a ``[lo, hi]`` bit range, shifted down to bit 0."""
    return (1 << (hi - lo + 1)) - 1


def optional_fields(rec: Record) -> tuple[str, ...]:
    """Names of the optional fields of ``rec`` in presence-vector bit order."""
    return tuple(f.name for f in rec.fields if f.optional)


def tag_values(variant: Variant) -> tuple[int, ...]:
    """The tag value of each alternative, in declaration order."""
    if variant.tag_values is not None:
        return tuple(variant.tag_values)
    return tuple(range(len(variant.alternatives)))


def count_of(ft: FieldType) -> Int | None:
    """The count integer of a variable-length type, or None for a fixed-length one."""
    if isinstance(ft, VarString | VarBytes | JausMessage | VarFormat | List):
        return ft.count
    return None


def raw_int(ft: FieldType) -> Int | None:
    """The wire integer behind an integer-like type (Int, Scaled, Enum, BitField)."""
    if isinstance(ft, Int):
        return ft
    if isinstance(ft, Scaled | Enum | BitField):
        return ft.raw
    return None


def fixed_size(ft: FieldType) -> int | None:
    """Encoded size in bytes if it never depends on the value, else None.

    A record with a presence vector, a list, a variant or a counted field has no fixed size.
    """
    if isinstance(ft, Int | Float):
        return ft.size
    if isinstance(ft, Scaled | Enum | BitField):
        return ft.raw.size
    if isinstance(ft, FixedString | FixedBytes):
        return ft.length
    if isinstance(ft, Record):
        if ft.pv is not None:
            return None
        total = 0
        for fld in ft.fields:
            size = fixed_size(fld.type)
            if size is None:
                return None
            total += size
        return total
    return None


def min_size(ft: FieldType) -> int:
    """Fewest bytes any encoding of ``ft`` can take (used to reject absurd list counts)."""
    size = fixed_size(ft)
    if size is not None:
        return size
    if isinstance(ft, VarFormat):
        return ft.format.raw.size + ft.count.size
    if isinstance(ft, JausMessage):
        return ft.count.size + 2
    if isinstance(ft, VarString | VarBytes | List):
        return ft.count.size
    if isinstance(ft, Record):
        pv = ft.pv.size if ft.pv is not None else 0
        return pv + sum(min_size(f.type) for f in ft.fields if not f.optional)
    if isinstance(ft, Variant):
        alts = [min_size(a.type) for a in ft.alternatives]
        return ft.tag.size + (min(alts) if alts else 0)
    raise TypeError(f"not a field type: {ft!r}")


def wire_signature(ft: FieldType) -> tuple[object, ...]:
    """What decides the wire form and the decoded keys of ``ft``, without documentation.

    Two types with equal signatures encode and decode identically: enumeration labels,
    units, JSIDL names and record names are left out.
    """
    if isinstance(ft, Int | Float):
        return (type(ft).__name__, ft.bits, getattr(ft, "signed", True))
    if isinstance(ft, Scaled):
        return ("Scaled", wire_signature(ft.raw), float(ft.lower), float(ft.upper))
    if isinstance(ft, Enum):
        return ("Enum", wire_signature(ft.raw))
    if isinstance(ft, BitField):
        subs = tuple((s.name, s.lo, s.hi) for s in ft.subfields)
        return ("BitField", wire_signature(ft.raw), subs)
    if isinstance(ft, FixedString | FixedBytes):
        return (type(ft).__name__, ft.length)
    if isinstance(ft, VarString):
        return ("VarString", wire_signature(ft.count), ft.max_length)
    if isinstance(ft, VarBytes | JausMessage):
        return (type(ft).__name__, wire_signature(ft.count))
    if isinstance(ft, VarFormat):
        return ("VarFormat", wire_signature(ft.format), wire_signature(ft.count))
    if isinstance(ft, Record):
        pv = wire_signature(ft.pv) if ft.pv is not None else None
        members = tuple((f.name, f.optional, wire_signature(f.type)) for f in ft.fields)
        return ("Record", pv, members)
    if isinstance(ft, List):
        return ("List", wire_signature(ft.count), wire_signature(ft.element))
    if isinstance(ft, Variant):
        alts = tuple((a.name, wire_signature(a.type)) for a in ft.alternatives)
        return ("Variant", wire_signature(ft.tag), tag_values(ft), alts)
    raise TypeError(f"not a field type: {ft!r}")


def children(ft: FieldType) -> Iterator[tuple[str, FieldType]]:
    """``(path segment, type)`` of the types nested directly in ``ft``."""
    if isinstance(ft, Record):
        for fld in ft.fields:
            yield fld.name, fld.type
    elif isinstance(ft, List):
        yield "[]", ft.element
    elif isinstance(ft, Variant):
        for alt in ft.alternatives:
            yield alt.name, alt.type


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_real(value: object) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
    )


def check_type(ft: FieldType, path: str = "") -> list[str]:
    """Problems that make ``ft`` impossible to encode or decode, as ``"path: problem"``.

    Checked: presence-vector width vs number of optional fields, unique field names,
    variant tag values (unique, fitting the tag), bit ranges inside their integer, scale
    ranges with ``upper > lower``, non-negative fixed lengths, Int-typed counts.
    """
    problems: list[str] = []
    where = path or "<body>"

    def bad(msg: str) -> None:
        problems.append(f"{where}: {msg}")

    if isinstance(ft, Int | Float):
        if isinstance(ft, Float) and ft.bits not in (32, 64):
            bad(f"float width {ft.bits} is not 32 or 64")
    elif isinstance(ft, Scaled):
        if not all(_is_real(x) for x in (ft.lower, ft.upper)):
            bad(f"scale range [{ft.lower!r}, {ft.upper!r}] needs finite numbers")
        elif not ft.upper > ft.lower:
            bad(f"scale range [{ft.lower}, {ft.upper}] is empty")
    elif isinstance(ft, Enum):
        pass
    elif isinstance(ft, BitField):
        if ft.raw.signed:
            bad("bit field on a signed integer")
        seen: set[str] = set()
        for sub in ft.subfields:
            if not (_is_int(sub.lo) and _is_int(sub.hi) and 0 <= sub.lo <= sub.hi < ft.raw.bits):
                bad(f"sub-field {sub.name} bits {sub.lo}-{sub.hi} outside {ft.raw.bits} bits")
            if sub.name in seen:
                bad(f"duplicate sub-field {sub.name}")
            seen.add(sub.name)
    elif isinstance(ft, FixedString | FixedBytes):
        if not _is_int(ft.length) or ft.length < 0:
            bad(f"length {ft.length!r} is not a non-negative integer")
    elif isinstance(ft, VarString | VarBytes | JausMessage | VarFormat | List):
        if not isinstance(ft.count, Int) or ft.count.signed:
            bad("count must be an unsigned Int")
        if isinstance(ft, VarFormat) and not isinstance(ft.format, Enum):
            bad("variable-format field needs an Enum format")
        if (
            isinstance(ft, VarString)
            and ft.max_length is not None
            and (not _is_int(ft.max_length) or ft.max_length < 0)
        ):
            bad(f"max_length {ft.max_length!r} is not a non-negative integer")
    elif isinstance(ft, Record):
        if not all(isinstance(f, Field) and isinstance(f.name, str) for f in ft.fields):
            bad("record members must be Fields with str names")
            return problems
        if ft.pv is not None and not isinstance(ft.pv, Int):
            bad("presence vector must be an Int")
            return problems
        names = [f.name for f in ft.fields]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            bad(f"duplicate field names {dupes}")
        n_opt = len(optional_fields(ft))
        if ft.pv is None and n_opt:
            bad(f"{n_opt} optional fields but no presence vector")
        if ft.pv is not None:
            if ft.pv.signed:
                bad("presence vector must be unsigned")
            elif n_opt > ft.pv.bits:
                bad(f"{n_opt} optional fields do not fit a {ft.pv.bits}-bit presence vector")
    elif isinstance(ft, Variant):
        if not all(isinstance(a, Field) and isinstance(a.name, str) for a in ft.alternatives):
            bad("variant alternatives must be Fields with str names")
            return problems
        values = tag_values(ft)
        if not all(_is_int(v) for v in values):
            bad(f"tag values {values!r} are not all integers")
            return problems
        if len(values) != len(ft.alternatives):
            bad("tag_values and alternatives differ in length")
        if len(set(values)) != len(values):
            bad(f"duplicate tag values {values}")
        if any(not ft.tag.min <= v <= ft.tag.max for v in values):
            bad(f"tag values {values} do not fit the tag integer")
        names = [a.name for a in ft.alternatives]
        if len(set(names)) != len(names):
            bad("duplicate alternative names")
        if any(a.optional for a in ft.alternatives):
            bad("a variant alternative cannot be optional")
    else:
        bad(f"not a field type: {type(ft).__name__}")
        return problems
    for seg, child in children(ft):
        where = f"{path}{seg}" if seg == "[]" else (f"{path}.{seg}" if path else seg)
        problems.extend(check_type(child, where))
    return problems


def check_message(defn: MessageDef) -> list[str]:
    """Problems of a message definition (see :func:`check_type`)."""
    problems = []
    if not isinstance(defn.code, int) or not 0 <= defn.code <= 0xFFFF:
        problems.append(f"message code {defn.code!r} is not a 16-bit integer")
    if not isinstance(defn.body, Record):
        problems.append("body is not a Record")
        return problems
    problems.extend(check_type(defn.body))
    return problems
