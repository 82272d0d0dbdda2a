"""The reference codec: a plain recursive walk over a type tree. No I/O.

It is the definition of what the compiled fast path in :mod:`edge_vis.codec.compiler` must
do, and the place errors are diagnosed: when a compiled decoder or encoder trips over its
input, the engine runs the same input through this walker, which knows the field path and
byte offset of every step and raises a :class:`~edge_vis.errors.DecodeError` or
:class:`~edge_vis.errors.EncodeError` naming them. It is slow, and only used for that (and
by the tests, as an oracle for the compiled code).

Decoding rules beyond the DSL table (:mod:`edge_vis.codec.types`):

* a presence-vector bit above the record's optional fields is a ``DecodeError``: the field it
  announces is unknown, so its size (and everything after it) is unknown too;
* a list count that cannot fit in the remaining bytes (each element takes at least one byte,
  or its minimum size) is a ``DecodeError`` before any element is read;
* an embedded JAUS message shorter than its 2-byte code is a ``DecodeError``;
* a variant tag that selects no alternative is a ``DecodeError``;
* any integer decodes: enumerations keep unknown values, scaled integers decode even when
  the result lies outside ``[lower, upper]``, bit fields ignore bits no sub-field covers.

Encoding rules: absent optional fields are missing keys (``None`` is not "absent"); unknown
keys are an ``EncodeError``; a scaled real is ``round((real - bias) / scale)`` and an error
only if that integer does not fit and the real lies outside ``[lower, upper]`` (a real inside
the range is clamped to the nearest integer, which matters for the upper end of signed
ranges); missing bit-field sub-fields encode as 0; a variable-length string may not exceed
``max_length``, which decoding does not enforce.
"""

from __future__ import annotations

import math
import numbers
import operator
import struct
from collections.abc import Mapping
from typing import Any

from edge_vis.codec.layout import (
    min_size,
    optional_fields,
    scaling,
    subfield_mask,
    tag_values,
)
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
from edge_vis.errors import DecodeError, EncodeError

BYTES_TYPES = (bytes, bytearray, memoryview)


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _type_label(ft: Int | Float) -> str:
    if isinstance(ft, Float):
        return f"f{ft.bits}"
    return f"{'i' if ft.signed else 'u'}{ft.bits}"


# -- decoding ------------------------------------------------------------------------------


def _need(buf: bytes, pos: int, size: int, path: str, what: str) -> None:
    if pos + size > len(buf):
        raise DecodeError(
            f"{what} needs {size} bytes, {max(len(buf) - pos, 0)} left", path=path, offset=pos
        )


def _read_int(buf: bytes, pos: int, ft: Int, path: str, what: str = "") -> int:
    _need(buf, pos, ft.size, path, what or _type_label(ft))
    return int.from_bytes(buf[pos : pos + ft.size], "little", signed=ft.signed)


def decode_type(ft: FieldType, buf: bytes, pos: int, path: str = "") -> tuple[Any, int]:
    """Decode one value of ``ft`` at ``pos``; ``(value, next_pos)``; DecodeError with path."""
    if isinstance(ft, Int):
        return _read_int(buf, pos, ft, path), pos + ft.size
    if isinstance(ft, Float):
        _need(buf, pos, ft.size, path, _type_label(ft))
        return struct.unpack_from("<" + ft.struct_code, buf, pos)[0], pos + ft.size
    if isinstance(ft, Scaled):
        scale, bias = scaling(ft)
        raw = _read_int(buf, pos, ft.raw, path)
        return raw * scale + bias, pos + ft.raw.size
    if isinstance(ft, Enum):
        return _read_int(buf, pos, ft.raw, path), pos + ft.raw.size
    if isinstance(ft, BitField):
        raw = _read_int(buf, pos, ft.raw, path, "bit field")
        value = {s.name: (raw >> s.lo) & subfield_mask(s.lo, s.hi) for s in ft.subfields}
        return value, pos + ft.raw.size
    if isinstance(ft, FixedString):
        _need(buf, pos, ft.length, path, f"fixed string of {ft.length}")
        data = bytes(buf[pos : pos + ft.length])
        return data.rstrip(b"\x00").decode("latin-1"), pos + ft.length
    if isinstance(ft, FixedBytes):
        _need(buf, pos, ft.length, path, f"fixed field of {ft.length}")
        return bytes(buf[pos : pos + ft.length]), pos + ft.length
    if isinstance(ft, VarString | VarBytes | JausMessage):
        n = _read_int(buf, pos, ft.count, path, "count")
        pos += ft.count.size
        if isinstance(ft, JausMessage) and n < 2:
            raise DecodeError(
                f"embedded message of {n} bytes has no message code", path=path, offset=pos
            )
        _need(buf, pos, n, path, "counted data")
        data = bytes(buf[pos : pos + n])
        counted: Any = data.decode("latin-1") if isinstance(ft, VarString) else data
        return counted, pos + n
    if isinstance(ft, VarFormat):
        fmt = _read_int(buf, pos, ft.format.raw, path, "format")
        pos += ft.format.raw.size
        n = _read_int(buf, pos, ft.count, path, "count")
        pos += ft.count.size
        _need(buf, pos, n, path, "counted data")
        return {"format": fmt, "data": bytes(buf[pos : pos + n])}, pos + n
    if isinstance(ft, Record):
        return _decode_record(ft, buf, pos, path)
    if isinstance(ft, List):
        n = _read_int(buf, pos, ft.count, path, "list count")
        pos += ft.count.size
        each = max(min_size(ft.element), 1)
        if n * each > len(buf) - pos:
            raise DecodeError(
                f"list count {n} needs at least {n * each} bytes, {len(buf) - pos} left",
                path=path,
                offset=pos - ft.count.size,
            )
        items = []
        for i in range(n):
            item, pos = decode_type(ft.element, buf, pos, f"{path}[{i}]")
            items.append(item)
        return items, pos
    if isinstance(ft, Variant):
        tag = _read_int(buf, pos, ft.tag, path, "variant tag")
        values = tag_values(ft)
        if tag not in values:
            raise DecodeError(
                f"variant tag {tag} selects no alternative (known: {list(values)})",
                path=path,
                offset=pos,
            )
        alt = ft.alternatives[values.index(tag)]
        value, pos = decode_type(alt.type, buf, pos + ft.tag.size, _join(path, alt.name))
        return {alt.name: value}, pos
    raise TypeError(f"not a field type: {ft!r}")


def _decode_record(rec: Record, buf: bytes, pos: int, path: str) -> tuple[dict[str, Any], int]:
    present = -1
    if rec.pv is not None:
        present = _read_int(buf, pos, rec.pv, path, "presence vector")
        n_opt = len(optional_fields(rec))
        if present >> n_opt:
            raise DecodeError(
                f"presence vector 0x{present:X} sets bits above the {n_opt} optional fields",
                path=path,
                offset=pos,
            )
        pos += rec.pv.size
    out: dict[str, Any] = {}
    bit = 0
    for fld in rec.fields:
        if fld.optional:
            here = present >> bit & 1
            bit += 1
            if not here:
                continue
        out[fld.name], pos = decode_type(fld.type, buf, pos, _join(path, fld.name))
    return out, pos


def decode_body(defn: MessageDef, body: bytes) -> dict[str, Any]:
    """Decode a whole body; trailing bytes are an error. DecodeError carries the code."""
    buf = bytes(body)
    try:
        value, pos = _decode_record(defn.body, buf, 0, "")
    except DecodeError as exc:
        raise DecodeError(exc.reason, code=defn.code, path=exc.path, offset=exc.offset) from None
    if pos != len(buf):
        raise DecodeError(
            f"{len(buf) - pos} bytes left over after the body", code=defn.code, offset=pos
        )
    return value


# -- encoding ------------------------------------------------------------------------------


def _as_int(value: Any, path: str) -> int:
    if isinstance(value, float):
        raise EncodeError(f"expected an integer, got float {value!r}", path=path)
    try:
        return operator.index(value)
    except TypeError:
        raise EncodeError(
            f"expected an integer, got {type(value).__name__}", path=path
        ) from None


def _pack_int(ft: Int, value: int, path: str, what: str = "value") -> bytes:
    if not ft.min <= value <= ft.max:
        raise EncodeError(
            f"{what} {value} outside {_type_label(ft)} range {ft.min}..{ft.max}", path=path
        )
    return value.to_bytes(ft.size, "little", signed=ft.signed)


def _as_bytes(value: Any, path: str) -> bytes:
    if not isinstance(value, BYTES_TYPES):
        raise EncodeError(f"expected bytes, got {type(value).__name__}", path=path)
    return bytes(value)


def _as_text(value: Any, path: str) -> bytes:
    if not isinstance(value, str):
        raise EncodeError(f"expected a str, got {type(value).__name__}", path=path)
    try:
        return value.encode("latin-1")
    except UnicodeEncodeError as exc:
        raise EncodeError(
            f"character {value[exc.start]!r} is not latin-1", path=path
        ) from None


def _as_mapping(value: Any, path: str, what: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise EncodeError(f"expected a dict for {what}, got {type(value).__name__}", path=path)
    return value


def encode_type(ft: FieldType, value: Any, out: bytearray, path: str = "") -> None:
    """Append the encoding of ``value`` as ``ft`` to ``out``; EncodeError with path."""
    if isinstance(ft, Int | Enum):
        raw = ft if isinstance(ft, Int) else ft.raw
        out += _pack_int(raw, _as_int(value, path), path)
    elif isinstance(ft, Float):
        try:
            out += struct.pack("<" + ft.struct_code, value)
        except (OverflowError, struct.error, TypeError):
            if not isinstance(value, numbers.Real):
                raise EncodeError(
                    f"expected a number, got {type(value).__name__}", path=path
                ) from None
            raise EncodeError(f"{value!r} does not fit an f{ft.bits}", path=path) from None
    elif isinstance(ft, Scaled):
        out += _pack_int(ft.raw, scaled_raw(ft, value, path), path, "scaled integer")
    elif isinstance(ft, BitField):
        out += _pack_int(ft.raw, _bitfield_raw(ft, value, path), path)
    elif isinstance(ft, FixedString):
        data = _as_text(value, path)
        if len(data) > ft.length:
            raise EncodeError(f"text of {len(data)} bytes exceeds {ft.length}", path=path)
        out += data.ljust(ft.length, b"\x00")
    elif isinstance(ft, FixedBytes):
        data = _as_bytes(value, path)
        if len(data) != ft.length:
            raise EncodeError(f"expected exactly {ft.length} bytes, got {len(data)}", path=path)
        out += data
    elif isinstance(ft, VarString | VarBytes | JausMessage):
        if isinstance(ft, VarString):
            data = _as_text(value, path)
            if ft.max_length is not None and len(data) > ft.max_length:
                raise EncodeError(
                    f"text of {len(data)} bytes exceeds the maximum {ft.max_length}", path=path
                )
        else:
            data = _as_bytes(value, path)
            if isinstance(ft, JausMessage) and len(data) < 2:
                raise EncodeError(
                    "an embedded message needs at least its 2-byte code", path=path
                )
        out += _pack_int(ft.count, len(data), path, "length")
        out += data
    elif isinstance(ft, VarFormat):
        mapping = _as_mapping(value, path, "a variable-format field")
        extra = sorted(set(mapping) - {"format", "data"})
        if extra:
            raise EncodeError(f"unknown keys {extra} (expected format, data)", path=path)
        if "format" not in mapping or "data" not in mapping:
            raise EncodeError("needs both 'format' and 'data'", path=path)
        fmt = _as_int(mapping["format"], _join(path, "format"))
        data = _as_bytes(mapping["data"], _join(path, "data"))
        out += _pack_int(ft.format.raw, fmt, _join(path, "format"))
        out += _pack_int(ft.count, len(data), _join(path, "data"), "length")
        out += data
    elif isinstance(ft, Record):
        _encode_record(ft, value, out, path)
    elif isinstance(ft, List):
        if not isinstance(value, list | tuple):
            raise EncodeError(f"expected a list, got {type(value).__name__}", path=path)
        out += _pack_int(ft.count, len(value), path, "list length")
        for i, item in enumerate(value):
            encode_type(ft.element, item, out, f"{path}[{i}]")
    elif isinstance(ft, Variant):
        mapping = _as_mapping(value, path, "a variant")
        names = [a.name for a in ft.alternatives]
        if len(mapping) != 1:
            raise EncodeError(
                f"a variant takes exactly one of {names}, got {sorted(mapping)}", path=path
            )
        ((name, inner),) = mapping.items()
        if name not in names:
            raise EncodeError(f"unknown alternative {name!r} (known: {names})", path=path)
        index = names.index(name)
        out += _pack_int(ft.tag, tag_values(ft)[index], path, "variant tag")
        encode_type(ft.alternatives[index].type, inner, out, _join(path, name))
    else:
        raise TypeError(f"not a field type: {ft!r}")


def scaled_raw(ft: Scaled, value: Any, path: str = "") -> int:
    """The wire integer for a real ``value`` (see the module docstring for the range rule)."""
    if not isinstance(value, numbers.Real):
        raise EncodeError(f"expected a number, got {type(value).__name__}", path=path)
    if not math.isfinite(value):
        raise EncodeError(f"{value!r} is not a finite number", path=path)
    number = float(value)
    scale, bias = scaling(ft)
    raw = round((number - bias) / scale)
    if raw < ft.raw.min or raw > ft.raw.max:
        if not ft.lower <= number <= ft.upper:
            raise EncodeError(
                f"{value!r} outside the scaled range [{ft.lower}, {ft.upper}]", path=path
            )
        raw = min(max(raw, ft.raw.min), ft.raw.max)
    return raw


def _bitfield_raw(ft: BitField, value: Any, path: str) -> int:
    mapping = _as_mapping(value, path, "a bit field")
    known = {s.name for s in ft.subfields}
    extra = sorted(set(mapping) - known)
    if extra:
        raise EncodeError(f"unknown sub-fields {extra}", path=path)
    raw = 0
    for sub in ft.subfields:
        sub_path = _join(path, sub.name)
        part = _as_int(mapping.get(sub.name, 0), sub_path)
        mask = subfield_mask(sub.lo, sub.hi)
        if not 0 <= part <= mask:
            raise EncodeError(
                f"{part} does not fit bits {sub.lo}-{sub.hi} (0..{mask})", path=sub_path
            )
        raw |= part << sub.lo
    return raw


def _encode_record(rec: Record, value: Any, out: bytearray, path: str) -> None:
    mapping = _as_mapping(value, path, "a record")
    known = {f.name for f in rec.fields}
    extra = sorted(str(k) for k in mapping if k not in known)
    if extra:
        raise EncodeError(f"unknown fields {extra}", path=path)
    missing = [f.name for f in rec.fields if not f.optional and f.name not in mapping]
    if missing:
        raise EncodeError(f"missing mandatory fields {missing}", path=path)
    if rec.pv is not None:
        present = 0
        for bit, name in enumerate(optional_fields(rec)):
            if name in mapping:
                present |= 1 << bit
        out += _pack_int(rec.pv, present, path, "presence vector")
    for fld in rec.fields:
        if fld.name in mapping:
            encode_type(fld.type, mapping[fld.name], out, _join(path, fld.name))


def encode_body(defn: MessageDef, fields: Any) -> bytes:
    """Encode a whole body; EncodeError carries the code and field path."""
    out = bytearray()
    try:
        _encode_record(defn.body, fields, out, "")
    except EncodeError as exc:
        raise EncodeError(exc.reason, code=defn.code, path=exc.path) from None
    return bytes(out)
