"""An independent, test-only reader of JSIDL (AS5684) XML. Reads files; no network.

It exists to give a *second opinion* on the message catalogue: it shares no code with
``edge_vis.catalogue.jsidl`` and reduces each ``message_def`` to its flattened sequence of wire
items
(:class:`Item`), the same shape :func:`flatten_record` derives from an
``edge_vis.codec.types`` definition, so the two can be compared item by item.

Flattening rules (they follow the wire, not the nesting):

* a record or sequence contributes its presence vector (if any) then its children in order;
  a nested record/sequence is inlined, so how a definition groups fields never matters;
* an optional child of a record with a presence vector carries its bit number in ``gate``
  (a chain of bits for nested presence vectors);
* lists, variants and ``variable_field`` s keep their element / alternatives as nested item
  tuples;
* arrays expand to one unnamed item per element.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

NS = "{urn:jaus:jsidl:1.0}"

_SCALAR_TYPES: dict[str, tuple[str, int, bool]] = {
    "byte": ("int", 8, True),
    "short integer": ("int", 16, True),
    "integer": ("int", 32, True),
    "long integer": ("int", 64, True),
    "unsigned byte": ("int", 8, False),
    "unsigned short integer": ("int", 16, False),
    "unsigned integer": ("int", 32, False),
    "unsigned long integer": ("int", 64, False),
    "float": ("float", 32, True),
    "long float": ("float", 64, True),
}

_CAMEL_1 = re.compile(r"(.)([A-Z][a-z]+)")
_CAMEL_2 = re.compile(r"([a-z0-9])([A-Z])")


def snake(name: str) -> str:
    """A JSIDL name in snake_case (written here again on purpose: an independent reading)."""
    text = re.sub(r"[^0-9A-Za-z]+", "_", name)
    text = _CAMEL_1.sub(r"\1_\2", text)
    text = _CAMEL_2.sub(r"\1_\2", text)
    text = re.sub(r"_+", "_", text).strip("_").lower()
    if text and text[0].isdigit():
        text = "_" + text
    return text


@dataclass(frozen=True)
class Item:
    """One wire item of a flattened message body.

    ``kind`` is one of ``pv``, ``int``, ``float``, ``scaled``, ``bits``, ``fixstr``,
    ``varstr``, ``bytes``, ``varfmt``, ``list``, ``variant``. ``name`` is snake_case or
    ``None`` when the reading has no name for it (array elements, list elements).
    """

    kind: str
    name: str | None
    bits: int = 0  # value width, or count/tag/PV width for containers
    signed: bool = False
    lower: float = 0.0
    upper: float = 0.0
    length: int = 0  # fixed string length
    count_bits: int = 0  # varfmt count width
    subfields: tuple[tuple[int, int, str], ...] = ()
    element: tuple[Item, ...] = ()
    #: variant alternatives: (tag value, name, items)
    alternatives: tuple[tuple[int, str | None, tuple[Item, ...]], ...] = ()
    gate: tuple[int, ...] = ()
    #: named values of an integer (JSIDL ``value_enum``), as (value, name), sorted
    labels: tuple[tuple[int, str], ...] = ()

    def describe(self) -> str:
        """Short human text of the wire type."""
        k = self.kind
        if k == "int":
            return f"{'i' if self.signed else 'u'}{self.bits}"
        if k == "float":
            return f"f{self.bits}"
        if k == "scaled":
            return f"{'i' if self.signed else 'u'}{self.bits}[{self.lower:g}..{self.upper:g}]"
        if k == "pv":
            return f"PV u{self.bits}"
        if k == "bits":
            return f"bitfield u{self.bits} {[(lo, hi) for lo, hi, _ in self.subfields]}"
        if k == "fixstr":
            return f"char[{self.length}]"
        if k == "varstr":
            return f"string (count u{self.bits})"
        if k == "bytes":
            return f"bytes (count u{self.bits})"
        if k == "varfmt":
            return f"format u{self.bits} + bytes (count u{self.count_bits})"
        if k == "list":
            return f"list (count u{self.bits}) of {len(self.element)} item(s)"
        if k == "variant":
            return f"variant (tag u{self.bits}) of {len(self.alternatives)} alternative(s)"
        return k


@dataclass
class JsidlMessage:
    """A message as one JSIDL file defines it."""

    code: int
    name: str
    items: tuple[Item, ...]
    #: ``(root label, path relative to the root)`` of every file defining this exact layout
    sources: list[tuple[str, str]] = field(default_factory=list)
    #: ``(service uri, version)`` of the services declaring it
    services: set[tuple[str, str]] = field(default_factory=set)


class JsidlError(Exception):
    """The JSIDL itself could not be read (an unresolvable reference, an unknown element)."""


def _tag(elem: ET.Element) -> str:
    return elem.tag[len(NS):] if elem.tag.startswith(NS) else elem.tag


def _children(elem: ET.Element, *names: str) -> list[ET.Element]:
    return [c for c in elem if _tag(c) in names]


def _width(type_name: str | None) -> int:
    if not type_name:
        raise JsidlError("missing field_type_unsigned")
    kind, bits, _ = _SCALAR_TYPES[" ".join(type_name.split())]
    if kind != "int":
        raise JsidlError(f"count/tag type {type_name!r} is not an integer")
    return bits


class JsidlLibrary:
    """Every JSIDL file under one root directory, with cross-file reference resolution."""

    def __init__(self, root: Path, label: str) -> None:
        self.root = root
        self.label = label
        self.parent: dict[ET.Element, ET.Element] = {}
        self.file_of: dict[ET.Element, str] = {}
        self.sets: dict[tuple[str, str], list[ET.Element]] = {}
        self.trees: list[ET.Element] = []
        for path in sorted(root.rglob("*.xml")):
            top = ET.parse(path).getroot()
            rel = str(path.relative_to(root))
            self.trees.append(top)
            self.file_of[top] = rel
            for parent in top.iter():
                for child in parent:
                    self.parent[child] = parent
            if _tag(top) in ("declared_type_set", "declared_const_set", "service_def"):
                key = (top.get("id", ""), top.get("version", ""))
                self.sets.setdefault(key, []).append(top)

    # -- reference resolution -------------------------------------------------------------

    def _file(self, elem: ET.Element) -> str:
        while elem in self.parent:
            elem = self.parent[elem]
        return self.file_of.get(elem, "?")

    def _scopes(self, elem: ET.Element) -> Iterator[ET.Element]:
        """Enclosing type sets, innermost first (a service_def exposes its inline sets)."""
        node: ET.Element | None = elem
        while node is not None:
            tag = _tag(node)
            if tag in ("declared_type_set", "declared_const_set"):
                yield node
            elif tag == "service_def":
                yield from _children(node, "declared_type_set")
                yield node
            node = self.parent.get(node)

    def _target_set(self, ref: ET.Element) -> ET.Element:
        key = (ref.get("id", ""), ref.get("version", ""))
        found = self.sets.get(key)
        if not found:
            same_id = [v for (i, _), v in self.sets.items() if i == key[0]]
            if not same_id:
                raise JsidlError(f"type set {key[0]} v{key[1]} not found under {self.label}")
            found = same_id[0]
        return found[0]

    def _lookup(self, scope: ET.Element, parts: list[str]) -> ET.Element | None:
        head = parts[0]
        if len(parts) == 1:
            for child in scope:
                if child.get("name") == head and _tag(child) not in (
                    "declared_type_set_ref", "declared_const_set_ref"):
                    return child
            return None
        for child in scope:
            if _tag(child) in ("declared_type_set_ref", "declared_const_set_ref") and \
                    child.get("name") == head:
                return self._lookup(self._target_set(child), parts[1:])
        return None

    def resolve(self, ref: str, at: ET.Element) -> ET.Element:
        """The element a ``declared_type_ref`` names, seen from element ``at``."""
        parts = ref.split(".")
        for scope in self._scopes(at):
            found = self._lookup(scope, parts)
            if found is not None:
                return found
        raise JsidlError(f"cannot resolve {ref!r} in {self.label}/{self._file(at)}")

    def constant(self, expr: str, at: ET.Element) -> float:
        """Evaluate a scale limit such as ``-8*basicConsts.PI`` or ``3.14159/2``."""

        def value_of(match: re.Match[str]) -> str:
            ref = match.group(0)
            try:
                const = self.resolve(ref, at)
                return repr(float(const.get("const_value", "nan")))
            except JsidlError:
                if ref.split(".")[-1] == "PI":
                    return repr(math.pi)
                raise

        text = re.sub(r"[A-Za-z_][\w.]*", value_of, expr.strip())
        if not re.fullmatch(r"[0-9eE.+\-*/() ]+", text):
            raise JsidlError(f"unexpected scale expression {expr!r}")
        return float(eval(text, {"__builtins__": {}}, {}))  # digits and operators only

    # -- flattening ----------------------------------------------------------------------

    def _definition(self, elem: ET.Element) -> tuple[ET.Element, str | None, bool]:
        """Follow ``declared_*`` to the definition; keep the use-site name and optional."""
        name = elem.get("name")
        optional = elem.get("optional", "false").strip() == "true"
        seen = 0
        while _tag(elem).startswith("declared_") and elem.get("declared_type_ref"):
            elem = self.resolve(elem.get("declared_type_ref", ""), elem)
            seen += 1
            if seen > 20:
                raise JsidlError(f"reference loop at {name}")
        return elem, name, optional

    def items_of(self, use: ET.Element, gate: tuple[int, ...] = ()) -> list[Item]:
        """The wire items of one child element (a field, record, list, ...)."""
        elem, name, _ = self._definition(use)
        tag = _tag(elem)
        sname = snake(name) if name else None
        if tag in ("record", "sequence", "body"):
            return self.group_items(elem, gate)
        if tag == "fixed_field":
            return [self._fixed(elem, sname, gate)]
        if tag == "bit_field":
            subs = []
            for sub in _children(elem, "sub_field"):
                rng = _children(sub, "bit_range")[0]
                subs.append((int(rng.get("from_index", "0")), int(rng.get("to_index", "0")),
                             snake(sub.get("name", ""))))
            return [Item("bits", sname, _width(elem.get("field_type_unsigned")),
                         subfields=tuple(subs), gate=gate)]
        if tag == "fixed_length_string":
            return [Item("fixstr", sname, length=int(elem.get("string_length", "0")), gate=gate)]
        if tag == "variable_length_string":
            count = _children(elem, "count_field")[0]
            return [Item("varstr", sname, _width(count.get("field_type_unsigned")), gate=gate)]
        if tag == "variable_length_field":
            count = _children(elem, "count_field")[0]
            return [Item("bytes", sname, _width(count.get("field_type_unsigned")), gate=gate)]
        if tag == "variable_format_field":
            count = _children(elem, "count_field")[0]
            return [Item("varfmt", sname, 8, count_bits=_width(count.get("field_type_unsigned")),
                         gate=gate)]
        if tag == "list":
            count = _children(elem, "count_field")[0]
            body = [c for c in elem if _tag(c) not in ("count_field", "description")]
            element: list[Item] = []
            for child in body:
                element.extend(self.items_of(child))
            return [Item("list", sname, _width(count.get("field_type_unsigned")),
                         element=tuple(element), gate=gate)]
        if tag == "variant":
            vtag = _children(elem, "vtag_field")[0]
            alts = []
            for index, alt in enumerate(c for c in elem if _tag(c) not in (
                    "vtag_field", "description")):
                alts.append((index, alt.get("name"), tuple(self.items_of(alt))))
            width = _width(vtag.get("field_type_unsigned"))
            if not alts:  # a tag with nothing to select is just an integer on the wire
                return [Item("int", sname, width, gate=gate)]
            return [Item("variant", sname, width, alternatives=tuple(alts), gate=gate)]
        if tag == "variable_field":
            tuf = _children(elem, "type_and_units_field")[0]
            alts = []
            for enum in _children(tuf, "type_and_units_enum"):
                alts.append((int(enum.get("index", "0")), enum.get("name"),
                             (self._fixed(enum, None, ()),)))
            return [Item("variant", sname, 8, alternatives=tuple(alts), gate=gate)]
        if tag == "array":
            size = 1
            for dim in _children(elem, "dimension"):
                size *= int(dim.get("size", "1"))
            element = [c for c in elem if _tag(c) not in ("dimension", "description")]
            one: list[Item] = []
            for child in element:
                one.extend(self.items_of(child, gate))
            return [Item(**{**_fields(i), "name": None}) for _ in range(size) for i in one]
        raise JsidlError(f"unsupported JSIDL element <{tag}> ({name}) in {self._file(elem)}")

    def _fixed(self, elem: ET.Element, name: str | None, gate: tuple[int, ...]) -> Item:
        kind, bits, signed = _SCALAR_TYPES[" ".join(elem.get("field_type", "").split())]
        scale = _children(elem, "scale_range")
        if scale and kind == "int":
            lo = self.constant(scale[0].get("real_lower_limit", "0"), elem)
            hi = self.constant(scale[0].get("real_upper_limit", "0"), elem)
            return Item("scaled", name, bits, signed, lo, hi, gate=gate)
        labels = []
        for value_set in _children(elem, "value_set"):
            for enum in _children(value_set, "value_enum"):
                labels.append((int(enum.get("enum_index", "0")),
                               " ".join(enum.get("enum_const", "").split())))
        return Item(kind, name, bits, signed, gate=gate, labels=tuple(sorted(labels)))

    def group_items(self, group: ET.Element, gate: tuple[int, ...] = ()) -> list[Item]:
        """A record / sequence / body: its presence vector, then its children, inlined."""
        out: list[Item] = []
        pv = _children(group, "presence_vector")
        if pv:
            out.append(Item("pv", None, _width(pv[0].get("field_type_unsigned")), gate=gate))
        bit = 0
        for child in group:
            tag = _tag(child)
            if tag in ("presence_vector", "description"):
                continue
            child_gate = gate
            if pv and child.get("optional", "false").strip() == "true":
                child_gate = (*gate, bit)
                bit += 1
            out.extend(self.items_of(child, child_gate))
        return out

    # -- messages ------------------------------------------------------------------------

    def messages(self) -> Iterator[tuple[ET.Element, JsidlMessage]]:
        """Every ``message_def`` in every file, flattened."""
        for top in self.trees:
            for elem in top.iter(f"{NS}message_def"):
                body = _children(elem, "body")
                items = self.group_items(body[0]) if body else []
                msg = JsidlMessage(int(elem.get("message_id", "0"), 16), elem.get("name", ""),
                                   tuple(items), [(self.label, self._file(elem))])
                yield elem, msg

    def services(self) -> Iterator[tuple[ET.Element, tuple[str, str]]]:
        """``(message_def element, (service uri, version))`` for every declaring service."""
        for top in self.trees:
            if _tag(top) != "service_def":
                continue
            service = (top.get("id", ""), top.get("version", ""))
            for mset in _children(top, "message_set"):
                for elem in mset.iter():
                    if _tag(elem) == "message_def":
                        yield elem, service
                    elif _tag(elem) == "declared_message_def":
                        yield self.resolve(elem.get("declared_type_ref", ""), elem), service


def _fields(item: Item) -> dict[str, object]:
    return {k: getattr(item, k) for k in Item.__dataclass_fields__}


def load_all(roots: Iterable[tuple[Path, str]]) -> dict[int, list[JsidlMessage]]:
    """Every distinct layout per message code, over all roots, with where it came from."""
    by_code: dict[int, list[JsidlMessage]] = {}
    for root, label in roots:
        lib = JsidlLibrary(root, label)
        declared: dict[ET.Element, set[tuple[str, str]]] = {}
        for elem, service in lib.services():
            declared.setdefault(elem, set()).add(service)
        for elem, msg in lib.messages():
            msg.services |= declared.get(elem, set())
            known = by_code.setdefault(msg.code, [])
            for other in known:
                if other.name == msg.name and other.items == msg.items:
                    other.sources.extend(msg.sources)
                    other.services |= msg.services
                    break
            else:
                known.append(msg)
    return by_code


# -- the same reduction of an edge_vis.codec.types definition ------------------------------


def flatten_type(t: object, name: str | None, gate: tuple[int, ...] = ()) -> list[Item]:
    """The wire items of one ``edge_vis.codec.types`` value (duck-typed by class name)."""
    kind = type(t).__name__
    if kind == "Int":
        return [Item("int", name, t.bits, t.signed, gate=gate)]
    if kind == "Float":
        return [Item("float", name, t.bits, True, gate=gate)]
    if kind == "Scaled":
        return [Item("scaled", name, t.raw.bits, t.raw.signed, float(t.lower), float(t.upper),
                     gate=gate)]
    if kind == "Enum":
        return [Item("int", name, t.raw.bits, t.raw.signed, gate=gate,
                     labels=tuple(sorted(t.labels.items())))]
    if kind == "BitField":
        subs = tuple((s.lo, s.hi, snake(s.name)) for s in t.subfields)
        return [Item("bits", name, t.raw.bits, subfields=subs, gate=gate)]
    if kind == "FixedString":
        return [Item("fixstr", name, length=t.length, gate=gate)]
    if kind == "VarString":
        return [Item("varstr", name, t.count.bits, gate=gate)]
    if kind == "FixedBytes":
        return [Item("int", None, 8, gate=gate) for _ in range(t.length)]
    if kind in ("VarBytes", "JausMessage"):
        return [Item("bytes", name, t.count.bits, gate=gate)]
    if kind == "VarFormat":
        return [Item("varfmt", name, t.format.raw.bits, count_bits=t.count.bits, gate=gate)]
    if kind == "Record":
        return flatten_record(t, gate)
    if kind == "List":
        return [Item("list", name, t.count.bits, element=tuple(flatten_type(t.element, None)),
                     gate=gate)]
    if kind == "Variant":
        alts = []
        for index, alt in enumerate(t.alternatives):
            value = t.tag_values[index] if t.tag_values else index
            alts.append((value, alt.name, tuple(flatten_type(alt.type, _field_name(alt)))))
        return [Item("variant", name, t.tag.bits, alternatives=tuple(alts), gate=gate)]
    raise TypeError(f"unknown field type {kind} for {name}")


def _field_name(fld: object) -> str:
    return snake(getattr(fld, "jsidl_name", "") or fld.name)


def flatten_record(rec: object, gate: tuple[int, ...] = ()) -> list[Item]:
    """A ``Record``: its presence vector, then its fields, nested records inlined."""
    out: list[Item] = []
    if rec.pv is not None:
        out.append(Item("pv", None, rec.pv.bits, gate=gate))
    bit = 0
    for fld in rec.fields:
        child_gate = gate
        if rec.pv is not None and fld.optional:
            child_gate = (*gate, bit)
            bit += 1
        out.extend(flatten_type(fld.type, _field_name(fld), child_gate))
    return out


# -- comparison ----------------------------------------------------------------------------


def _where(item: Item) -> str:
    gate = f" (PV bit {'.'.join(map(str, item.gate))})" if item.gate else ""
    return f"{item.describe()}{gate}"


def _path(prefix: str, item: Item, index: int) -> str:
    label = item.name if item.name else f"#{index}"
    return f"{prefix}.{label}" if prefix else label


def compare_items(expected: tuple[Item, ...] | list[Item], actual: tuple[Item, ...] | list[Item],
                  prefix: str = "") -> list[str]:
    """Every difference, as ``field path: expected ..., actual ...`` lines."""
    problems: list[str] = []
    for index, (e, a) in enumerate(zip(expected, actual, strict=False)):
        path = _path(prefix, e if e.name else a, index)
        if e.kind != a.kind or e.bits != a.bits or (e.kind != "pv" and e.signed != a.signed):
            problems.append(f"{path}: expected {_where(e)}, actual {_where(a)}")
            continue
        if e.name and a.name and e.name != a.name:
            problems.append(f"{path}: expected name {e.name!r}, actual {a.name!r}")
        if e.gate != a.gate:
            problems.append(f"{path}: expected {_where(e) if e.gate else 'mandatory'}, "
                            f"actual {_where(a) if a.gate else 'mandatory'}")
        if e.kind == "scaled" and not (
                math.isclose(e.lower, a.lower, rel_tol=1e-9, abs_tol=1e-9)
                and math.isclose(e.upper, a.upper, rel_tol=1e-9, abs_tol=1e-9)):
            problems.append(f"{path}: expected scale [{e.lower!r}..{e.upper!r}], "
                            f"actual [{a.lower!r}..{a.upper!r}]")
        if e.labels != a.labels:
            problems.append(f"{path}: expected value names {dict(e.labels)}, "
                            f"actual {dict(a.labels)}")
        if e.kind == "fixstr" and e.length != a.length:
            problems.append(f"{path}: expected char[{e.length}], actual char[{a.length}]")
        if e.kind == "varfmt" and e.count_bits != a.count_bits:
            problems.append(f"{path}: expected {_where(e)}, actual {_where(a)}")
        if e.kind == "bits":
            if [s[:2] for s in e.subfields] != [s[:2] for s in a.subfields]:
                problems.append(f"{path}: expected bit ranges {[s[:2] for s in e.subfields]}, "
                                f"actual {[s[:2] for s in a.subfields]}")
            elif [s[2] for s in e.subfields] != [s[2] for s in a.subfields]:
                problems.append(f"{path}: expected sub-fields {[s[2] for s in e.subfields]}, "
                                f"actual {[s[2] for s in a.subfields]}")
        if e.kind == "list":
            problems.extend(compare_items(e.element, a.element, f"{path}[]"))
        if e.kind == "variant":
            etags = [t for t, _, _ in e.alternatives]
            atags = [t for t, _, _ in a.alternatives]
            if etags != atags:
                problems.append(f"{path}: expected alternatives with tags {etags}, actual {atags}")
                continue
            for (tag, _, eitems), (_, _, aitems) in zip(e.alternatives, a.alternatives,
                                                         strict=True):
                problems.extend(compare_items(eitems, aitems, f"{path}<{tag}>"))
    if len(expected) > len(actual):
        missing = expected[len(actual)]
        problems.append(f"{_path(prefix, missing, len(actual))}: expected {_where(missing)}, "
                        f"actual nothing (definition ends early)")
    elif len(actual) > len(expected):
        extra = actual[len(expected)]
        problems.append(f"{_path(prefix, extra, len(expected))}: expected nothing, "
                        f"actual {_where(extra)}")
    return problems
