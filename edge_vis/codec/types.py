"""Declarative field types for JAUS messages. No I/O.

A message is *data*: a tree of the frozen values below, mirroring the JSIDL constructs
(AS5684). The engine in :mod:`edge_vis.codec.bodies` compiles each tree once into fast
encoders and decoders. Decoded values are plain Python:

============================  ================================================
type                          decoded value
============================  ================================================
:class:`Int`                  ``int``
:class:`Float`                ``float``
:class:`Scaled`               ``float`` in the definition's units
:class:`Enum`                 ``int`` (labels are for display only)
:class:`BitField`             ``dict`` sub-field name -> ``int``
:class:`FixedString`          ``str`` (trailing NULs removed; latin-1)
:class:`VarString`            ``str`` (latin-1)
:class:`FixedBytes`           ``bytes``
:class:`VarBytes`             ``bytes``
:class:`JausMessage`          ``bytes`` (a complete message: 2-byte code + body)
:class:`VarFormat`            ``{"format": int, "data": bytes}``
:class:`Record`               ``dict`` field name -> value; absent optional fields are
                              missing keys, and the presence vector is derived, never stored
:class:`List`                 ``list``
:class:`Variant`              one-key ``dict``: alternative name -> value
============================  ================================================

Field names are the JSIDL names in snake_case (``Position_RMS`` -> ``position_rms``), see
:func:`snake_case`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Union


@dataclass(frozen=True, slots=True)
class Int:
    """A fixed-width little-endian integer of 8, 16, 32 or 64 bits."""

    bits: int
    signed: bool = False
    units: str = ""

    def __post_init__(self) -> None:
        if self.bits not in (8, 16, 32, 64):
            raise ValueError(f"integer width {self.bits} is not 8, 16, 32 or 64")

    @property
    def size(self) -> int:
        """Encoded size in bytes."""
        return self.bits // 8

    @property
    def min(self) -> int:
        """Smallest value."""
        return -(1 << (self.bits - 1)) if self.signed else 0

    @property
    def max(self) -> int:
        """Largest value."""
        return (1 << (self.bits - 1)) - 1 if self.signed else (1 << self.bits) - 1

    @property
    def struct_code(self) -> str:
        """The :mod:`struct` format character."""
        code = {8: "b", 16: "h", 32: "i", 64: "q"}[self.bits]
        return code if self.signed else code.upper()


u8, u16, u32, u64 = Int(8), Int(16), Int(32), Int(64)
i8, i16, i32, i64 = Int(8, True), Int(16, True), Int(32, True), Int(64, True)


@dataclass(frozen=True, slots=True)
class Float:
    """An IEEE 754 float of 32 or 64 bits."""

    bits: int
    units: str = ""

    @property
    def size(self) -> int:
        """Encoded size in bytes."""
        return self.bits // 8

    @property
    def struct_code(self) -> str:
        """The :mod:`struct` format character."""
        return "f" if self.bits == 32 else "d"


f32, f64 = Float(32), Float(64)


@dataclass(frozen=True, slots=True)
class Scaled:
    """A real number carried as an integer over ``[lower, upper]`` (the JAUS scaling rule).

    ``scale = (upper - lower) / (2**bits - 1)``; on the wire
    ``integer = round((real - bias) / scale)`` and ``real = integer * scale + bias``, where
    ``bias`` is ``lower`` for unsigned integers and ``(upper + lower) / 2`` for signed ones.
    """

    raw: Int
    lower: float
    upper: float
    units: str = ""


@dataclass(frozen=True, slots=True)
class Enum:
    """An integer whose values carry names (JSIDL ``value_set``)."""

    raw: Int
    labels: Mapping[int, str] = field(default_factory=dict)
    #: ``(lo, hi, label)`` ranges from the value set, for display
    ranges: tuple[tuple[int, int, str], ...] = ()
    units: str = ""


@dataclass(frozen=True, slots=True)
class SubField:
    """A named bit range ``[lo, hi]`` (inclusive, bit 0 = LSB) of a :class:`BitField`."""

    name: str
    lo: int
    hi: int
    labels: Mapping[int, str] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class BitField:
    """One unsigned integer split into named sub-fields."""

    raw: Int
    subfields: tuple[SubField, ...]


@dataclass(frozen=True, slots=True)
class FixedString:
    """Exactly ``length`` bytes of text, NUL-padded."""

    length: int


@dataclass(frozen=True, slots=True)
class VarString:
    """A count (of ``count`` width) followed by that many bytes of text."""

    count: Int = u8
    max_length: int | None = None


@dataclass(frozen=True, slots=True)
class FixedBytes:
    """Exactly ``length`` opaque bytes."""

    length: int


@dataclass(frozen=True, slots=True)
class VarBytes:
    """A count followed by that many opaque bytes (JSIDL ``variable_length_field``)."""

    count: Int = u32
    #: the JSIDL ``field_format`` (e.g. ``"JPEG"``), informational
    format: str = ""


@dataclass(frozen=True, slots=True)
class JausMessage:
    """A count followed by a complete JAUS message (2-byte code + body), as in Events."""

    count: Int = u32


@dataclass(frozen=True, slots=True)
class VarFormat:
    """A format enumeration, a count, then that many bytes (``variable_format_field``)."""

    format: Enum
    count: Int = u32


@dataclass(frozen=True, slots=True)
class Field:
    """A named member of a :class:`Record` or an alternative of a :class:`Variant`."""

    name: str
    type: FieldType
    optional: bool = False
    #: the JSIDL name, kept for verification and documentation
    jsidl_name: str = ""


@dataclass(frozen=True, slots=True)
class Record:
    """An ordered group of fields; ``pv`` is the presence-vector width (8/16/32) or None.

    Bit *i* of the presence vector is the *i*-th optional field in declaration order.
    Both JSIDL ``record`` and ``sequence`` map to a Record (a sequence is a record whose
    fields are records, lists or variants).
    """

    fields: tuple[Field, ...]
    pv: Int | None = None
    name: str = ""
    #: a message body that was one JSIDL record: that record's name, so a path qualified by
    #: it can be told from a misspelt one (not part of the wire layout, so not compared)
    flattened: str = field(default="", compare=False)


@dataclass(frozen=True, slots=True)
class List:
    """A count of ``count`` width followed by that many elements."""

    count: Int
    element: FieldType
    name: str = ""


@dataclass(frozen=True, slots=True)
class Variant:
    """A tag then the alternative it selects; tag value ``i`` selects ``alternatives[i]``.

    ``tag_values`` overrides the tag value per alternative when the JSIDL gives explicit
    values.
    """

    tag: Int
    alternatives: tuple[Field, ...]
    tag_values: tuple[int, ...] | None = None
    name: str = ""


FieldType = Union[  # noqa: UP007 - a runtime alias used in isinstance-free dispatch
    Int, Float, Scaled, Enum, BitField, FixedString, VarString, FixedBytes, VarBytes,
    JausMessage, VarFormat, Record, List, Variant,
]


@dataclass(frozen=True, slots=True)
class MessageDef:
    """A JAUS message definition.

    ``body`` is the record that follows the 2-byte message code. ``services`` are the
    ``(uri, version)`` pairs of the services that declare this message.
    """

    code: int
    name: str
    body: Record
    service_set: str
    services: tuple[tuple[str, str], ...] = ()
    doc: str = ""


@dataclass(frozen=True, slots=True)
class Dialect:
    """Another published definition of messages whose codes the base catalogue already
    defines: manipulator v1.0 beside v2.0, the IOP readings of some SAE messages.

    ``messages`` replace the base definitions of their codes for a vehicle that speaks the
    dialect (same code, the dialect's own name and layout); ``aliases`` are further names
    the dialect's readings give to a code (``ReportJointPosition`` for 0x4602).
    ``recognise`` lists ``(URI prefix, version prefix)`` pairs: a vehicle reporting a
    service that matches one of them speaks the dialect. Definitions from several message
    sets that share a dialect name are one dialect.
    """

    name: str
    messages: tuple[MessageDef, ...] = ()
    aliases: tuple[tuple[str, int], ...] = ()
    recognise: tuple[tuple[str, str], ...] = ()
    doc: str = ""


_CAMEL_1 = re.compile(r"(.)([A-Z][a-z]+)")
_CAMEL_2 = re.compile(r"([a-z0-9])([A-Z])")


def snake_case(name: str) -> str:
    """JSIDL name -> Python field name: ``Position_RMS`` -> ``position_rms``.

    ``TimeStamp`` -> ``time_stamp``, ``HorizontalFieldOfViewStartAngle`` ->
    ``horizontal_field_of_view_start_angle``; non-alphanumerics become underscores.
    """
    text = re.sub(r"[^0-9A-Za-z]+", "_", name)
    text = _CAMEL_1.sub(r"\1_\2", text)
    text = _CAMEL_2.sub(r"\1_\2", text)
    text = re.sub(r"_+", "_", text).strip("_").lower()
    if text and text[0].isdigit():
        text = "_" + text
    return text


# -- short constructors, so that a definition reads like the JSIDL -------------------------


def f(name: str, type_: FieldType, *, jsidl: str = "") -> Field:
    """A mandatory field."""
    return Field(name, type_, False, jsidl)


def opt(name: str, type_: FieldType, *, jsidl: str = "") -> Field:
    """An optional field (one presence-vector bit)."""
    return Field(name, type_, True, jsidl)


def record(*fields: Field, pv: Int | None = None, name: str = "") -> Record:
    """A record of ``fields`` with an optional presence vector."""
    return Record(tuple(fields), pv, name)


def message(
    code: int,
    name: str,
    *fields: Field,
    pv: Int | None = None,
    service_set: str,
    services: tuple[tuple[str, str], ...] = (),
    doc: str = "",
) -> MessageDef:
    """A message whose body is one record of ``fields``."""
    return MessageDef(code, name, Record(tuple(fields), pv, name), service_set, services, doc)
