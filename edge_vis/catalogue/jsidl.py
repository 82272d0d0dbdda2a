"""Read JSIDL (SAE AS5684) service definitions into :class:`~edge_vis.codec.types.MessageDef`.

Reads the XML files it is given (file I/O only, no network); everything else is pure.
Used at run time for users' own JSIDL and by ``tools/gen_messages.py`` to write the
built-in message modules.

How JSIDL maps onto the codec DSL:

==================================  =====================================================
JSIDL                               edge-vis
==================================  =====================================================
``fixed_field``                     :class:`Int` / :class:`Float`; with ``scale_range`` a
                                    :class:`Scaled`; with a ``value_set`` an :class:`Enum`
``bit_field`` / ``sub_field``       :class:`BitField` / :class:`SubField`
``variable_length_string``          :class:`VarString` (count width from ``count_field``)
``fixed_length_string``             :class:`FixedString`
``variable_length_field``           :class:`JausMessage` when ``field_format`` is
                                    "JAUS MESSAGE", else :class:`VarBytes`
``variable_format_field``           :class:`VarFormat`
``variable_field``                  :class:`Variant` whose tag is the type-and-units index
``record`` / ``sequence``           :class:`Record` (``presence_vector`` -> ``pv``)
``list``                            :class:`List`
``variant``                         :class:`Variant` (a variant with no alternatives is
                                    just its tag, an :class:`Int`)
``array`` (fixed dimensions)        :class:`Record` of ``<element>_<i>`` fields: arrays
                                    carry no count on the wire
==================================  =====================================================

A message body that is a single record or sequence is flattened: its members become the
message's top-level fields and its presence vector the message's. Types are looked up
through ``declared_type_set_ref`` chains (``core.commandClass.CreateEvent``) among all the
files given; scale limits may be expressions over declared constants
(``-8*basicConsts.PI``). Every problem raises :class:`~edge_vis.errors.ConfigError` naming
the file, the element (tag, name and line) and what is wrong.

Two leniencies, both because published JSIDL needs them: the message header is not
required to resolve (it is always the 2-byte message ID, and users' files often leave out
the core type set that declares it), and a prefix declared only by a referenced type set
is found through it (the HMI set relies on that).
"""

from __future__ import annotations

import ast
import logging
import math
import operator
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, overload
from xml.parsers import expat

from edge_vis.codec.types import (
    BitField,
    Enum,
    Field,
    FieldType,
    FixedString,
    Float,
    Int,
    JausMessage,
    List,
    MessageDef,
    Record,
    Scaled,
    SubField,
    VarBytes,
    VarFormat,
    Variant,
    VarString,
    f32,
    f64,
    i8,
    i16,
    i32,
    i64,
    snake_case,
    u8,
    u16,
    u32,
    u64,
)
from edge_vis.errors import ConfigError

if TYPE_CHECKING:
    from edge_vis.catalogue import Catalogue

__all__ = ["JsidlModel", "load_jsidl", "parse_files"]

log = logging.getLogger(__name__)

#: JSIDL ``field_type`` names -> wire types
FIELD_TYPES: dict[str, Int | Float] = {
    "byte": i8,
    "short integer": i16,
    "integer": i32,
    "long integer": i64,
    "unsigned byte": u8,
    "unsigned short integer": u16,
    "unsigned integer": u32,
    "unsigned long integer": u64,
    "float": f32,
    "long float": f64,
}
UNSIGNED_TYPES = {k: v for k, v in FIELD_TYPES.items() if k.startswith("unsigned")}

#: JSIDL units that mean "dimensionless"
_NO_UNITS = {"one", ""}

# -- a small XML tree that remembers line numbers ------------------------------------------


@dataclass(eq=False)
class Node:
    """One XML element: local tag name, attributes, children, source file and line."""

    tag: str
    attrs: dict[str, str]
    file: str
    line: int
    children: list[Node] = field(default_factory=list)
    text: str = ""
    parent: Node | None = field(default=None, repr=False)

    @overload
    def get(self, key: str) -> str | None: ...
    @overload
    def get(self, key: str, default: str) -> str: ...
    def get(self, key: str, default: str | None = None) -> str | None:
        """Attribute ``key``; with a string ``default``, always a string."""
        return self.attrs.get(key, default)

    @property
    def name(self) -> str:
        return self.attrs.get("name", "")

    def kids(self, *tags: str) -> list[Node]:
        return [c for c in self.children if not tags or c.tag in tags]

    def first(self, tag: str) -> Node | None:
        for c in self.children:
            if c.tag == tag:
                return c
        return None

    def where(self) -> str:
        """``<tag name="X"> (line N)`` for error messages; a nameless element also names
        its nearest named ancestor (``<scale_range> in <fixed_field name="Lat">``)."""
        name = f' name="{self.name}"' if self.name else ""
        text = f"<{self.tag}{name}>"
        if not self.name:
            up = self.parent
            while up is not None and not up.name:
                up = up.parent
            if up is not None:
                text += f' in <{up.tag} name="{up.name}">'
        return f"{text} (line {self.line})"


def parse_xml(path: Path) -> Node:
    """Parse one XML file into :class:`Node` s, or raise ConfigError with the line."""
    file = str(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError([(file, "", f"cannot read JSIDL file: {exc.strerror or exc}")]) from exc
    parser = expat.ParserCreate(namespace_separator="}")
    stack: list[Node] = []
    root: list[Node] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        local = tag.rsplit("}", 1)[-1]
        clean = {k.rsplit("}", 1)[-1] if "}" in k else k: v for k, v in attrs.items()}
        node = Node(local, clean, file, parser.CurrentLineNumber)
        node.parent = stack[-1] if stack else None
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(_tag: str) -> None:
        stack.pop()

    def chars(text: str) -> None:
        if stack:
            stack[-1].text += text

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise ConfigError(
            [(file, f"line {exc.lineno}, column {exc.offset + 1}",
              f"not well-formed XML: {expat.ErrorString(exc.code)}")]
        ) from exc
    return root[0]


def _fail(node: Node, problem: str) -> ConfigError:
    return ConfigError([(node.file, node.where(), problem)])


# -- type sets, constant sets and name scopes ----------------------------------------------

#: elements that define a named type inside a declared_type_set
_TYPE_TAGS = {
    "fixed_field", "bit_field", "variable_length_string", "fixed_length_string",
    "variable_length_field", "variable_format_field", "variable_field", "record",
    "sequence", "list", "variant", "array", "header", "footer", "message_def", "body",
}


@dataclass(eq=False)
class Scope:
    """A namespace: a declared_type_set (or a service's anonymous one) and its references."""

    model: JsidlModel
    node: Node | None
    types: dict[str, Node] = field(default_factory=dict)
    type_refs: dict[str, Node] = field(default_factory=dict)
    const_refs: dict[str, Node] = field(default_factory=dict)
    consts: dict[str, Node] = field(default_factory=dict)
    label: str = ""

    @classmethod
    def of(cls, model: JsidlModel, node: Node | None, label: str = "") -> Scope:
        scope = cls(model, node, label=label)
        if node is None:
            return scope
        for child in node.children:
            if child.tag == "declared_type_set_ref":
                scope.type_refs[child.name] = child
            elif child.tag == "declared_const_set_ref":
                scope.const_refs[child.name] = child
            elif child.tag == "const_def":
                scope.consts[child.name] = child
            elif child.tag in _TYPE_TAGS and child.name:
                scope.types.setdefault(child.name, child)
        return scope

    def _ref_scope(self, ref: Node, const: bool) -> Scope:
        key = (ref.get("id", ""), ref.get("version", ""))
        table = self.model.const_sets if const else self.model.type_sets
        scope = table.get(key)
        if scope is None:
            versions = sorted(v for (i, v) in table if i == key[0])
            what = "declared_const_set" if const else "declared_type_set"
            hint = f" (loaded versions: {', '.join(versions)})" if versions else ""
            raise _fail(ref, f"unresolved {what} {key[0]} version {key[1]}{hint}")
        return scope

    def _indirect_ref(self, name: str) -> Node | None:
        """A reference named ``name`` made by a type set this one references.

        Some published JSIDL (the HMI set) uses a prefix declared only by a type set it
        references; the JAUS Toolset accepts that, so this reader does too, when the
        name is unambiguous.
        """
        found: dict[tuple[str, str], Node] = {}
        todo, seen = list(self.type_refs.values()), set()
        while todo:
            ref = todo.pop(0)
            key = (ref.get("id", ""), ref.get("version", ""))
            if key in seen:
                continue
            seen.add(key)
            scope = self.model.type_sets.get(key)
            if scope is None:
                continue
            hit = scope.type_refs.get(name)
            if hit is not None:
                found[(hit.get("id", ""), hit.get("version", ""))] = hit
            todo.extend(scope.type_refs.values())
        if len(found) == 1:
            log.debug("resolved prefix %r indirectly in %s", name, self.label)
            return next(iter(found.values()))
        return None

    def resolve(self, dotted: str, at: Node) -> tuple[Node, Scope]:
        """Find the type ``a.b.Name`` as seen from this scope."""
        parts = dotted.strip().split(".")
        scope: Scope = self
        for part in parts[:-1]:
            ref = scope.type_refs.get(part) or scope._indirect_ref(part)
            if ref is None:
                raise _fail(at, f"unresolved declared type {dotted!r}: no declared_type_set_ref "
                            f"named {part!r} in {scope.label or 'scope'}")
            scope = scope._ref_scope(ref, const=False)
        node = scope.types.get(parts[-1])
        if node is None:
            raise _fail(at, f"unresolved declared type {dotted!r}: {parts[-1]!r} is not "
                        f"defined in {scope.label or 'scope'}")
        return node, scope

    def constant(self, dotted: str, at: Node) -> float:
        """The value of the constant ``prefix.NAME`` (or a local ``NAME``)."""
        parts = dotted.split(".")
        scope: Scope = self
        for part in parts[:-1]:
            ref = scope.const_refs.get(part)
            if ref is not None:
                scope = scope._ref_scope(ref, const=True)
                continue
            tref = scope.type_refs.get(part)
            if tref is None:
                raise _fail(at, f"unresolved constant {dotted!r}: no reference named {part!r}")
            scope = scope._ref_scope(tref, const=False)
        node = scope.consts.get(parts[-1])
        if node is None:
            raise _fail(at, f"unresolved constant {dotted!r}")
        return scope.evaluate(node.get("const_value", ""), node)

    _OPS: ClassVar[dict[type, Callable[..., float]]] = {
        ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv, ast.USub: operator.neg, ast.UAdd: operator.pos,
    }

    def evaluate(self, text: str, at: Node) -> float:
        """Evaluate a numeric JSIDL expression such as ``-8*basicConsts.PI``."""
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError:
            raise _fail(at, f"not a number or expression: {text!r}") from None

        def dotted(n: ast.expr) -> str | None:
            if isinstance(n, ast.Name):
                return n.id
            if isinstance(n, ast.Attribute):
                base = dotted(n.value)
                return None if base is None else f"{base}.{n.attr}"
            return None

        def ev(n: ast.expr) -> float:
            if isinstance(n, ast.Constant) and isinstance(n.value, (int, float)):
                return float(n.value)
            if isinstance(n, ast.BinOp) and type(n.op) in self._OPS:
                return self._OPS[type(n.op)](ev(n.left), ev(n.right))
            if isinstance(n, ast.UnaryOp) and type(n.op) in self._OPS:
                return self._OPS[type(n.op)](ev(n.operand))
            name = dotted(n)
            if name is not None:
                return self.constant(name, at)
            raise _fail(at, f"unsupported expression {text!r}")

        try:
            return ev(tree.body)
        except (ZeroDivisionError, OverflowError) as exc:
            raise _fail(at, f"cannot evaluate {text!r}: {exc}") from None


# -- the model of all files given ----------------------------------------------------------


@dataclass(eq=False)
class ServiceInfo:
    uri: str
    version: str
    name: str
    node: Node
    scope: Scope


class JsidlModel:
    """Every type set, constant set and service found in a group of JSIDL files."""

    def __init__(self, roots: Iterable[Node]) -> None:
        self.type_sets: dict[tuple[str, str], Scope] = {}
        self.const_sets: dict[tuple[str, str], Scope] = {}
        self.services: list[ServiceInfo] = []
        self._cache: dict[tuple[int, str], FieldType] = {}
        self._building: set[tuple[int, str]] = set()
        for root in roots:
            if root.tag == "declared_type_set":
                self._add_set(self.type_sets, root)
            elif root.tag == "declared_const_set":
                self._add_set(self.const_sets, root)
            elif root.tag == "service_def":
                for attr in ("id", "version"):
                    if not root.get(attr):
                        raise _fail(root, f"service_def has no {attr} attribute")
                inner = root.first("declared_type_set")
                scope = Scope.of(self, inner, label=f"service {root.get('id')}")
                self.services.append(
                    ServiceInfo(root.get("id", ""), root.get("version", ""), root.name, root, scope)
                )
            else:
                log.debug("%s: ignoring root element <%s>", root.file, root.tag)

    def _add_set(self, table: dict[tuple[str, str], Scope], root: Node) -> None:
        key = (root.get("id", ""), root.get("version", ""))
        if not key[0]:
            raise _fail(root, f"{root.tag} has no id attribute")
        if key in table:
            loaded = table[key].node
            log.debug("%s: %s %s v%s already loaded from %s", root.file, root.tag, key[0],
                      key[1], loaded.file if loaded is not None else "?")
            return
        table[key] = Scope.of(self, root, label=f"{root.tag} {key[0]} v{key[1]}")

    # -- types -------------------------------------------------------------------------

    def resolve_declared(self, node: Node, scope: Scope) -> tuple[Node, Scope]:
        """Follow ``declared_X`` to the ``X`` it names (possibly through several hops)."""
        seen = 0
        while node.tag.startswith("declared_"):
            ref = node.get("declared_type_ref")
            if not ref:
                raise _fail(node, "declared element has no declared_type_ref attribute")
            target, tscope = scope.resolve(ref, node)
            want = node.tag[len("declared_"):]
            if target.tag != want and not target.tag.startswith("declared_"):
                raise _fail(node, f"declared type {ref!r} is a <{target.tag}>, not a <{want}>")
            node, scope = target, tscope
            seen += 1
            if seen > 32:
                raise _fail(node, "declared type references loop")
        return node, scope

    def field_of(self, node: Node, scope: Scope) -> Field:
        """A :class:`Field` for a member element, named by the declaring element."""
        jsidl_name = node.name
        if not jsidl_name:
            raise _fail(node, "element has no name attribute")
        optional = (node.get("optional", "false") or "false").strip().lower() == "true"
        target, tscope = self.resolve_declared(node, scope)
        return Field(snake_case(jsidl_name), self.type_of(target, tscope), optional, jsidl_name)

    def type_of(self, node: Node, scope: Scope) -> FieldType:
        key = (id(node), node.tag)
        cached = self._cache.get(key)
        if cached is None:
            builder = _BUILDERS.get(node.tag)
            if builder is None:
                raise _fail(node, f"unknown field type <{node.tag}>")
            if key in self._building:
                raise _fail(node, "type contains itself (recursive declared type)")
            self._building.add(key)
            try:
                cached = builder(self, node, scope)
            finally:
                self._building.discard(key)
            self._cache[key] = cached
        return cached

    # -- messages ----------------------------------------------------------------------

    def message_of(self, node: Node, scope: Scope, service_set: str,
                   services: tuple[tuple[str, str], ...]) -> MessageDef:
        name = node.name
        if not name:
            raise _fail(node, "message_def has no name attribute")
        code_text = (node.get("message_id") or "").strip()
        if not code_text:
            raise _fail(node, "message_def has no message_id attribute")
        try:
            code = int(code_text, 16)
        except ValueError:
            raise _fail(node, f"message_id {code_text!r} is not hexadecimal") from None
        if not 0 <= code <= 0xFFFF:
            raise _fail(node, f"message_id {code_text!r} does not fit in 16 bits")
        for child in node.children:
            if child.tag in ("header", "declared_header"):
                self._check_header(child, scope)
            elif child.tag in ("footer", "declared_footer"):
                foot, _ = self.resolve_declared(child, scope)
                if foot.kids("record", "list", "sequence", "variant", "declared_record"):
                    raise _fail(child, "message footers with fields are not supported")
        body_node = node.first("body") or node.first("declared_body")
        body = self._body(body_node, scope, name) if body_node is not None else Record((), None,
                                                                                        name)
        doc = _first_sentence(node.first("description"))
        return MessageDef(code, name, body, service_set, services, doc)

    def _check_header(self, node: Node, scope: Scope) -> None:
        try:
            head, hscope = self.resolve_declared(node, scope)
        except ConfigError as exc:
            # The application header is always the 2-byte message ID, so a user's file
            # may leave out the core type set that declares it.
            log.debug("header not checked: %s", exc)
            return
        fields: list[Field] = []
        for child in head.children:
            if child.tag in ("record", "declared_record"):
                rec = self.field_of(child, hscope).type
                assert isinstance(rec, Record)
                fields.extend(rec.fields)
        if fields and (len(fields) != 1 or fields[0].type != u16):
            raise _fail(node, "message header must hold only the 2-byte message ID")

    def _body(self, node: Node, scope: Scope, name: str) -> Record:
        body, bscope = self.resolve_declared(node, scope)
        members = [c for c in body.children if c.tag not in ("description",)]
        if not members:
            return Record((), None, name)
        if len(members) == 1:
            only, oscope = self.resolve_declared(members[0], bscope)
            optional = (members[0].get("optional") or "false").lower() == "true"
            if only.tag in ("record", "sequence") and not optional:
                rec = self.type_of(only, oscope)
                assert isinstance(rec, Record)
                return Record(rec.fields, rec.pv, name, flattened=snake_case(only.name))
        rec = _composite(self, body, bscope)
        return Record(rec.fields, rec.pv, name)

    def message_nodes(
        self, errors: list[ConfigError] | None = None
    ) -> list[tuple[Node, Scope, tuple[tuple[str, str], ...]]]:
        """Every ``message_def`` with its scope and the ``(uri, version)`` s declaring it.

        Messages declared by services come first, in service order; messages defined in
        a type set but declared by no service follow. With ``errors``, an unresolvable
        declaration is appended there instead of raised.
        """
        declared: dict[int, list[tuple[str, str]]] = {}
        order: list[tuple[Node, Scope]] = []
        seen: set[int] = set()

        def note(msg: Node, mscope: Scope, svc: ServiceInfo | None) -> None:
            if id(msg) not in seen:
                seen.add(id(msg))
                order.append((msg, mscope))
            if svc is not None:
                pair = (svc.uri, svc.version)
                lst = declared.setdefault(id(msg), [])
                if pair not in lst:
                    lst.append(pair)

        for svc in self.services:
            mset = svc.node.first("message_set")
            if mset is None:
                continue
            for group in mset.kids("input_set", "output_set"):
                for child in group.children:
                    if child.tag == "message_def":
                        note(child, svc.scope, svc)
                    elif child.tag == "declared_message_def":
                        try:
                            msg, mscope = self.resolve_declared(child, svc.scope)
                        except ConfigError as exc:
                            if errors is None:
                                raise
                            errors.append(exc)
                            continue
                        note(msg, mscope, svc)
        for tscope in self.type_sets.values():
            for node in tscope.types.values():
                if node.tag == "message_def":
                    note(node, tscope, None)
        return [(msg, mscope, tuple(declared.get(id(msg), ()))) for msg, mscope in order]

    def messages(self, service_set: str | None = None) -> list[MessageDef]:
        """Every message defined, each with the services that declare it.

        Raises one :class:`ConfigError` listing the problems of every message that cannot
        be read, so that a user can fix them all at once.
        """
        errors: list[ConfigError] = []
        result = []
        for msg, mscope, services in self.message_nodes(errors):
            if service_set is not None:
                sset = service_set
            elif services:
                sset = services[0][0].rsplit(":", 1)[0]
            else:
                sset = mscope.node.get("id", "") if mscope.node is not None else ""
            try:
                result.append(self.message_of(msg, mscope, sset, services))
            except ConfigError as exc:
                errors.append(exc)
        if errors:
            problems = [p for exc in errors for p in exc.problems]
            raise ConfigError(list(dict.fromkeys(problems)))
        return result


def _first_sentence(node: Node | None) -> str:
    if node is None:
        return ""
    text = " ".join(node.text.split())
    match = re.match(r"(.+?[.!?])(\s|$)", text)
    sentence = match.group(1) if match else text
    return sentence if len(sentence) <= 200 else sentence[:197].rstrip() + "..."


# -- builders, one per JSIDL element -------------------------------------------------------


def _units(node: Node) -> str:
    units = " ".join((node.get("field_units") or "").split())
    return "" if units in _NO_UNITS else units


def _int_type(node: Node, attr: str, table: dict[str, Int | Float] = UNSIGNED_TYPES) -> Int:
    text = " ".join((node.get(attr) or "").split())
    if not text:
        raise _fail(node, f"missing {attr} attribute")
    t = table.get(text)
    if not isinstance(t, Int):
        raise _fail(node, f"unknown {attr} {text!r}")
    return t


def _count(node: Node, child: str = "count_field") -> tuple[Int, int | None]:
    count = node.first(child)
    if count is None:
        raise _fail(node, f"missing <{child}>")
    width = _int_type(count, "field_type_unsigned")
    max_count = count.get("max_count")
    try:
        return width, int(max_count) if max_count not in (None, "") else None
    except ValueError:
        raise _fail(count, f"max_count {max_count!r} is not an integer") from None


def _value_set(node: Node, scope: Scope) -> tuple[dict[int, str], tuple[tuple[int, int, str], ...]]:
    labels: dict[int, str] = {}
    ranges: list[tuple[int, int, str]] = []
    vs = node.first("value_set")
    if vs is None:
        return labels, ()
    for item in vs.children:
        if item.tag == "value_enum":
            try:
                labels[int(item.get("enum_index", ""))] = " ".join(
                    (item.get("enum_const") or "").split())
            except ValueError:
                raise _fail(item, f"enum_index {item.get('enum_index')!r} is not an "
                            "integer") from None
        elif item.tag == "value_range":
            lo = scope.evaluate(item.get("lower_limit", ""), item)
            hi = scope.evaluate(item.get("upper_limit", ""), item)
            if item.get("lower_limit_type") == "exclusive":
                lo += 1
            if item.get("upper_limit_type") == "exclusive":
                hi -= 1
            ranges.append((int(lo), int(hi), " ".join((item.get("interpretation") or "").split())))
    return labels, tuple(ranges)


def _fixed_field(model: JsidlModel, node: Node, scope: Scope) -> FieldType:
    text = " ".join((node.get("field_type") or "").split())
    raw = FIELD_TYPES.get(text)
    if raw is None:
        raise _fail(node, f"unknown field_type {text!r}")
    units = _units(node)
    scale = node.first("scale_range")
    if scale is not None:
        if not isinstance(raw, Int):
            raise _fail(scale, f"scale_range on a {text} field (only integers are scaled)")
        lo = scope.evaluate(scale.get("real_lower_limit", ""), scale)
        hi = scope.evaluate(scale.get("real_upper_limit", ""), scale)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise _fail(scale, f"bad scale range: upper limit {hi:g} is not above lower "
                        f"limit {lo:g}")
        return Scaled(raw, lo, hi, units)
    vs = node.first("value_set")
    if vs is not None and isinstance(raw, Int):
        labels, ranges = _value_set(node, scope)
        return Enum(raw, labels, ranges, units)
    if units and "units" in getattr(type(raw), "__dataclass_fields__", {}):
        return replace(raw, units=units)  # a plain number with units, where the DSL has them
    return raw


def _bit_field(model: JsidlModel, node: Node, scope: Scope) -> BitField:
    raw = _int_type(node, "field_type_unsigned")
    subs = []
    for sub in node.kids("sub_field"):
        rng = sub.first("bit_range")
        if rng is None:
            raise _fail(sub, "sub_field has no <bit_range>")
        try:
            lo, hi = int(rng.get("from_index", "")), int(rng.get("to_index", ""))
        except ValueError:
            raise _fail(rng, "bit_range indexes must be integers") from None
        if not 0 <= lo <= hi < raw.bits:
            raise _fail(rng, f"bad bit range {lo}..{hi} for a {raw.bits}-bit field")
        labels, _ = _value_set(sub, scope)
        subs.append(SubField(snake_case(sub.name), lo, hi, labels))
    return BitField(raw, tuple(subs))


def _var_string(model: JsidlModel, node: Node, scope: Scope) -> VarString:
    width, max_count = _count(node)
    return VarString(width, max_count)


def _fixed_string(model: JsidlModel, node: Node, scope: Scope) -> FixedString:
    try:
        length = int(node.get("string_length", ""))
    except ValueError:
        raise _fail(node, "string_length must be an integer") from None
    if length <= 0:
        raise _fail(node, f"string_length {length} must be positive")
    return FixedString(length)


def _var_field(model: JsidlModel, node: Node, scope: Scope) -> FieldType:
    width, _ = _count(node)
    fmt = " ".join((node.get("field_format") or "").split())
    if fmt.upper() == "JAUS MESSAGE":
        return JausMessage(width)
    return VarBytes(width, fmt)


def _var_format(model: JsidlModel, node: Node, scope: Scope) -> VarFormat:
    fmt = node.first("format_field")
    if fmt is None:
        raise _fail(node, "variable_format_field has no <format_field>")
    labels: dict[int, str] = {}
    for item in fmt.kids("format_enum"):
        try:
            labels[int(item.get("index", ""))] = " ".join((item.get("field_format") or "").split())
        except ValueError:
            raise _fail(item, "format_enum index must be an integer") from None
    width, _ = _count(node)
    return VarFormat(Enum(u8, labels), width)


def _variable_field(model: JsidlModel, node: Node, scope: Scope) -> Variant:
    tu = node.first("type_and_units_field")
    if tu is None:
        raise _fail(node, "variable_field has no <type_and_units_field>")
    alts, tags = [], []
    for item in tu.kids("type_and_units_enum"):
        try:
            tags.append(int(item.get("index", "")))
        except ValueError:
            raise _fail(item, "type_and_units_enum index must be an integer") from None
        alts.append(Field(snake_case(item.name), _fixed_field(model, item, scope), False,
                          item.name))
    if not alts:
        raise _fail(node, "variable_field has no type_and_units_enum")
    if len({a.name for a in alts}) != len(alts):
        # Published JSIDL leaves placeholder names ("rename_me"): name them by type.
        items = tu.kids("type_and_units_enum")
        alts = [replace(a, name=snake_case(" ".join((i.get("field_type") or "").split())))
                for a, i in zip(alts, items, strict=True)]
    _check_unique(node, [a.name for a in alts], "alternative")
    values = None if tags == list(range(len(tags))) else tuple(tags)
    return Variant(u8, tuple(alts), values, node.name)


def _check_unique(node: Node, names: list[str], what: str) -> None:
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise _fail(node, f"duplicate {what} name(s): {', '.join(dup)}")


_MEMBER_TAGS = {
    "fixed_field", "bit_field", "variable_length_string", "fixed_length_string",
    "variable_length_field", "variable_format_field", "variable_field", "record",
    "sequence", "list", "variant", "array",
}
_MEMBER_TAGS |= {f"declared_{t}" for t in _MEMBER_TAGS}


def _composite(model: JsidlModel, node: Node, scope: Scope) -> Record:
    """record, sequence or body: members in order, with an optional presence vector."""
    pv: Int | None = None
    fields: list[Field] = []
    for child in node.children:
        if child.tag == "presence_vector":
            pv = _int_type(child, "field_type_unsigned")
        elif child.tag in _MEMBER_TAGS:
            fields.append(model.field_of(child, scope))
        elif child.tag not in ("description",):
            raise _fail(child, f"unknown field type <{child.tag}> in <{node.tag}>")
    n_opt = sum(f.optional for f in fields)
    if n_opt and pv is None:
        raise _fail(node, f"{n_opt} optional member(s) but no presence_vector")
    if pv is not None and n_opt > pv.bits:
        raise _fail(node, f"{n_opt} optional members do not fit a {pv.bits}-bit presence vector")
    _check_unique(node, [f.name for f in fields], "member")
    return Record(tuple(fields), pv, node.name)


def _single(model: JsidlModel, node: Node, scope: Scope) -> FieldType:
    members = [c for c in node.children if c.tag in _MEMBER_TAGS]
    if len(members) != 1:
        raise _fail(node, f"<{node.tag}> must hold exactly one element type, "
                    f"found {len(members)}")
    target, tscope = model.resolve_declared(members[0], scope)
    return model.type_of(target, tscope)


def _list(model: JsidlModel, node: Node, scope: Scope) -> List:
    width, _ = _count(node)
    return List(width, _single(model, node, scope), node.name)


def _variant(model: JsidlModel, node: Node, scope: Scope) -> FieldType:
    tag = node.first("vtag_field")
    if tag is None:
        raise _fail(node, "variant has no <vtag_field>")
    width = _int_type(tag, "field_type_unsigned")
    alts = [model.field_of(c, scope) for c in node.children if c.tag in _MEMBER_TAGS]
    if not alts:
        # Only the tag travels (e.g. NoGeometricPropertiesVariant in AS6060).
        return width
    try:
        start = int(tag.get("min_count") or 0)
    except ValueError:
        raise _fail(tag, "vtag_field min_count must be an integer") from None
    _check_unique(node, [a.name for a in alts], "alternative")
    values = tuple(range(start, start + len(alts))) if start else None
    return Variant(width, tuple(alts), values, node.name)


def _array(model: JsidlModel, node: Node, scope: Scope) -> Record:
    dims = []
    for dim in node.kids("dimension"):
        try:
            size = int(dim.get("size", ""))
        except ValueError:
            raise _fail(dim, "dimension size must be an integer") from None
        if size <= 0:
            raise _fail(dim, f"dimension size {size} must be positive")
        dims.append(size)
    if not dims:
        raise _fail(node, "array has no <dimension>")
    members = [c for c in node.children if c.tag in _MEMBER_TAGS]
    if len(members) != 1:
        raise _fail(node, "array must hold exactly one element type")
    elem_node, escope = model.resolve_declared(members[0], scope)
    element = model.type_of(elem_node, escope)
    base = snake_case(members[0].name or "element")

    def build(level: int, prefix: str) -> Record:
        fields = []
        for i in range(dims[level]):
            name = f"{prefix}_{i}"
            inner: FieldType = element if level == len(dims) - 1 else build(level + 1, name)
            fields.append(Field(name, inner, False, members[0].name))
        return Record(tuple(fields), None, node.name)

    return build(0, base)


_BUILDERS = {
    "fixed_field": _fixed_field,
    "bit_field": _bit_field,
    "variable_length_string": _var_string,
    "fixed_length_string": _fixed_string,
    "variable_length_field": _var_field,
    "variable_format_field": _var_format,
    "variable_field": _variable_field,
    "record": _composite,
    "sequence": _composite,
    "list": _list,
    "variant": _variant,
    "array": _array,
}


# -- public entry points --------------------------------------------------------------------


def _expand(paths: str | Path | Iterable[str | Path]) -> list[Path]:
    if isinstance(paths, (str, Path)):
        paths = [paths]
    files: list[Path] = []
    for p in paths:
        path = Path(p)
        if path.is_dir():
            found = sorted(q for q in path.rglob("*") if q.suffix.lower() in (".xml", ".jsidl"))
            if not found:
                raise ConfigError([(str(path), "", "directory holds no JSIDL .xml files")])
            files.extend(found)
        elif path.exists():
            files.append(path)
        else:
            raise ConfigError([(str(path), "", "no such JSIDL file or directory")])
    return files


def parse_files(paths: str | Path | Iterable[str | Path]) -> JsidlModel:
    """Parse JSIDL files (directories are searched for ``*.xml``) into a model."""
    return JsidlModel(parse_xml(p) for p in _expand(paths))


def load_jsidl(
    paths: str | Path | Iterable[str | Path], *, service_set: str | None = None
) -> list[MessageDef]:
    """Every message defined in the JSIDL ``paths`` (files or directories).

    ``service_set`` names the set in each :class:`MessageDef`; by default it is the
    declaring service URI without its last part (``urn:jaus:jss:mobility``).
    Raises :class:`ConfigError` naming file, element and problem for malformed input.
    """
    return parse_files(paths).messages(service_set)


def profile_catalogue(jsidl: Iterable[str | Path], *, base: Catalogue | None = None,
                      source: str = "profile JSIDL") -> Catalogue:
    """The relay's catalogue: ``base`` (default: the default one) plus the messages of a
    profile's ``catalogue.jsidl`` files (``base`` itself when there are none).

    One function for ``edge-vis run``, ``edge-vis check`` and the simulator's vehicles, so
    all see the same messages; ``source`` names the files in error messages. Raises
    ConfigError naming a file that does not parse, PluginConflictError for a code already
    taken by another definition.
    """
    from edge_vis.catalogue import default_catalogue

    catalogue = base if base is not None else default_catalogue()
    files = list(jsidl)
    if not files:
        return catalogue
    extended = catalogue.copy()
    extended.add(load_jsidl(files), source=source)
    return extended
