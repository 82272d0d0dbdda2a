"""Decoded message values <-> JSON-ready values, guided by the message definition. No I/O.

Decoded fields are plain Python except for bytes, which JSON cannot carry: they become
lowercase hex strings here and are turned back into bytes on the way in. Everything else
(ints, floats in the definition's units, strings, bit-field dicts) passes through.
"""

from __future__ import annotations

from typing import Any

from edge_vis.codec import types as t
from edge_vis.errors import EncodeError


def to_json(value: Any, type_: t.FieldType) -> Any:
    """Make a decoded value JSON-serialisable."""
    if isinstance(type_, (t.FixedBytes, t.VarBytes, t.JausMessage)):
        return bytes(value).hex()
    if isinstance(type_, t.VarFormat):
        return {"format": value["format"], "data": bytes(value["data"]).hex()}
    if isinstance(type_, t.Record):
        return record_to_json(value, type_)
    if isinstance(type_, t.List):
        return [to_json(item, type_.element) for item in value]
    if isinstance(type_, t.Variant):
        ((name, inner),) = value.items()
        alt = next(a for a in type_.alternatives if a.name == name)
        return {name: to_json(inner, alt.type)}
    return value


def record_to_json(fields: dict[str, Any], record: t.Record) -> dict[str, Any]:
    """Make a decoded record JSON-serialisable (absent optional fields stay absent)."""
    out: dict[str, Any] = {}
    for member in record.fields:
        if member.name in fields:
            out[member.name] = to_json(fields[member.name], member.type)
    return out


def from_json(value: Any, type_: t.FieldType, path: str = "") -> Any:
    """Turn a JSON value back into what the encoder expects (hex strings -> bytes)."""
    try:
        if isinstance(type_, (t.FixedBytes, t.VarBytes, t.JausMessage)):
            return bytes.fromhex(value) if isinstance(value, str) else bytes(value)
        if isinstance(type_, t.VarFormat):
            return {"format": value["format"], "data": from_json(value["data"], t.VarBytes())}
        if isinstance(type_, t.Record):
            return record_from_json(value, type_, path)
        if isinstance(type_, t.List):
            return [
                from_json(item, type_.element, f"{path}[{i}]") for i, item in enumerate(value)
            ]
        if isinstance(type_, t.Variant):
            ((name, inner),) = value.items()
            alt = next(a for a in type_.alternatives if a.name == name)
            return {name: from_json(inner, alt.type, f"{path}.{name}")}
    except (ValueError, TypeError, KeyError, StopIteration) as exc:
        raise EncodeError(f"bad JSON value {value!r}: {exc}", path=path) from None
    return value


def record_from_json(fields: dict[str, Any], record: t.Record, path: str = "") -> dict[str, Any]:
    """Turn a JSON object back into a record value; unknown keys are left for the encoder."""
    if not isinstance(fields, dict):
        raise EncodeError(f"expected a JSON object, got {type(fields).__name__}", path=path)
    known = {member.name: member for member in record.fields}
    out: dict[str, Any] = {}
    for key, value in fields.items():
        member = known.get(key)
        where = f"{path}.{key}" if path else key
        out[key] = from_json(value, member.type, where) if member else value
    return out
