"""DDS type shapes from JAUS field types: what a typed topic carries, without DDS. No I/O.

A profile mapping (``[[translators.generic.mappings]]`` or ``.commands``) publishes or reads
a topic whose type is built at run time from the JSIDL field types of its message. The kit
describes that type as a *shape* - a declaration, so translators stay free of DDS and
``edge-vis idl --profile`` can print it without Cyclone DDS; the DDS side
(``edge_vis.dds.runtime_types``) builds the IdlStruct from it.

A shape is a scalar name (:data:`SCALARS`), a :class:`SeqShape` (a JAUS list) or a
:class:`StructShape` (a JAUS record; a variant is a struct whose alternatives are all
``@optional``, one present). The mapping from JAUS types keeps what the decoder gives, so a
decoded JAUS value is already a valid DDS value of its shape (and back for commands):

=====================================  =========================================
JAUS (codec type)                      DDS
=====================================  =========================================
integer (and value set, enumeration)   the integer of the same width and sign
scaled integer                         ``double`` in the field's units
float / long float                     ``float`` / ``double``
fixed or variable length string        ``string``
fixed or variable length field         ``sequence<octet>``
bit field                              struct of its sub-fields (integers)
variable format field                  struct ``{format, data}``
record / sequence                      struct (optional JAUS fields ``@optional``)
list                                   ``sequence<element>``
variant                                struct, one ``@optional`` member per alternative
=====================================  =========================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from edge_vis.codec.types import (
    BitField,
    Enum,
    FixedBytes,
    FixedString,
    Float,
    Int,
    JausMessage,
    List,
    Record,
    Scaled,
    VarBytes,
    VarFormat,
    Variant,
    VarString,
)

#: scalar shapes, by their IDL spelling (``octets`` is ``sequence<octet>``)
SCALARS = ("boolean", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
           "uint64", "float", "double", "string", "octets")
#: the IDL module typed topics live in
MODULE = "edge_vis::profile"


@dataclass(frozen=True, slots=True)
class Member:
    """One member of a struct shape; ``units`` of a measurement, for the IDL comment."""

    name: str
    shape: Shape
    optional: bool = False
    key: bool = False
    units: str = ""


@dataclass(frozen=True, slots=True)
class StructShape:
    """A struct: ``name`` is its fully scoped IDL name (``edge_vis::profile::CameraStatus``)."""

    name: str
    members: tuple[Member, ...]

    @property
    def short(self) -> str:
        """The name without its module."""
        return self.name.rsplit("::", 1)[-1]


@dataclass(frozen=True, slots=True)
class SeqShape:
    """A sequence of ``element``."""

    element: Shape


Shape = Union[str, StructShape, SeqShape]  # noqa: UP007 - a runtime alias


def camel(name: str) -> str:
    """``lens_list`` -> ``LensList``: part of a nested struct's type name."""
    return "".join(part[:1].upper() + part[1:] for part in name.split("_"))


def _int(raw: Int) -> str:
    return f"{'' if raw.signed else 'u'}int{raw.bits}"  # Int is 8, 16, 32 or 64 bits


def shape_of(field_type: object, type_name: str) -> Shape:
    """The DDS shape of a JAUS field type; a struct it needs is named ``type_name``."""
    if isinstance(field_type, Scaled):
        return "double"
    if isinstance(field_type, Enum):
        return _int(field_type.raw)
    if isinstance(field_type, Int):
        return _int(field_type)
    if isinstance(field_type, Float):
        return "float" if field_type.bits == 32 else "double"
    if isinstance(field_type, VarString | FixedString):
        return "string"
    if isinstance(field_type, VarBytes | FixedBytes | JausMessage):
        return "octets"
    if isinstance(field_type, BitField):
        width = _int(field_type.raw)
        return StructShape(type_name, tuple(Member(sub.name, width)
                                            for sub in field_type.subfields))
    if isinstance(field_type, VarFormat):
        return StructShape(type_name, (Member("format", _int(field_type.format.raw)),
                                       Member("data", "octets")))
    if isinstance(field_type, Record):
        return StructShape(type_name, tuple(
            Member(f.name, shape_of(f.type, type_name + camel(f.name)), f.optional,
                   units=_units(f.type))
            for f in field_type.fields))
    if isinstance(field_type, Variant):
        return StructShape(type_name, tuple(
            Member(a.name, shape_of(a.type, type_name + camel(a.name)), True,
                   units=_units(a.type))
            for a in field_type.alternatives))
    if isinstance(field_type, List):
        return SeqShape(shape_of(field_type.element, type_name))
    raise TypeError(f"no DDS shape for JAUS type {field_type!r}")


def _units(field_type: object) -> str:
    units = getattr(field_type, "units", "") or getattr(getattr(field_type, "raw", None),
                                                        "units", "")
    return "" if units in ("", "one") else str(units)


def field_at(body: Record, path: str) -> tuple[object, bool, str]:
    """``(type, optional, units)`` of the JAUS field at dotted ``path`` of a message body
    (a path :func:`~edge_vis.kit.rules.path_problem` accepts); optional when any step is."""
    node: object = body
    optional = False
    for step in path.split("."):
        if isinstance(node, Record):
            found = next(f for f in node.fields if f.name == step)
        elif isinstance(node, Variant):
            found = next(a for a in node.alternatives if a.name == step)
            optional = True
        else:  # a sub-field of a bit field or variable format field
            if isinstance(node, VarFormat):
                return (_int(node.format.raw) if step == "format" else VarBytes()), optional, ""
            assert isinstance(node, BitField)
            return node.raw, optional, ""
        optional = optional or found.optional
        node = found.type
    return node, optional, _units(node)


def struct_names(shape: Shape) -> list[StructShape]:
    """Every struct ``shape`` uses, innermost first (the order IDL declares them in)."""
    out: list[StructShape] = []

    def walk(s: Shape) -> None:
        if isinstance(s, SeqShape):
            walk(s.element)
        elif isinstance(s, StructShape):
            for m in s.members:
                walk(m.shape)
            if s not in out:
                out.append(s)

    walk(shape)
    return out


_IDL_SCALARS = {"boolean": "boolean", "float": "float", "double": "double",
                "string": "string", "octets": "sequence<octet>", "uint8": "octet"}


def idl_type(shape: Shape) -> str:
    """The IDL spelling of a member of ``shape``."""
    if isinstance(shape, StructShape):
        return shape.short
    if isinstance(shape, SeqShape):
        return f"sequence<{idl_type(shape.element)}>"
    return _IDL_SCALARS.get(shape, shape)


def idl_text(structs: list[StructShape], doc: dict[str, str] | None = None) -> str:
    """IDL declaring ``structs`` (and what they use) in module ``edge_vis::profile``."""
    ordered: list[StructShape] = []
    for struct in structs:
        for s in struct_names(struct):
            if s not in ordered:
                ordered.append(s)
    lines = ["module edge_vis {", "module profile {", ""]
    for s in ordered:
        if doc and s.name in doc:
            lines.append(f"// {doc[s.name]}")
        lines.append(f"struct {s.short} {{")
        for m in s.members:
            flags = "".join(("@key " if m.key else "", "@optional " if m.optional else ""))
            units = f"  // {m.units}" if m.units else ""
            lines.append(f"    {flags}{idl_type(m.shape)} {m.name};{units}")
        lines.extend(["};", ""])
    lines.extend(["};  // module profile", "};  // module edge_vis", ""])
    return "\n".join(lines)
