"""Plain dicts <-> IdlStruct samples, checked field by field. No I/O.

Translators speak dicts (``{"vehicle_id": "ugv1", "latitude": 48.1, ...}``); DDS speaks
IdlStruct instances. :func:`converter_for` compiles, once per type, a pair of functions that
turn one into the other:

* dict -> struct (:meth:`Converter.to_struct`) accepts, per IDL type: ``str`` for strings;
  ``bool`` for booleans; ``int`` (not ``bool``) within the type's range for integers;
  ``int`` or ``float`` for floating point; for enums the literal name (with or without
  the enum's common prefix, any case), the enum member or its integer value; ``bytes``,
  ``bytearray``, ``memoryview`` or a list of ints for ``sequence<uint8>``; a list or tuple
  for other sequences and arrays; a dict (or an instance) for nested structs; ``None``
  for an absent ``@optional`` member. Missing members take the type's default; a member without a
  default must be present. Unknown keys are errors (a typo must not vanish silently).
* struct -> dict (:meth:`Converter.to_dict`) gives enums as literal names, sequences as
  lists, nested structs as dicts, ``sequence<uint8>`` as ``bytes``, and leaves out absent
  ``@optional`` members (the codec's convention for absent optional fields).

Every failure is an :class:`~edge_vis.errors.EncodeError` whose message names the topic and
whose ``path`` is the member path (``waypoints[2].latitude``).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import typing
from collections.abc import Callable, Mapping
from typing import Any

from cyclonedds.idl import IdlEnum, IdlStruct
from cyclonedds.idl import types as idl_types

from edge_vis.errors import EncodeError

_INT_RANGES: dict[str, tuple[int, int]] = {
    "int8": (-(1 << 7), (1 << 7) - 1),
    "int16": (-(1 << 15), (1 << 15) - 1),
    "int32": (-(1 << 31), (1 << 31) - 1),
    "int64": (-(1 << 63), (1 << 63) - 1),
    "uint8": (0, (1 << 8) - 1),
    "byte": (0, (1 << 8) - 1),
    "uint16": (0, (1 << 16) - 1),
    "uint32": (0, (1 << 32) - 1),
    "uint64": (0, (1 << 64) - 1),
}
# types.byte is in the 11.x binding only (edge_vis.dds.binding)
_OCTETS = (idl_types.uint8, getattr(idl_types, "byte", idl_types.uint8))
_MISSING = object()


class _Bad(Exception):
    """A conversion failure on its way up; each level prepends its member name."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason
        self.path: list[str] = []


def _describe(value: object) -> str:
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{type(value).__name__} {text}"


def _join(parts: list[str]) -> str:
    out = ""
    for part in parts:
        out += part if part.startswith("[") or not out else "." + part
    return out


ToStruct = Callable[[Any], Any]
ToPlain = Callable[[Any], Any]


# --------------------------------------------------------------------------- leaf converters


def _str_in(value: Any) -> str:
    if type(value) is str:
        if "\x00" in value:
            raise _Bad("a string cannot contain NUL characters")
        return value
    raise _Bad(f"expected a string, got {_describe(value)}")


def _bounded_str_in(bound: int) -> ToStruct:
    def convert(value: Any) -> str:
        text = _str_in(value)
        if len(text.encode("utf-8")) > bound:
            raise _Bad(f"string longer than its bound of {bound} bytes")
        return text

    return convert


def _bool_in(value: Any) -> bool:
    if type(value) is bool:
        return value
    raise _Bad(f"expected true or false, got {_describe(value)}")


def _float_in(value: Any) -> float:
    kind = type(value)
    if kind is float:
        return value  # type: ignore[no-any-return]
    if kind is int:
        return float(value)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    raise _Bad(f"expected a number, got {_describe(value)}")


def _float32_in(value: Any) -> float:
    number = _float_in(value)
    if math.isfinite(number) and abs(number) > 3.4028234663852886e38:
        raise _Bad(f"{number} does not fit a 32-bit float")
    return number


def _int_in(low: int, high: int, name: str) -> ToStruct:
    def convert(value: Any) -> int:
        if type(value) is not int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise _Bad(f"expected an integer ({name}), got {_describe(value)}")
            value = int(value)
        if value < low or value > high:
            raise _Bad(f"{value} is outside the {name} range {low}..{high}")
        return value  # type: ignore[no-any-return]

    return convert


def _octets_in(max_length: int | None) -> ToStruct:
    as_list = _sequence_in(_int_in(0, 255, "uint8"), max_length)

    def convert(value: Any) -> Any:
        # bytes serialise as they are (cyclonedds packs them element-wise), no list needed
        if type(value) is bytes:
            octets = value
        elif isinstance(value, (bytearray, memoryview)):
            octets = bytes(value)
        else:
            return as_list(value)
        if max_length is not None and len(octets) > max_length:
            raise _Bad(f"{len(octets)} bytes exceed the bound of {max_length}")
        return octets

    return convert


def _enum_in(cls: type[IdlEnum]) -> ToStruct:
    members = list(cls)  # type: ignore[var-annotated]
    by_name: dict[str, Any] = {}
    for member in members:
        by_name[member.name.upper()] = member
    prefix = _common_prefix([m.name for m in members])
    if prefix:
        for member in members:
            by_name.setdefault(member.name[len(prefix):].upper(), member)
    by_value = {member.value: member for member in members}
    choices = ", ".join(m.name for m in members)

    def convert(value: Any) -> Any:
        if isinstance(value, cls):
            return value
        if type(value) is str:
            member = by_name.get(value.upper())
            if member is not None:
                return member
        elif type(value) is int and value in by_value:
            return by_value[value]
        raise _Bad(f"expected one of {choices}, got {_describe(value)}")

    return convert


def _common_prefix(names: list[str]) -> str:
    """The shared ``WORD_`` prefix of all enumerator names, or ''."""
    if len(names) < 2:
        return ""
    first = names[0]
    cut = first.find("_")
    if cut <= 0:
        return ""
    prefix = first[: cut + 1]
    return prefix if all(n.startswith(prefix) and len(n) > len(prefix) for n in names) else ""


def _optional_in(inner: ToStruct) -> ToStruct:
    def convert(value: Any) -> Any:
        return None if value is None else inner(value)

    return convert


def _sequence_in(inner: ToStruct, max_length: int | None, exact: int | None = None) -> ToStruct:
    def convert(value: Any) -> list[Any]:
        if not isinstance(value, (list, tuple)):
            raise _Bad(f"expected a list, got {_describe(value)}")
        if max_length is not None and len(value) > max_length:
            raise _Bad(f"{len(value)} elements exceed the bound of {max_length}")
        if exact is not None and len(value) != exact:
            raise _Bad(f"expected exactly {exact} elements, got {len(value)}")
        out = []
        for index, item in enumerate(value):
            try:
                out.append(inner(item))
            except _Bad as exc:
                exc.path.insert(0, f"[{index}]")
                raise
        return out

    return convert


# --------------------------------------------------------------------------- struct -> plain


def _enum_out(value: Any) -> str:
    return value.name  # type: ignore[no-any-return]


def _list_out(inner: ToPlain | None) -> ToPlain:
    if inner is None:
        return list
    return lambda value: [inner(item) for item in value]


def _optional_out(inner: ToPlain | None) -> ToPlain | None:
    if inner is None:
        return None
    return lambda value: None if value is None else inner(value)


# --------------------------------------------------------------------------- compiler


def _compile_type(annotation: Any) -> tuple[ToStruct, ToPlain | None]:
    """(dict-side -> struct-side converter, struct-side -> plain converter or None = as is)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        base, *extras = typing.get_args(annotation)
        meta = extras[0]
        if isinstance(meta, str):
            if meta in _INT_RANGES:
                low, high = _INT_RANGES[meta]
                return _int_in(low, high, meta), None
            if meta == "float32":
                return _float32_in, None
            if meta == "float64":
                return _float_in, None
            if meta == "char":
                return _bounded_str_in(1), None
        if isinstance(meta, idl_types.typedef):
            return _compile_type(meta.subtype)
        if isinstance(meta, idl_types.bounded_str):
            return _bounded_str_in(meta.max_length), None
        if isinstance(meta, idl_types.sequence) and meta.subtype in _OCTETS:
            return _octets_in(meta.max_length), bytes
        if isinstance(meta, (idl_types.sequence, idl_types.array)):
            inner_in, inner_out = _compile_type(meta.subtype)
            if isinstance(meta, idl_types.array):
                return _sequence_in(inner_in, None, exact=meta.length), _list_out(inner_out)
            return _sequence_in(inner_in, meta.max_length), _list_out(inner_out)
        return _compile_type(base)
    if origin is typing.Union:
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            inner_in, inner_out = _compile_type(args[0])
            return _optional_in(inner_in), _optional_out(inner_out)
    if annotation is str:
        return _str_in, None
    if annotation is bool:
        return _bool_in, None
    if annotation is float:
        return _float_in, None
    if annotation is int:
        low, high = _INT_RANGES["int64"]
        return _int_in(low, high, "int64"), None
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return _enum_in(annotation), _enum_out  # type: ignore[arg-type]
    if isinstance(annotation, type) and issubclass(annotation, IdlStruct):
        nested = converter_for(annotation)
        return nested.struct_in, nested.to_dict
    raise TypeError(f"member type {annotation!r} is not supported by the dict converter")


class Converter:
    """Compiled dict <-> struct conversion for one IdlStruct type."""

    def __init__(self, cls: type[IdlStruct]) -> None:
        self.cls = cls
        hints = typing.get_type_hints(cls, include_extras=True)
        self.fields: list[tuple[str, ToStruct, ToPlain | None, Any, Any]] = []
        for member in dataclasses.fields(cls):  # type: ignore[arg-type]
            to_struct, to_plain = _compile_type(hints[member.name])
            self.fields.append(
                (member.name, to_struct, to_plain, member.default, member.default_factory)
            )
        self.names = frozenset(name for name, *_ in self.fields)
        self.optional = frozenset(
            name for name in self.names if typing.get_origin(hints[name]) is typing.Union
        )

    def struct_in(self, value: Any) -> Any:
        """Convert a dict (or pass an instance through); raises ``_Bad`` with a path."""
        if isinstance(value, self.cls):
            return value
        if not isinstance(value, Mapping):
            raise _Bad(f"expected a dict for {self.cls.__name__}, got {_describe(value)}")
        kwargs = {}
        used = 0
        for name, to_struct, _, default, factory in self.fields:
            item = value.get(name, _MISSING)
            if item is _MISSING:
                if default is not dataclasses.MISSING:
                    kwargs[name] = default
                elif factory is not dataclasses.MISSING:
                    kwargs[name] = factory()
                else:
                    exc = _Bad("required member is missing")
                    exc.path.append(name)
                    raise exc
                continue
            used += 1
            try:
                kwargs[name] = to_struct(item)
            except _Bad as exc:
                exc.path.insert(0, name)
                raise
        if used != len(value):
            unknown = sorted(str(k) for k in value if k not in self.names)
            exc = _Bad(
                f"unknown member(s) {', '.join(unknown)} for {self.cls.__name__}; "
                f"members are {', '.join(name for name, *_ in self.fields)}"
            )
            raise exc
        return self.cls(**kwargs)

    def to_struct(self, value: Mapping[str, Any], topic: str = "") -> Any:
        """The IdlStruct for ``value``; :class:`EncodeError` naming topic and member if bad."""
        try:
            return self.struct_in(value)
        except _Bad as exc:
            where = topic or self.cls.__name__
            error = EncodeError(f"cannot publish on {where!r}: {exc.reason}", path=_join(exc.path))
            error.topic = where  # type: ignore[attr-defined]
            raise error from None

    def to_dict(self, sample: Any) -> dict[str, Any]:
        """A plain dict of ``sample`` (enums as names, nested structs as dicts); an absent
        ``@optional`` member is a missing key, as in decoded JAUS messages."""
        out = {}
        optional = self.optional
        for name, _, to_plain, _, _ in self.fields:
            value = getattr(sample, name)
            if value is None and name in optional:
                continue
            out[name] = value if to_plain is None else to_plain(value)
        return out

    def key_of(self, key: Any, topic: str = "") -> Any:
        """A struct carrying only the key members (for dispose/unregister).

        ``key`` is a dict of the key members or, for single-key types, the key value itself.
        Non-key members take their defaults, or a zero value if they have none.
        """
        keys = key_members(self.cls)
        if not isinstance(key, Mapping):
            if len(keys) != 1:
                raise EncodeError(
                    f"topic {topic or self.cls.__name__!r} has keys {', '.join(keys)}; "
                    "give them as a dict"
                )
            key = {keys[0]: key}
        missing = [k for k in keys if k not in key]
        if missing:
            raise EncodeError(
                f"cannot address an instance of {topic or self.cls.__name__!r}: "
                f"key member(s) {', '.join(missing)} missing"
            )
        filled = {name: _zero(self.cls, name) for name, *_ in self.fields}
        filled.update({k: v for k, v in key.items() if k in keys})
        return self.to_struct(filled, topic)


def _zero(cls: type[IdlStruct], name: str) -> Any:
    member = {m.name: m for m in dataclasses.fields(cls)}[name]  # type: ignore[arg-type]
    if member.default is not dataclasses.MISSING:
        return member.default
    if member.default_factory is not dataclasses.MISSING:
        return member.default_factory()
    return _zero_for(typing.get_type_hints(cls, include_extras=True)[name])


def _zero_for(annotation: Any) -> Any:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        base, meta = typing.get_args(annotation)[:2]
        if isinstance(meta, (idl_types.sequence,)):
            return []
        if isinstance(meta, idl_types.array):
            return [_zero_for(meta.subtype)] * meta.length
        return _zero_for(base)
    if origin is typing.Union:
        return None
    if isinstance(annotation, type):
        if issubclass(annotation, enum.Enum):
            return next(iter(annotation))
        if issubclass(annotation, IdlStruct):
            return {m.name: _zero(annotation, m.name) for m in dataclasses.fields(annotation)}  # type: ignore[arg-type]
        if annotation in (str, bool, float, int, bytes):
            return annotation()
    if annotation is typing.Sequence or origin is not None:
        return []
    raise TypeError(f"no zero value for {annotation!r}")


@functools.cache
def key_members(cls: type[IdlStruct]) -> tuple[str, ...]:
    """Names of the ``key(...)`` members of ``cls``, in declaration order."""
    annotations = getattr(cls, "__idl_annotations__", {})
    keys = set(annotations.get("keylist", ())) if isinstance(annotations, dict) else set()
    field_annotations = getattr(cls, "__idl_field_annotations__", {})
    for name, notes in field_annotations.items():
        if isinstance(notes, dict) and notes.get("key"):
            keys.add(name)
    return tuple(m.name for m in dataclasses.fields(cls) if m.name in keys)  # type: ignore[arg-type]


@functools.cache
def converter_for(cls: type[IdlStruct]) -> Converter:
    """The (cached) compiled converter of ``cls``."""
    return Converter(cls)
