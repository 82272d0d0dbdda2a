#!/usr/bin/env python3
"""Write edge-vis's built-in message modules from the public JSIDL service definitions.

Usage::

    .venv/bin/python tools/gen_messages.py [JAUS_REFERENCE_DIR]

``JAUS_REFERENCE_DIR`` holds ``jsidl/`` (the JAUS Toolset set) and ``jsidl-iop/`` (the
Army IOP set); it defaults to ``../shared/jaus`` beside the repository root. The script
parses them with :mod:`edge_vis.catalogue.jsidl` and writes readable Python modules to
``edge_vis/jaus/messages/``, one per service set, then runs ``ruff format`` and
``ruff check --fix`` on them. The product never reads the JSIDL at run time: the generated
modules are committed.

One catalogue is keyed by message code, so each code appears once across all sets:

* the JAUS Toolset (SAE) reading wins where the IOP set differs, and the difference is
  written into the module docstring;
* a message of another version with the same code and the same layout only adds its
  service to ``services``; one with a different layout is left out and listed in
  ``edge_vis/jaus/messages/__init__.py``.

File I/O only (reads JSIDL, writes modules); no network.
"""

from __future__ import annotations

import argparse
import logging
import math
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from edge_vis.catalogue.jsidl import JsidlModel, parse_files  # noqa: E402
from edge_vis.codec.layout import wire_signature  # noqa: E402
from edge_vis.codec.types import (  # noqa: E402
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
    snake_case,
)
from edge_vis.errors import ConfigError  # noqa: E402

log = logging.getLogger("gen_messages")

OUT = REPO / "edge_vis" / "jaus" / "messages"


@dataclass
class SetSpec:
    """One generated module: where its JSIDL lives and which sources win."""

    module: str
    title: str
    #: (label, directories loaded together; the first holds this set's own messages)
    primary: tuple[str, tuple[str, ...]]
    #: other readings of the same set: same code + same layout adds services, else a diff
    others: tuple[tuple[str, tuple[str, ...]], ...] = ()
    notes: list[str] = field(default_factory=list)
    #: code -> name of the message to keep when one reading gives a code twice
    prefer: dict[int, str] = field(default_factory=dict)
    #: reading label -> the dialect its different definitions form (see :class:`DialectSpec`)
    dialects: dict[str, DialectSpec] = field(default_factory=dict)


@dataclass(frozen=True)
class DialectSpec:
    """A reading whose definitions of shared codes are kept as a dialect of the set:
    ``name``, the ``(URI prefix, version prefix)`` pairs that recognise a vehicle speaking
    it, and a line saying what it is."""

    name: str
    recognise: tuple[tuple[str, str], ...]
    doc: str


MANIPULATOR_V1 = DialectSpec(
    "manipulator-1.0", (("urn:jaus:jss:manipulator:", "1."),),
    "manipulator v1.0: plural names, motion profiles and specifications as v1.0 defines them")
IOP = DialectSpec(
    "iop", (("urn:jaus:jss:iop:", ""),),
    "the Army IOP readings of SAE messages (optional speed and acceleration, stabilizer "
    "reports)")


SETS = [
    SetSpec(
        "core", "JAUS Core Service Set (SAE AS5710A), version 1.1 and 1.0",
        ("JTS core v1.1", ("jsidl/urn.jaus.jss.core-v1.1",)),
        (
            ("JTS core v1.0", ("jsidl/urn.jaus.jss.core-v1.0",)),
            ("IOP core v1.1", ("jsidl-iop/urn.jaus.jss.core-v1.1",)),
            ("IOP core v1.0", ("jsidl-iop/urn.jaus.jss.core-v1.0",)),
        ),
    ),
    SetSpec(
        "mobility", "JAUS Mobility Service Set (SAE AS6009), version 1.0",
        ("JTS mobility v1.0", ("jsidl/urn.jaus.jss.mobility",)),
        (("IOP mobility v1.0", ("jsidl-iop/urn.jaus.jss.mobility",)),),
        dialects={"IOP mobility v1.0": IOP},
    ),
    SetSpec(
        "environment", "JAUS Environment Sensing Service Set (SAE AS6060), version 1.0",
        ("JTS environmentSensing v1.0", ("jsidl/urn.jaus.jss.environmentSensing",)),
        (("IOP environmentSensing v1.0", ("jsidl-iop/urn.jaus.jss.environmentSensing",)),),
    ),
    SetSpec(
        "manipulator", "JAUS Manipulator Service Set (SAE AS6057), version 2.0 and 1.0",
        ("JTS manipulator v2.0", ("jsidl/urn.jaus.jss.manipulator-v2.0",)),
        (
            ("JTS manipulator v1.0", ("jsidl/urn.jaus.jss.manipulator-v1.0",)),
            ("IOP manipulator v2.0", ("jsidl-iop/urn.jaus.jss.manipulator-v2.0",
                                      "jsidl-iop/urn.jaus.jss.core-v1.1")),
            ("IOP manipulator (older copy)", ("jsidl-iop/urn.jaus.jss.manipulator",)),
        ),
        dialects={"JTS manipulator v1.0": MANIPULATOR_V1,
                  "IOP manipulator (older copy)": MANIPULATOR_V1},
    ),
    SetSpec(
        "ugv", "JAUS Unmanned Ground Vehicle Service Set (SAE AS6091), version 1.0",
        ("JTS ugv v1.0", ("jsidl/urn.jaus.jss.ugv",)),
        (("IOP ugv v1.0", ("jsidl-iop/urn.jaus.jss.ugv",)),),
        dialects={"IOP ugv v1.0": IOP},
    ),
    SetSpec(
        "iop", "Army IOP public services (urn:jaus:jss:iop)",
        ("IOP services", ("jsidl-iop/urn.jaus.jss.iop", "jsidl-iop/urn.jaus.jss.core-v1.1",
                          "jsidl-iop/urn.jaus.jss.mobility")),
        # MeasurementSensor's query pairs with ReportMeasurement 0xF92B; the CBRN sensor
        # reuses 0xF92A for a scan-window command.
        prefer={0xF92A: "QueryMeasurement"},
    ),
    SetSpec(
        "hmi", "JAUS Human-Machine Interface services (urn:jaus:jss:HMI)",
        ("JTS HMI v1.0", ("jsidl/urn.jaus.jss.hmi", "jsidl/urn.jaus.jss.core-v1.1")),
    ),
    SetSpec(
        "mission_spooler", "JAUS Mission Spooler service (urn:jaus:jss:missionSpooler)",
        ("JTS missionSpooler", ("jsidl/urn.jaus.jss.missionSpooler",
                                "jsidl/urn.jaus.jss.core-v1.1")),
    ),
]


# -- loading -------------------------------------------------------------------------------


def load(root: Path, dirs: tuple[str, ...], module: str) -> tuple[list[MessageDef], list[str]]:
    """The messages of one reading whose defining file lies in ``dirs[0]``.

    Returns the messages and the problems of those that could not be read (a defect in
    one message of the public JSIDL must not cost the whole set).
    """
    own = (root / dirs[0]).resolve()
    model: JsidlModel = parse_files([root / d for d in dirs])
    errors: list[ConfigError] = []
    out = []
    for node, scope, services in model.message_nodes(errors):
        if not Path(node.file).resolve().is_relative_to(own):
            continue
        try:
            out.append(model.message_of(node, scope, module, services))
        except ConfigError as exc:
            code = node.get("message_id", "????")
            errors.append(ConfigError([(f, f"message {node.name} 0x{code}: {w}", m)
                                       for f, w, m in exc.problems]))
    problems = []
    for exc in errors:
        for file, where, problem in exc.problems:
            rel = Path(file).resolve().relative_to(root) if file else ""
            problems.append(f"{rel}: {where}: {problem}")
    return out, problems


# -- comparing two readings of a message ---------------------------------------------------


def diff(a: object, b: object, path: str = "") -> str | None:
    """A short description of the first wire-relevant difference, or None if equal."""
    if type(a) is not type(b):
        return f"{path or 'body'}: {_kind(a)} vs {_kind(b)}"
    if isinstance(a, Field) and isinstance(b, Field):
        here = f"{path}.{a.name}" if path else a.name
        if a.name != b.name:
            return f"{path or 'body'}: field {a.jsidl_name} vs {b.jsidl_name}"
        if a.optional != b.optional:
            word = lambda f: "optional" if f.optional else "mandatory"  # noqa: E731
            return f"{here}: {word(a)} vs {word(b)}"
        return diff(a.type, b.type, here)
    if isinstance(a, (Record, List, Variant)):
        if isinstance(a, Record) and isinstance(b, Record):
            if a.pv != b.pv:
                return f"{path or 'body'}: presence vector {_kind(a.pv)} vs {_kind(b.pv)}"
            names_a = [f.name for f in a.fields]
            names_b = [f.name for f in b.fields]
            if names_a != names_b:
                return f"{path or 'body'}: fields {names_a} vs {names_b}"
            for fa, fb in zip(a.fields, b.fields, strict=True):
                d = diff(fa, fb, path)
                if d:
                    return d
            return None
        if isinstance(a, List) and isinstance(b, List):
            if a.count != b.count:
                return f"{path}: list count {_kind(a.count)} vs {_kind(b.count)}"
            return diff(a.element, b.element, f"{path}[]")
        if isinstance(a, Variant) and isinstance(b, Variant):
            if a.tag != b.tag or len(a.alternatives) != len(b.alternatives):
                return f"{path}: variant tag/alternatives differ"
            for fa, fb in zip(a.alternatives, b.alternatives, strict=True):
                d = diff(fa, fb, path)
                if d:
                    return d
            return None
    if isinstance(a, Enum) and isinstance(b, Enum):
        if a.raw != b.raw or a.units != b.units:
            return f"{path}: {_kind(a)} vs {_kind(b)}"
        return None  # labels are display only
    if isinstance(a, BitField) and isinstance(b, BitField):
        ra = [(s.name, s.lo, s.hi) for s in a.subfields]
        rb = [(s.name, s.lo, s.hi) for s in b.subfields]
        return None if (a.raw, ra) == (b.raw, rb) else f"{path}: bit fields differ"
    if isinstance(a, Scaled) and isinstance(b, Scaled):
        same = (a.raw == b.raw and math.isclose(a.lower, b.lower, rel_tol=1e-9, abs_tol=1e-12)
                and math.isclose(a.upper, b.upper, rel_tol=1e-9, abs_tol=1e-12)
                and a.units == b.units)
        return None if same else f"{path}: {_kind(a)} vs {_kind(b)}"
    if isinstance(a, VarString) and isinstance(b, VarString):
        return None if a.count == b.count else f"{path}: {_kind(a)} vs {_kind(b)}"
    if isinstance(a, VarFormat) and isinstance(b, VarFormat):
        return None if (a.count, a.format.raw) == (b.count, b.format.raw) else (
            f"{path}: {_kind(a)} vs {_kind(b)}")
    return None if a == b else f"{path}: {_kind(a)} vs {_kind(b)}"


def _kind(t: object) -> str:
    if t is None:
        return "none"
    if isinstance(t, Int):
        return f"{'i' if t.signed else 'u'}{t.bits}"
    if isinstance(t, Float):
        return f"f{t.bits}"
    if isinstance(t, Scaled):
        units = f" {t.units}" if t.units else ""
        return f"{_kind(t.raw)}[{t.lower:g}..{t.upper:g}]{units}"
    if isinstance(t, (Enum,)):
        return f"enum {_kind(t.raw)}"
    if isinstance(t, (VarString, VarBytes, JausMessage)):
        return f"{type(t).__name__}(count {_kind(t.count)})"
    return type(t).__name__


def message_diff(a: MessageDef, b: MessageDef) -> str | None:
    """The first difference in layout or field names (message names aside)."""
    return diff(a.body, b.body)


# -- choosing the catalogue ----------------------------------------------------------------


@dataclass
class Chosen:
    spec: SetSpec
    messages: dict[int, MessageDef] = field(default_factory=dict)
    #: (code, kept name, other reading label, other name, difference)
    differences: list[tuple[int, str, str, str, str]] = field(default_factory=list)
    #: dialect name -> its spec, its definitions by code and its further names
    dialects: dict[str, DialectSpec] = field(default_factory=dict)
    variants: dict[str, dict[int, MessageDef]] = field(default_factory=dict)
    aliases: dict[str, dict[str, int]] = field(default_factory=dict)
    #: dialect name -> the reading that defines it first (later ones add names only)
    first: dict[str, str] = field(default_factory=dict)

    def offer_variant(self, dialect: DialectSpec, label: str, kept: MessageDef,
                      msg: MessageDef, same_layout: bool) -> str | None:
        """Keep ``msg`` (a reading of ``dialect``) beside ``kept``; None when it is kept
        (as a definition of the dialect or another name of one), else why not."""
        self.dialects.setdefault(dialect.name, dialect)
        first = self.first.setdefault(dialect.name, label) == label
        variants = self.variants.setdefault(dialect.name, {})
        aliases = self.aliases.setdefault(dialect.name, {})
        earlier = variants.get(msg.code)
        if earlier is None:
            if same_layout and not first:
                aliases.setdefault(msg.name, msg.code)
            elif same_layout or first:
                variants[msg.code] = msg
            else:
                return f"{dialect.name} defines it as {kept.name}"
            return None
        if message_diff(earlier, msg) is not None and \
                wire_signature(earlier.body) != wire_signature(msg.body):
            return f"{dialect.name} already defines it as {earlier.name}"
        # the same bytes, the same decoded keys: one reading whatever its labels say
        if msg.name != earlier.name and msg.name != kept.name:
            aliases.setdefault(msg.name, msg.code)
        return None


@dataclass
class LeftOut:
    code: int
    name: str
    reading: str
    reason: str


def build(root: Path) -> tuple[list[Chosen], list[LeftOut], list[tuple[str, str]]]:
    """Choose one definition per code; also return the JSIDL defects met on the way."""
    defects: list[tuple[str, str]] = []
    owner: dict[int, Chosen] = {}
    chosen: list[Chosen] = []
    left: list[LeftOut] = []

    def offer(this: Chosen, msg: MessageDef, label: str) -> None:
        holder = owner.get(msg.code)
        if holder is None:
            owner[msg.code] = this
            this.messages[msg.code] = msg
            return
        kept = holder.messages[msg.code]
        if this.spec.prefer.get(msg.code) == msg.name and holder is this:
            holder.messages[msg.code] = msg
            left.append(LeftOut(kept.code, kept.name, label,
                                f"same code as {msg.name}, which is kept (chosen deliberately)"))
            this.differences.append((msg.code, msg.name, label, kept.name,
                                     "another message with this code, left out"))
            return
        d = message_diff(kept, msg)
        dialect = this.spec.dialects.get(label) if holder is this else None
        if d is None:
            holder.messages[msg.code] = _merge(kept, msg)
            if kept.name != msg.name:
                if dialect is not None:
                    this.offer_variant(dialect, label, kept, msg, same_layout=True)
                holder.differences.append((msg.code, kept.name, label, msg.name,
                                           "same layout under another name"))
            return
        why = None if dialect is None else this.offer_variant(dialect, label, kept, msg, False)
        if dialect is not None and why is None:
            earlier = this.variants[dialect.name].get(msg.code)
            same = "" if earlier is None or earlier is msg else message_diff(earlier, msg)
            note = (f"; read with {dialect.name}'s definition, the same on the wire (only "
                    f"labels differ: {same})") if same else ""
            holder.differences.append((msg.code, kept.name, label, msg.name,
                                       f"{d}; dialect {dialect.name}{note}"))
            return
        if why is not None:
            earlier = this.variants[dialect.name][msg.code] if dialect else kept
            d = f"{why}: {message_diff(earlier, msg)}"
        where = "the kept " if holder is this else f"{holder.spec.module}."
        named = f"; named {msg.name}" if msg.name != kept.name else ""
        left.append(LeftOut(msg.code, msg.name, label,
                            f"code taken by {where}{kept.name} ({d}{named})"))
        holder.differences.append((msg.code, kept.name, label, msg.name, d))

    for spec in SETS:
        label, dirs = spec.primary
        try:
            primary, problems = load(root, dirs, spec.module)
        except ConfigError as exc:
            log.error("%s: skipped: %s", label, exc)
            continue
        defects.extend((label, p) for p in problems)
        this = Chosen(spec)
        chosen.append(this)
        by_code = {m.code: m for m in primary}
        for msg in primary:
            if not msg.services:
                query = by_code.get(msg.code | 0x2000)
                if query is not None and query.services and msg.code < 0x2000:
                    msg = replace(msg, services=query.services,
                                  doc="declared by no service; sent as a list element")
            offer(this, msg, label)
        for olabel, odirs in spec.others:
            try:
                other, problems = load(root, odirs, spec.module)
            except ConfigError as exc:
                log.error("%s: skipped: %s", olabel, exc)
                continue
            defects.extend((olabel, p) for p in problems)
            for msg in other:
                offer(this, msg, olabel)
    everything = {code: m for c in chosen for code, m in c.messages.items()}
    for c in chosen:
        for code, m in c.messages.items():
            c.messages[code] = replace(m, doc=describe(m, everything))
    return chosen, left, defects


def describe(m: MessageDef, everything: dict[int, MessageDef]) -> str:
    """Our own one-line summary: kind, declaring service, and the matching query/report."""
    kind = {0: "Command", 1: "Query", 2: "Report"}.get(m.code >> 13, "Message")
    if m.services:
        uri, version = m.services[0]
        where = f" of {uri.rsplit(':', 1)[-1]} {version}"
    else:
        where = ""
    pair = ""
    if kind == "Query":
        report = everything.get((m.code & 0x1FFF) | 0x4000)
        if report is not None:
            pair = f"; answered by {report.name} (0x{report.code:04X})"
    elif kind == "Report":
        query = everything.get((m.code & 0x1FFF) | 0x2000)
        if query is not None:
            pair = f"; answers {query.name} (0x{query.code:04X})"
    note = f" ({m.doc})" if m.doc.startswith("declared by no service") else ""
    return f"{kind}{where}{pair}{note}."


def _merge(kept: MessageDef, other: MessageDef) -> MessageDef:
    services = list(kept.services)
    for pair in other.services:
        if pair not in services:
            services.append(pair)
    return replace(kept, services=tuple(services))


# -- writing Python ------------------------------------------------------------------------

_INT_NAMES = {(8, False): "u8", (16, False): "u16", (32, False): "u32", (64, False): "u64",
              (8, True): "i8", (16, True): "i16", (32, True): "i32", (64, True): "i64"}


def num(x: float) -> str:
    """A float literal, with multiples of pi written as such."""
    if x != 0:
        frac = Fraction(x / math.pi).limit_denominator(8)
        if frac != 0 and math.isclose(float(frac) * math.pi, x, rel_tol=1e-12):
            n, d = frac.numerator, frac.denominator
            text = "PI" if abs(n) == 1 else f"{abs(n)} * PI"
            if d != 1:
                text += f" / {d}"
            return f"-{text}" if n < 0 else text
    if x == int(x) and abs(x) < 1e15:
        return f"{int(x)}"
    return repr(x)


_ASCII = str.maketrans({"\u2019": "'", "\u2018": "'", "\u201c": '"', "\u201d": '"',
                        "\u2013": "-", "\u2014": "-", "\u00b0": " deg", "\u00b2": "^2"})


def ascii_text(text: str) -> str:
    """Documentation text in plain ASCII (the JSIDL uses typographic quotes)."""
    text = text.translate(_ASCII)
    return text.encode("ascii", "replace").decode("ascii")


def uses_pi(text: str) -> bool:
    return re.search(r"\bPI\b", text) is not None


class Writer:
    """Turns field-type trees into DSL source, hoisting repeated composites to constants."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self.consts: dict[str, str] = {}  # full text -> constant name
        self.defs: list[tuple[str, str]] = []
        self.names: set[str] = {"SET", "PI", "MESSAGES", "math"}
        self.used: set[str] = set()

    def plain(self, t: FieldType) -> str:
        return self._text(t, hoist=False)

    def count(self, t: FieldType) -> None:
        if isinstance(t, (BitField, Record, List, Variant, VarFormat)) or (
            isinstance(t, Enum) and len(t.labels) > 3
        ):
            key = self.plain(t)
            self.counts[key] = self.counts.get(key, 0) + 1
            if self.counts[key] > 1:
                return
        for child in _children(t):
            self.count(child)

    def render(self, t: FieldType, hint: str = "") -> str:
        text = self._text(t, hoist=True, hint=hint)
        key = self.plain(t)
        if self.counts.get(key, 0) > 1 and len(key) > 40:
            name = self.consts.get(key)
            if name is None:
                name = self._name(getattr(t, "name", "") or hint or type(t).__name__)
                self.consts[key] = name
                self.defs.append((name, text))
            return name
        return text

    def _name(self, hint: str) -> str:
        base = snake_case(hint).upper() or "TYPE"
        if base[0].isdigit():
            base = "T_" + base
        name, i = base, 2
        while name in self.names:
            name, i = f"{base}_{i}", i + 1
        self.names.add(name)
        return name

    def _sub(self, t: FieldType, hoist: bool, hint: str = "") -> str:
        return self.render(t, hint) if hoist else self.plain(t)

    def _text(self, t: FieldType, hoist: bool, hint: str = "") -> str:
        use = self.used.add
        units = getattr(t, "units", "") if isinstance(t, (Int, Float)) else ""
        if isinstance(t, Int) and units:
            use("Int")
            signed = ", signed=True" if t.signed else ""
            return f"Int({t.bits}{signed}, units={units!r})"
        if isinstance(t, Float) and units:
            use("Float")
            return f"Float({t.bits}, units={units!r})"
        if isinstance(t, Int):
            name = _INT_NAMES[(t.bits, t.signed)]
            use(name)
            return name
        if isinstance(t, Float):
            name = "f32" if t.bits == 32 else "f64"
            use(name)
            return name
        if isinstance(t, Scaled):
            use("Scaled")
            units = f", {t.units!r}" if t.units else ""
            return f"Scaled({self._text(t.raw, hoist)}, {num(t.lower)}, {num(t.upper)}{units})"
        if isinstance(t, Enum):
            use("Enum")
            args = [self._text(t.raw, hoist)]
            if t.labels:
                args.append("{" + ", ".join(f"{k}: {v!r}" for k, v in t.labels.items()) + "}")
            if t.ranges:
                args.append("ranges=(" + "".join(f"({lo}, {hi}, {lab!r}), "
                                                 for lo, hi, lab in t.ranges).rstrip(", ")
                            + ("," if len(t.ranges) == 1 else "") + ")")
            if t.units:
                args.append(f"units={t.units!r}")
            return f"Enum({', '.join(args)})"
        if isinstance(t, BitField):
            use("BitField")
            use("SubField")
            subs = []
            for s in t.subfields:
                labels = ""
                if s.labels:
                    labels = ", {" + ", ".join(f"{k}: {v!r}" for k, v in s.labels.items()) + "}"
                subs.append(f"SubField({s.name!r}, {s.lo}, {s.hi}{labels})")
            tail = "," if len(subs) == 1 else ""
            return f"BitField({self._text(t.raw, hoist)}, ({', '.join(subs)}{tail}))"
        if isinstance(t, FixedString):
            use("FixedString")
            return f"FixedString({t.length})"
        if isinstance(t, FixedBytes):
            use("FixedBytes")
            return f"FixedBytes({t.length})"
        if isinstance(t, VarString):
            use("VarString")
            extra = f", {t.max_length}" if t.max_length is not None else ""
            return f"VarString({self._text(t.count, hoist)}{extra})"
        if isinstance(t, VarBytes):
            use("VarBytes")
            fmt = f", {t.format!r}" if t.format else ""
            return f"VarBytes({self._text(t.count, hoist)}{fmt})"
        if isinstance(t, JausMessage):
            use("JausMessage")
            return f"JausMessage({self._text(t.count, hoist)})"
        if isinstance(t, VarFormat):
            use("VarFormat")
            return f"VarFormat({self._sub(t.format, hoist)}, {self._text(t.count, hoist)})"
        if isinstance(t, Record):
            use("record")
            args = [self.field(f, hoist) for f in t.fields]
            if t.pv is not None:
                args.append(f"pv={self._text(t.pv, hoist)}")
            if t.name:
                args.append(f"name={t.name!r}")
            return f"record({', '.join(args)})"
        if isinstance(t, List):
            use("List")
            name = f", {t.name!r}" if t.name else ""
            elem = self._sub(t.element, hoist, t.name + "Element" if t.name else "")
            return f"List({self._text(t.count, hoist)}, {elem}{name})"
        if isinstance(t, Variant):
            use("Variant")
            alts = [self.field(f, hoist) for f in t.alternatives]
            tail = "," if len(alts) == 1 else ""
            args = [self._text(t.tag, hoist), f"({', '.join(alts)}{tail})"]
            if t.tag_values is not None:
                vals = ", ".join(str(v) for v in t.tag_values)
                args.append(f"tag_values=({vals}{',' if len(t.tag_values) == 1 else ''})")
            if t.name:
                args.append(f"name={t.name!r}")
            return f"Variant({', '.join(args)})"
        raise TypeError(f"cannot write {t!r}")

    def field(self, fld: Field, hoist: bool = True) -> str:
        ctor = "opt" if fld.optional else "f"
        self.used.add(ctor)
        type_text = self._sub(fld.type, hoist, fld.jsidl_name)
        return f"{ctor}({fld.name!r}, {type_text}, jsidl={fld.jsidl_name!r})"


def _children(t: FieldType) -> list[FieldType]:
    if isinstance(t, Record):
        return [f.type for f in t.fields]
    if isinstance(t, Variant):
        return [f.type for f in t.alternatives]
    if isinstance(t, List):
        return [t.element]
    if isinstance(t, VarFormat):
        return [t.format]
    return []


def _entries(w: Writer, msgs: list[MessageDef], indent: str = "    ") -> list[str]:
    entries = []
    for m in msgs:
        svc = " ".join(m.services[0]) if m.services else "declared by no service"
        if len(m.services) > 1:
            svc += f" (+{len(m.services) - 1} more)"
        args = [f"0x{m.code:04X}", repr(m.name)]
        args += [w.field(fld) for fld in m.body.fields]
        if m.body.pv is not None:
            args.append(f"pv={w._text(m.body.pv, True)}")
        args.append("service_set=SET")
        services = ", ".join(f"({u!r}, {v!r})" for u, v in m.services)
        if len(m.services) == 1:
            services += ","
        args.append(f"services=({services})")
        if m.doc:
            args.append(f"doc={ascii_text(m.doc)!r}")
        entries.append(f"{indent}# {svc}\n{indent}message({', '.join(args)}),\n")
    return entries


def write_module(chosen: Chosen, sources: str) -> str:
    spec = chosen.spec
    msgs = sorted(chosen.messages.values(), key=lambda m: (m.services[:1], m.code))
    variants = {name: sorted(defs.values(), key=lambda m: m.code)
                for name, defs in sorted(chosen.variants.items()) if defs}
    w = Writer()
    for m in [*msgs, *(v for defs in variants.values() for v in defs)]:
        for fld in m.body.fields:
            w.count(fld.type)
    entries = _entries(w, msgs)
    dialect_text = ""
    for name, defs in variants.items():
        d = chosen.dialects[name]
        aliases = "".join(f"({n!r}, 0x{c:04X}), "
                          for n, c in sorted(chosen.aliases.get(name, {}).items()))
        recognise = "".join(f"({u!r}, {v!r}), " for u, v in d.recognise)
        dialect_text += (f"    Dialect(\n        {name!r},\n        messages=(\n"
                         + "".join(_entries(w, defs, " " * 12))
                         + f"        ),\n        aliases=({aliases}),\n"
                         f"        recognise=({recognise}),\n        doc={d.doc!r},\n    ),\n")
    if dialect_text:
        w.used.add("Dialect")
    w.used.add("message")
    w.used.add("MessageDef")
    defs = "".join(f"{name} = {text}\n" for name, text in w.defs)
    body_text = defs + "".join(entries) + dialect_text
    pi = "\nimport math\n" if uses_pi(body_text) else ""
    imports = ", ".join(sorted(w.used, key=lambda s: (s[0].islower(), s)))
    doc = module_doc(chosen, sources, len(msgs))
    out = [f'"""{doc}"""\n\nfrom __future__ import annotations\n{pi}\n']
    out.append(f"from edge_vis.codec.types import {imports}\n\n")
    out.append(f'SET = "{spec.module}"\n')
    if pi:
        out.append("PI = math.pi\n")
    out.append("\n# Types used by several messages\n" if defs else "\n")
    out.append(defs)
    out.append(f"\nMESSAGES: tuple[MessageDef, ...] = (\n{''.join(entries)})\n")
    if dialect_text:
        out.append("\n# Other definitions of codes above, for vehicles that speak them\n"
                   f"DIALECTS: tuple[Dialect, ...] = (\n{dialect_text})\n")
    return "".join(out)


def module_doc(chosen: Chosen, sources: str, n: int) -> str:
    spec = chosen.spec
    lines = [
        f"Built-in messages: {spec.title}. No I/O.",
        "",
        f"{n} message definitions.",
        "Generated by ``tools/gen_messages.py`` from the public JSIDL service definitions",
        f"({sources}); edit the generator, not this file.",
        f"Layouts follow the {spec.primary[0]} reading.",
    ]
    others = ", ".join(label for label, _ in spec.others)
    if others:
        lines.append(f"Also compared with: {others}; a message they share with the same layout "
                     "lists their services too.")
    if chosen.differences:
        lines += ["", "Differences between readings (the kept definition is named first):", ""]
        for code, kept, label, other, d in sorted(chosen.differences):
            name = kept if kept == other else f"{kept} / {other}"
            lines.append(f"* 0x{code:04X} {name} ({label}): {d}")
    lines += spec.notes
    return "\n".join(_wrap(x) for x in lines) + "\n"


def _wrap(line: str, width: int = 96) -> str:
    if len(line) <= width:
        return line
    indent = "  " if line.startswith("* ") else ""
    words, out, cur = line.split(" "), [], ""
    for word in words:
        if cur and len(cur) + 1 + len(word) > width:
            out.append(cur)
            cur = indent + word
        else:
            cur = f"{cur} {word}" if cur else word
    out.append(cur)
    return "\n".join(out)


def write_init(chosen: list[Chosen], left: list[LeftOut], defects: list[tuple[str, str]]) -> str:
    names = [c.spec.module for c in chosen]
    total = sum(len(c.messages) for c in chosen)
    lines = [
        "Built-in JAUS message definitions, one module per service set. No I/O.",
        "",
        "Each module exports ``MESSAGES: tuple[MessageDef, ...]``; the modules are generated by",
        "``tools/gen_messages.py`` from the public JSIDL and committed, so nothing is read at",
        f"run time. {total} messages in all: "
        + ", ".join(f"{c.spec.module} {len(c.messages)}" for c in chosen) + ".",
        "",
        "A catalogue is keyed by message code. Where another published reading defines a",
        "code differently (manipulator v1.0, the IOP readings of mobility and UGV messages),",
        "its definitions are kept as a *dialect* (``DIALECTS`` of the set's module): a",
        "vehicle that speaks it (its profile's ``dialects``, or the services it reports)",
        "has those codes decoded and encoded with the dialect's definitions. Other",
        "definitions that reuse a code are left out (listed below); load the JSIDL of that",
        "version (``edge_vis.catalogue.jsidl.load_jsidl``) to talk to a peer that uses one.",
        "",
        "Versions kept: core 1.1 (every core 1.0 message has the same layout and lists the",
        "1.0 services too), mobility 1.0, environmentSensing 1.0, manipulator 2.0, ugv 1.0, the",
        "IOP services as published by FKIE, HMI 1.0 and the mission spooler. Manipulator 1.0",
        "has no code of its own: its messages match 2.0 under a plural name (their services",
        "are listed on the 2.0 definition too) or differ (its dialect). Mobility 1.1 and",
        "environmentSensing 2.0 are not in the public JSIDL these modules come from.",
        "",
        "Representation choices: a JSIDL ``array`` (fixed dimensions, no count on the wire)",
        "is a record of ``<element>_<i>`` fields; a variant with no alternatives",
        "(``NoGeometricPropertiesVariant``) is its tag alone; a ``variable_field`` is a",
        "variant whose tag is the type-and-units index. Fields with units but neither scale",
        "nor value set keep their units only where the DSL's Int/Float can carry them.",
        "",
        "Left out:",
        "",
    ]
    for item in sorted(left, key=lambda x: (x.reading, x.code)):
        lines.append(f"* 0x{item.code:04X} {item.name} ({item.reading}): {item.reason}")
    if defects:
        lines += ["", "Not readable in the public JSIDL (left out; a strict reading rejects them):",
                  ""]
        lines += [f"* {label}: {problem}" for label, problem in defects]
    doc = "\n".join(_wrap(x) for x in lines)
    tup = ", ".join(repr(n) for n in names)
    return (f'"""{doc}\n"""\n\nfrom __future__ import annotations\n\n'
            f"BUILTIN_SETS: tuple[str, ...] = ({tup},)\n")


def ruff(paths: list[Path]) -> None:
    exe = Path(sys.executable).parent / "ruff"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "ruff"]
    for args in (["format", "-q"], ["check", "--fix", "-q"], ["format", "-q"]):
        try:
            subprocess.run(cmd + args + [str(p) for p in paths], check=False, cwd=REPO)
        except OSError as exc:
            log.warning("ruff not run (%s); output left unformatted", exc)
            return


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(message)s")
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", nargs="?", default=str(REPO.parent / "shared" / "jaus"),
                        help="folder holding jsidl/ and jsidl-iop/ (default ../shared/jaus)")
    parser.add_argument("--out", default=str(OUT), help="output package folder")
    parser.add_argument("--check", action="store_true",
                        help="write to a temporary folder and fail if the committed modules "
                             "differ")
    args = parser.parse_args(argv)
    root = Path(args.root).resolve()
    if not (root / "jsidl").is_dir():
        log.error("no jsidl/ folder in %s", root)
        return 2
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            main([str(root), "--out", tmp])
            stale = [p.name for p in sorted(Path(tmp).glob("*.py"))
                     if not (OUT / p.name).exists() or (OUT / p.name).read_text() != p.read_text()]
        if stale:
            log.error("out of date: %s (run tools/gen_messages.py)", ", ".join(stale))
            return 1
        log.info("committed modules are up to date")
        return 0
    out = Path(args.out)
    chosen, left, defects = build(root)
    for label, problem in defects:
        log.warning("%s: %s", label, problem)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    sources = "JAUS Toolset ``jsidl/`` and FKIE IOP ``jsidl-iop/`` sets"
    for c in chosen:
        path = out / f"{c.spec.module}.py"
        path.write_text(write_module(c, sources))
        written.append(path)
        log.info("%s: %d messages", path.name, len(c.messages))
    init = out / "__init__.py"
    init.write_text(write_init(chosen, left, defects))
    written.append(init)
    ruff(written)
    log.info("total %d messages; %d left out", sum(len(c.messages) for c in chosen), len(left))
    return 0


if __name__ == "__main__":
    sys.exit(main())
