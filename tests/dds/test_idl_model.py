"""The shipped IDL and the Python IdlStruct types describe the same data model.

Operator stations in C/C++ compile ``edge_vis.idl``; the relay uses ``edge_vis.dds.model``.
If the two drift apart, DDS type matching fails or samples decode as garbage, so every
struct, member, member type, key, optional flag and enumerator is compared.
"""

from __future__ import annotations

import dataclasses
import enum
import re
import typing
from typing import Any

import pytest

from edge_vis.cli import idl as idl_command
from edge_vis.dds import model
from edge_vis.dds.convert import key_members
from edge_vis.dds.topics import standard_topics

pytestmark = pytest.mark.dds

IDL = idl_command.idl_text()


# --------------------------------------------------------------------------- a minimal IDL parser


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def parse_idl(text: str) -> tuple[str, dict[str, list[str]], dict[str, list[tuple[str, ...]]]]:
    """(module name, enum name -> enumerators, struct name -> [(type, name, flags...)])."""
    body = _strip_comments(text)
    module = re.search(r"\bmodule\s+(\w+)\s*\{", body)
    assert module, "no module in the IDL"
    enums = {
        name: [e.strip() for e in items.split(",") if e.strip()]
        for name, items in re.findall(r"\benum\s+(\w+)\s*\{([^}]*)\}\s*;", body)
    }
    structs: dict[str, list[tuple[str, ...]]] = {}
    for name, members in re.findall(r"\bstruct\s+(\w+)\s*\{([^}]*)\}\s*;", body):
        parsed = []
        for decl in members.split(";"):
            decl = " ".join(decl.split())
            if not decl:
                continue
            flags = tuple(sorted(re.findall(r"@(\w+)", decl)))
            decl = re.sub(r"@\w+\s*", "", decl)
            match = re.fullmatch(r"(.+?)\s+(\w+)", decl)
            assert match, f"cannot parse member {decl!r} of {name}"
            parsed.append((match.group(1).replace(" ", ""), match.group(2), *flags))
        structs[name] = parsed
    return module.group(1), enums, structs


# --------------------------------------------------------------------------- Python side

_PRIMITIVES = {
    str: "string",
    bool: "boolean",
    float: "double",
    int: "int64",
}


def idl_type(annotation: Any) -> tuple[str, bool]:
    """(IDL spelling of a member annotation, is @optional)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Union:
        (inner,) = [a for a in typing.get_args(annotation) if a is not type(None)]
        return idl_type(inner)[0], True
    if origin is typing.Annotated:
        meta = typing.get_args(annotation)[1]
        if isinstance(meta, str):
            return {"float64": "double", "float32": "float", "byte": "octet"}.get(meta, meta), False
        subtype = getattr(meta, "subtype", None)
        if subtype is not None and type(meta).__name__ == "sequence":
            return f"sequence<{idl_type(subtype)[0]}>", False
        raise AssertionError(f"unexpected annotation {annotation!r}")
    if annotation in _PRIMITIVES:
        return _PRIMITIVES[annotation], False
    if isinstance(annotation, type) and issubclass(annotation, (enum.Enum, model.IdlStruct)):
        return annotation.__name__, False
    raise AssertionError(f"unexpected annotation {annotation!r}")


def python_struct(cls: type) -> list[tuple[str, ...]]:
    hints = typing.get_type_hints(cls, include_extras=True)
    keys = set(key_members(cls))
    out = []
    for member in dataclasses.fields(cls):
        spelled, optional = idl_type(hints[member.name])
        flags = tuple(sorted(({"key"} if member.name in keys else set())
                             | ({"optional"} if optional else set())))
        out.append((spelled, member.name, *flags))
    return out


def python_model() -> tuple[dict[str, list[str]], dict[str, list[tuple[str, ...]]]]:
    enums = {
        name: [m.name for m in obj]
        for name, obj in vars(model).items()
        if isinstance(obj, type) and issubclass(obj, model.IdlEnum) and obj is not model.IdlEnum
    }
    structs = {
        name: python_struct(obj)
        for name, obj in vars(model).items()
        if isinstance(obj, type) and issubclass(obj, model.IdlStruct) and obj is not model.IdlStruct
    }
    return enums, structs


# --------------------------------------------------------------------------- tests


def test_the_idl_declares_module_edge_vis() -> None:
    module, _, _ = parse_idl(IDL)
    assert module == "edge_vis"


def test_idl_and_python_declare_the_same_structs_members_types_and_keys() -> None:
    _, idl_enums, idl_structs = parse_idl(IDL)
    py_enums, py_structs = python_model()
    assert sorted(idl_structs) == sorted(py_structs)
    for name, members in py_structs.items():
        assert idl_structs[name] == members, f"struct {name} differs between IDL and Python"
    assert idl_enums == py_enums


def test_python_typenames_live_in_the_idl_module() -> None:
    _, py_structs = python_model()
    for name in py_structs:
        assert getattr(model, name).__idl_typename__ == f"edge_vis::{name}"


def test_enumerators_are_unique_in_the_module_scope() -> None:
    """IDL puts enumerators in the enclosing scope: a duplicate would not compile."""
    _, enums, _ = parse_idl(IDL)
    literals = [lit for items in enums.values() for lit in items]
    assert len(literals) == len(set(literals))


def test_the_idl_parser_notices_a_drift() -> None:
    """Guard the guard: a changed member type is detected."""
    drifted = IDL.replace("double latitude;                    // deg\n    double longitude;"
                          "                   // deg\n    double altitude;                    // m "
                          "above", "float latitude; double longitude; double altitude; // m above")
    assert drifted != IDL
    _, _, structs = parse_idl(drifted)
    assert structs["GlobalPose"] != python_struct(model.GlobalPose)


def test_every_topic_type_is_keyed_by_vehicle_id_or_link() -> None:
    for spec in standard_topics():
        keys = key_members(spec.type)
        if spec.name == "RelayStatus":  # one instance per relay on the domain
            assert keys == ("relay",)
            continue
        assert "vehicle_id" in keys, spec.name
        if spec.name == "LinkStatus":  # two relays' links of one name are two instances
            assert keys == ("link", "vehicle_id", "relay")
