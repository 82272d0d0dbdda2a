"""IdlStruct types built at run time from kit shapes (typed topics of profile mappings).

A profile maps a message of the user's JSIDL to a topic; the generic translator declares
the topic's type as a :class:`~edge_vis.kit.shapes.StructShape` and this module turns it
into a real IdlStruct, so the topic carries its JAUS fields with their types and any DDS
reader (``cyclonedds subscribe``, an operator station compiled from
``edge-vis idl --profile``) sees them member by member. No I/O.

The dataclasses are keyword-only, so an ``@optional`` member (default None) may precede a
required one without reordering the members. Building the same shape twice gives the same
class (XTypes sees one type per name).
"""

from __future__ import annotations

import dataclasses
import functools
import typing
from typing import Any

from cyclonedds.idl import IdlMeta, IdlStruct
from cyclonedds.idl import types as t

from edge_vis.kit.shapes import SeqShape, Shape, StructShape

_SCALARS: dict[str, Any] = {
    "boolean": bool, "int8": t.int8, "uint8": t.uint8, "int16": t.int16, "uint16": t.uint16,
    "int32": t.int32, "uint32": t.uint32, "int64": t.int64, "uint64": t.uint64,
    "float": t.float32, "double": t.float64, "string": str, "octets": t.sequence[t.uint8],
}


def _annotation(shape: Shape) -> Any:
    if isinstance(shape, StructShape):
        return struct_type(shape)
    if isinstance(shape, SeqShape):
        return t.sequence[_annotation(shape.element)]
    return _SCALARS[shape]


@functools.cache
def struct_type(shape: StructShape) -> type[IdlStruct]:
    """The IdlStruct class of ``shape`` (cached: one class per shape)."""
    short = shape.short
    namespace = IdlMeta.__prepare__(short, (IdlStruct,), typename=shape.name)
    for member in shape.members:
        annotation = _annotation(member.shape)
        if member.optional:
            annotation = typing.Optional[annotation]  # noqa: UP045 - cyclonedds reads Optional
            namespace[member.name] = None
        namespace["__annotations__"][member.name] = annotation
    keys = {m.name: {"key": True} for m in shape.members if m.key}
    if keys:
        namespace["__idl_field_annotations__"] = keys
    cls = IdlMeta(short, (IdlStruct,), namespace)
    return dataclasses.dataclass(kw_only=True)(cls)  # type: ignore[no-any-return]
