"""The rule vocabulary translators are written in: declarative JAUS <-> DDS tables. No I/O.

Most translation is a table: *this field of that report goes to that member of this topic,
converted so*. This module holds the table's vocabulary, and :class:`RuleTranslator`, a
:class:`~edge_vis.kit.contract.Translator` that runs such tables. The same rule objects are
what ``edge-vis mappings`` prints (through :meth:`RuleTranslator.describe`), so the
documentation cannot drift from what runs.

JAUS -> DDS, a :class:`ReportRule`: ``fields`` maps each DDS member to a value spec:

* :class:`From` - a decoded JAUS field by dotted path (``"platform_spec.front"``). A path
  step ``*`` takes the value of a variant whatever its alternative
  (``{"radian": 1.2}`` -> ``1.2``). Absent optional fields give the spec's default
  (NaN for measurements, so "not reported" never reads as zero);
* :class:`Each` - a DDS sequence built from a JAUS list, one item per element;
* :class:`Const` - a fixed value; :class:`Computed` - a small function, with a note saying
  which JAUS fields it reads.

``split`` makes one sample per element of a JAUS list (one ``RangeScan`` per sensor of a
``ReportRangeSensorData``); ``require`` skips elements without that path (an error
alternative of a variant). ``merge`` keeps the latest value of every member per instance,
so a state topic fed by several reports (``PlatformStatus`` from ``ReportPlatformState``
and ``ReportPlatformMode``) never clears what another report said, and a member a report
did not carry (NaN) keeps its earlier value; the engine merges such samples across
translators too (``HealthStatus`` from the health monitor and the power plant).

DDS -> JAUS, a :class:`CommandRule`: ``fields`` maps JAUS field paths to :class:`Put`
(one DDS member, clamped to the JAUS field's limits) or :class:`PutEach` (a JAUS list from
a DDS sequence) or :class:`Build` (a function of the sample). ``when`` selects the rule by
sample values (``{"quantity": "position"}``, a tuple of values, or a predicate), so one
topic can drive several messages. Commands go out as
:class:`~edge_vis.kit.actions.Command`: the engine gates them on control and throttles
them.

The ``generic`` translator plugin is one ordinary translator written with these rules.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Union

from edge_vis.codec.bodies import compile_type
from edge_vis.codec.types import BitField, List, Record, VarFormat, Variant
from edge_vis.errors import DecodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Action, Command, Publish
from edge_vis.kit.contract import Binding, ReportSpec, Translator, TranslatorContext

log = logging.getLogger(__name__)

NAN = math.nan

# ---------------------------------------------------------------------------------- values


@dataclass(frozen=True, slots=True)
class From:
    """A DDS member taken from the JAUS field at ``path``, optionally converted."""

    path: str
    convert: Callable[[Any], Any] | None = None
    default: Any = NAN
    note: str = ""


@dataclass(frozen=True, slots=True)
class Each:
    """A DDS sequence from the JAUS list at ``path``: per element, ``item`` (a spec for a
    sequence of scalars, or a mapping of member -> spec for a sequence of structs)."""

    path: str
    item: Union[Spec, Mapping[str, Spec]]  # noqa: UP007 - Spec is a forward reference
    note: str = ""


@dataclass(frozen=True, slots=True)
class Const:
    """A fixed DDS value."""

    value: Any
    note: str = ""


@dataclass(frozen=True, slots=True)
class Computed:
    """A DDS value computed from the whole JAUS field dict; ``note`` says from what."""

    fn: Callable[[Mapping[str, Any]], Any]
    note: str


Spec = Union[From, Each, Const, Computed]  # noqa: UP007


@dataclass(frozen=True, slots=True)
class ReportRule:
    """JAUS message ``message`` -> a sample of DDS ``topic`` (see the module docstring).

    ``query``/``service``/``query_fields``/``rate``/``on_change`` become the
    :class:`~edge_vis.kit.contract.ReportSpec` the engine subscribes with; without
    ``query`` the message is taken as it comes (unsolicited, or asked for elsewhere).
    ``service_set`` binds the rule to that set's message when two sets use the name
    (``ReportActiveElement``): only that one reaches the translator, and the query is
    encoded with that set's code.
    """

    message: str
    topic: str
    fields: Mapping[str, Spec]
    query: str = ""
    service: str = ""
    query_fields: Mapping[str, Any] = field(default_factory=dict)
    rate: float = 1.0
    on_change: bool = False
    split: str = ""
    require: str = ""
    keys: tuple[str, ...] = ()
    merge: bool = False
    stamp: bool = True
    doc: str = ""
    service_set: str = ""


@dataclass(frozen=True, slots=True)
class Put:
    """A JAUS field from DDS member ``dds``: numbers clamped to ``[low, high]``, then
    ``convert``. ``optional``: an absent/None/NaN member leaves the JAUS field out;
    otherwise it becomes ``default``."""

    dds: str
    low: float | None = None
    high: float | None = None
    convert: Callable[[Any], Any] | None = None
    default: Any = 0.0
    optional: bool = False
    note: str = ""


@dataclass(frozen=True, slots=True)
class PutEach:
    """A JAUS list from the DDS sequence ``dds``: ``item(value, index, sample)`` builds
    each element."""

    dds: str
    item: Callable[[Any, int, Mapping[str, Any]], Any]
    note: str = ""


@dataclass(frozen=True, slots=True)
class Build:
    """A JAUS field built from the whole DDS sample by ``fn`` (``dds`` names the members it
    reads, for the mapping table); a ValueError refuses the command."""

    dds: str
    fn: Callable[[Mapping[str, Any]], Any]
    note: str = ""


@dataclass(frozen=True, slots=True)
class CommandRule:
    """A sample of DDS ``topic`` (matching ``when``) -> JAUS command ``message`` to the
    component offering ``service``; ``kind`` groups commands for throttling and ``stop``,
    when given, makes it a motion command (dead-man stop, refused in emergency): the stop
    fields, or a function of the command's fields giving them (a zero per joint).
    ``service_set`` names the message set of ``message`` when two sets use the name
    (``ExecuteList``): the command is then encoded with that set's code. ``rate`` (Hz) and
    ``lifespan`` (s) replace the profile's ``[commands]`` throttle for this kind.
    ``needs_ready``/``every_provider`` are the :class:`~edge_vis.kit.actions.Command`'s;
    ``component``, when given, names the DDS member holding a JAUS address (``S.N.C``)
    the command is sent to instead (empty: the default destination)."""

    topic: str
    message: str
    service: str
    kind: str
    fields: Mapping[str, Put | PutEach | Build]
    when: Mapping[str, Any] = field(default_factory=dict)
    stop: Mapping[str, Any] | Callable[[Mapping[str, Any]], Mapping[str, Any]] | None = None
    doc: str = ""
    service_set: str | None = None
    needs_ready: bool = True
    every_provider: bool = False
    component: str = ""
    rate: float | None = None
    lifespan: float | None = None


# ---------------------------------------------------------------------------------- helpers


def get_path(fields: Any, path: str, default: Any = None) -> Any:
    """The value at dotted ``path`` in decoded fields (``*`` enters a variant)."""
    value = fields
    if not path:
        return value
    for step in path.split("."):
        if not isinstance(value, Mapping):
            return default
        if step == "*":
            if len(value) != 1:
                return default
            value = next(iter(value.values()))
        elif step in value:
            value = value[step]
        else:
            return default
    return value


def path_problem(body: Record, path: str) -> str:
    """Why :func:`get_path` can find nothing at ``path`` in a message whose body is
    ``body`` (its definition); "" when the path exists (see :func:`resolve_path`)."""
    return resolve_path(body, path)[1]


def resolve_path(body: Record, path: str) -> tuple[str, str]:
    """``(the path as decoded fields hold it, why there is nothing there or "")``.

    Paths start at the body's fields. A body that is one record is flattened when
    decoded, so a path qualified by that record's name (``"pack_rec.pack_id"``, as the
    JSIDL nests it) is read as the path into the flattened fields (``"pack_id"``): both
    forms name the same field. Where the catalogue knows that record's name (messages read
    from JSIDL), a first step naming another record is refused, not skipped.
    """
    steps = path.split(".")
    problem = _path_problem(body, steps, [])
    if problem and len(steps) > 1 and steps[0] and \
            not any(f.name == steps[0] for f in body.fields) and \
            not _path_problem(body, steps[1:], []):
        if body.flattened and steps[0] != body.flattened:
            return path, (f"no field or record {steps[0]!r} in the message (its body is the "
                          f"record {body.flattened!r}, whose fields are read as "
                          f"{steps[1]!r} or {body.flattened}.{steps[1]})")
        return ".".join(steps[1:]), ""
    return path, problem


def type_at(body: Record, path: str) -> Any:
    """The field type at ``path`` (resolved as :func:`resolve_path` does), or None."""
    resolved, problem = resolve_path(body, path)
    if problem:
        return None
    node: Any = body
    for step in resolved.split("."):
        if isinstance(node, Record):
            node = next(f.type for f in node.fields if f.name == step)
        elif isinstance(node, Variant):
            if step == "*":
                return None
            node = next(a.type for a in node.alternatives if a.name == step)
        else:
            return None  # a sub-field of a bit field: an integer
    return node


def decode_as(catalogue: Any, message: str, type_name: str, data: bytes) -> Any:
    """``data`` decoded as the type named ``type_name`` (its JSIDL name) in the definition
    of ``message``: for a JAUS value carried as bytes inside another (the JSIDL's
    ``field_format``: compressed scan points are a ``RangeSensorDataPointList``). Raises
    ValueError when no such type is there or the bytes do not fit it exactly."""
    field_type = named_type(catalogue.by_name(message).body, type_name)
    if field_type is None:
        raise ValueError(f"{message} has no type named {type_name!r}")
    try:
        value, end = compile_type(field_type).decode(data, 0)
    except DecodeError as exc:
        raise ValueError(f"not a {type_name}: {exc}") from None
    if end != len(data):
        raise ValueError(f"{len(data) - end} bytes left over after the {type_name}")
    return value


def named_type(node: Any, name: str) -> Any:
    """The first record, list or variant named ``name`` (its JSIDL name) in the field type
    ``node`` (a message body), depth first; None when there is none."""
    if getattr(node, "name", None) == name and isinstance(node, Record | List | Variant):
        return node
    if isinstance(node, Record):
        children = [f.type for f in node.fields]
    elif isinstance(node, Variant):
        children = [a.type for a in node.alternatives]
    elif isinstance(node, List):
        children = [node.element]
    else:
        return None
    for child in children:
        found = named_type(child, name)
        if found is not None:
            return found
    return None


def _path_problem(node: Any, steps: list[str], done: list[str]) -> str:
    if not steps:
        return ""
    step, rest, here = steps[0], steps[1:], ".".join(done) or "the message"
    if not step:
        return f"empty step in the path after {here}"
    if isinstance(node, Record):
        for member in node.fields:
            if member.name == step:
                return _path_problem(member.type, rest, [*done, step])
        listed = ", ".join(f.name for f in node.fields) or "none"
        return f"no field {step!r} in {here} (fields: {listed})"
    if isinstance(node, Variant):
        alternatives = ", ".join(a.name for a in node.alternatives)
        if step == "*":
            found = [_path_problem(a.type, rest, [*done, step]) for a in node.alternatives]
            return "" if "" in found or not found else found[0]
        for alternative in node.alternatives:
            if alternative.name == step:
                return _path_problem(alternative.type, rest, [*done, step])
        return f"no alternative {step!r} in {here} (alternatives: {alternatives}, or *)"
    if isinstance(node, BitField | VarFormat):
        names = [sub.name for sub in node.subfields] if isinstance(node, BitField) \
            else ["format", "data"]
        if step not in names:
            return f"no sub-field {step!r} in {here} (sub-fields: {', '.join(names)})"
        return f"{here}.{step} is a single value: nothing is inside it" if rest else ""
    if isinstance(node, List):
        return f"{here} is a list: a path cannot enter it (it names the whole list)"
    return f"{here} is a single value: nothing is inside it"


def set_path(fields: dict[str, Any], path: str, value: Any) -> None:
    """Set dotted ``path`` in ``fields``, creating the records on the way."""
    steps = path.split(".")
    for step in steps[:-1]:
        fields = fields.setdefault(step, {})
    fields[steps[-1]] = value


def label(labels: Mapping[int, str], unknown: str = "UNKNOWN") -> Callable[[Any], str]:
    """Converter: a JAUS enumeration value -> its name (``unknown_<n>`` if unlisted)."""

    def convert(value: Any) -> str:
        if value is None:
            return unknown
        return labels.get(int(value), f"{unknown}_{int(value)}")

    return convert


def code_of(labels: Mapping[int, str]) -> Callable[[Any], int]:
    """Converter: a name (any case; spaces or underscores) or number -> the JAUS value."""
    by_name = {_norm(name): value for value, name in labels.items()}

    def convert(value: Any) -> int:
        if isinstance(value, int | float) and not isinstance(value, bool):
            return int(value)
        key = _norm(str(value))
        if key not in by_name:
            raise ValueError(f"{value!r} is not one of {', '.join(labels.values())}")
        return by_name[key]

    return convert


def _norm(name: str) -> str:
    return name.strip().upper().replace(" ", "_").replace("-", "_")


def flags(value: Any) -> str:
    """Converter: a decoded bit field -> the comma-joined names of its non-zero members."""
    if not isinstance(value, Mapping):
        return ""
    return ",".join(name for name, bit in value.items() if bit)


def number(value: Any) -> float:
    """Converter: any number -> float (None -> NaN)."""
    return NAN if value is None else float(value)


def _finite(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def clamp(value: float, low: float | None, high: float | None) -> float:
    """``value`` limited to ``[low, high]`` (either may be None)."""
    if low is not None:
        value = max(low, value)
    if high is not None:
        value = min(high, value)
    return value


# ---------------------------------------------------------------------------------- running


def extract(spec: Spec, fields: Mapping[str, Any]) -> Any:
    """Evaluate one value spec against decoded JAUS fields."""
    if isinstance(spec, From):
        value = get_path(fields, spec.path)
        if value is None:
            return spec.default
        return spec.convert(value) if spec.convert is not None else value
    if isinstance(spec, Each):
        items = get_path(fields, spec.path) or []
        out = []
        for element in items:
            if isinstance(spec.item, Mapping):
                out.append({name: extract(sub, element) for name, sub in spec.item.items()})
            else:
                out.append(extract(spec.item, element))
        return out
    if isinstance(spec, Const):
        return spec.value
    return spec.fn(fields)


def put(spec: Put | PutEach | Build, sample: Mapping[str, Any]) -> tuple[bool, Any]:
    """Evaluate one JAUS field spec against a DDS sample: (present, value)."""
    if isinstance(spec, Build):
        return True, spec.fn(sample)
    if isinstance(spec, PutEach):
        values = sample.get(spec.dds) or []
        return True, [spec.item(v, i, sample) for i, v in enumerate(values)]
    value = sample.get(spec.dds)
    if not _finite(value):
        if spec.optional:
            return False, None
        value = spec.default
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = clamp(float(value), spec.low, spec.high)
    if spec.convert is not None:
        value = spec.convert(value)
    return True, value


def _spec_source(spec: Spec) -> tuple[str, str]:
    """(JAUS source, note) of a value spec, for the mapping table."""
    if isinstance(spec, From):
        return spec.path, spec.note
    if isinstance(spec, Each):
        if isinstance(spec.item, Mapping):
            inner = ", ".join(f"{k}<-{_spec_source(v)[0]}" for k, v in spec.item.items())
            return f"{spec.path}[] ({inner})", spec.note
        return f"{spec.path}[].{_spec_source(spec.item)[0]}", spec.note
    if isinstance(spec, Const):
        return f"= {spec.value!r}", spec.note
    return "(computed)", spec.note


class RuleTranslator(Translator):
    """A translator that runs :class:`ReportRule` and :class:`CommandRule` tables.

    Subclasses set ``report_rules`` and ``command_rules``; ``messages``, ``reports``,
    ``publishes``, ``subscribes`` and ``controlled_services`` are derived from them (plus
    anything the subclass lists itself in ``extra_messages`` / ``extra_publishes``).
    """

    report_rules: ClassVar[tuple[ReportRule, ...]] = ()
    command_rules: ClassVar[tuple[CommandRule, ...]] = ()
    extra_messages: ClassVar[tuple[str, ...]] = ()
    extra_publishes: ClassVar[tuple[str, ...]] = ()
    #: names the mapping table lists as not translated, with the reason
    not_translated: ClassVar[tuple[tuple[str, str], ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._derive()

    @classmethod
    def _derive(cls) -> None:
        for name, value in declarations(cls.report_rules, cls.command_rules,
                                         cls.extra_messages,
                                         cls.extra_publishes).items():
            setattr(cls, name, value)

    def __init__(self) -> None:
        self._latest: dict[tuple[str, tuple[Any, ...]], dict[str, Any]] = {}
        self._by_message: dict[str, list[ReportRule]] = {}
        for rule in self.report_rules:
            self._by_message.setdefault(rule.message, []).append(rule)
        self._by_topic: dict[str, list[CommandRule]] = {}
        for command in self.command_rules:
            self._by_topic.setdefault(command.topic, []).append(command)

    # -- JAUS -> DDS -----------------------------------------------------------------------

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if ctx.vehicle is None:
            return []
        actions: list[Action] = []
        for rule in self._by_message.get(name, ()):
            merge = ("vehicle_id", *rule.keys) if rule.merge else ()
            for sample in self.samples(rule, fields, ctx):
                actions.append(Publish(rule.topic, sample, merge))
        return actions

    def samples(self, rule: ReportRule, fields: Mapping[str, Any],
                ctx: TranslatorContext) -> list[dict[str, Any]]:
        """The DDS samples ``rule`` makes of one message (several when it splits)."""
        assert ctx.vehicle is not None
        roots: Sequence[Any] = get_path(fields, rule.split) or [] if rule.split else [fields]
        out = []
        for root in roots:
            if rule.require and get_path(root, rule.require) is None:
                continue
            sample: dict[str, Any] = {"vehicle_id": ctx.vehicle.vehicle_id}
            for member, spec in rule.fields.items():
                sample[member] = extract(spec, root)
            if rule.stamp:
                sample["timestamp_ms"] = ctx.timestamp_ms
            if rule.merge:
                key = (rule.topic, tuple(sample.get(k) for k in ("vehicle_id", *rule.keys)))
                merged = self._latest.setdefault(key, {})
                # a member this report did not carry (NaN) keeps what an earlier one said
                merged.update({k: v for k, v in sample.items()
                               if k not in merged or _finite(v)})
                sample = dict(merged)
            out.append(sample)
        return out

    # -- DDS -> JAUS -----------------------------------------------------------------------

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        actions: list[Action] = []
        for rule in self._by_topic.get(topic, ()):
            if not all(_matches(sample.get(k), v) for k, v in rule.when.items()):
                continue
            command = self.command(rule, sample)
            if command is not None:
                actions.append(command)
        return actions

    def command(self, rule: CommandRule, sample: Mapping[str, Any]) -> Command | None:
        """The JAUS command ``rule`` makes of ``sample`` (None if a value is unusable)."""
        fields: dict[str, Any] = {}
        try:
            for path, spec in rule.fields.items():
                present, value = put(spec, sample)
                if present:
                    set_path(fields, path, value)
            target = str(sample.get(rule.component) or "") if rule.component else ""
            component = JausAddress.parse(target) if target else None
        except (ValueError, TypeError) as exc:
            log.warning("%s sample for %s not translated to %s: %s", rule.topic,
                        sample.get("vehicle_id"), rule.message, exc)
            return None
        stop = rule.stop(fields) if callable(rule.stop) else rule.stop
        return Command(str(sample.get("vehicle_id", "")), str(sample.get("operator_id", "")),
                       rule.kind, rule.message, fields, rule.service,
                       stop=dict(stop) if stop is not None else None,
                       service_set=rule.service_set, rate=rule.rate, lifespan=rule.lifespan,
                       needs_ready=rule.needs_ready, component=component,
                       every_provider=rule.every_provider)

    # -- the mapping table -------------------------------------------------------------------

    def describe(self) -> list[dict[str, Any]]:
        """The rows ``edge-vis mappings`` prints: one per JAUS message and DDS topic."""
        return describe_rules(self.name, self.report_rules, self.command_rules,
                              self.not_translated)


def _matches(value: Any, wanted: Any) -> bool:
    if callable(wanted):
        return bool(wanted(value))
    if isinstance(wanted, tuple):
        return any(_matches(value, w) for w in wanted)
    if isinstance(wanted, str) and isinstance(value, str):
        return _norm(value) == _norm(wanted)
    return bool(value == wanted)


def declarations(report_rules: Sequence[ReportRule], command_rules: Sequence[CommandRule],
                  extra_messages: Sequence[str] = (), extra_publishes: Sequence[str] = ()
                  ) -> dict[str, Any]:
    messages = dict.fromkeys([*(r.message for r in report_rules), *extra_messages])
    reports = tuple(
        ReportSpec(r.message, r.query, r.service, dict(r.query_fields), r.rate, r.on_change,
                   r.service_set or None)
        for r in report_rules if r.query
    )
    bindings = {r.message: Binding(service_set=r.service_set)
                for r in report_rules if r.service_set}
    publishes = dict.fromkeys([*(r.topic for r in report_rules), *extra_publishes])
    subscribes = dict.fromkeys(r.topic for r in command_rules)
    controlled = dict.fromkeys(r.service for r in command_rules)
    return {"messages": tuple(messages), "reports": _unique_reports(reports),
            "publishes": tuple(publishes), "subscribes": tuple(subscribes),
            "controlled_services": tuple(controlled), "bindings": bindings}


def _unique_reports(reports: Sequence[ReportSpec]) -> tuple[ReportSpec, ...]:
    seen: set[tuple[str, str]] = set()
    out = []
    for spec in reports:
        if (spec.report, spec.service) not in seen:
            seen.add((spec.report, spec.service))
            out.append(spec)
    return tuple(out)


def describe_rules(translator: str, report_rules: Sequence[ReportRule],
                   command_rules: Sequence[CommandRule],
                   not_translated: Sequence[tuple[str, str]] = ()) -> list[dict[str, Any]]:
    """Mapping-table rows of a rule table (see ``edge-vis mappings``)."""
    rows: list[dict[str, Any]] = []
    for r in report_rules:
        rows.append({
            "translator": translator, "direction": "jaus->dds", "message": r.message,
            "topic": r.topic, "query": r.query, "service": r.service,
            "rate": r.rate if r.query else None,
            "fields": [{"dds": member, "jaus": _spec_source(spec)[0],
                        "note": _spec_source(spec)[1]} for member, spec in r.fields.items()],
            "doc": r.doc,
        })
        if r.service_set:
            rows[-1]["service_set"] = r.service_set
    for c in command_rules:
        when = ", ".join(f"{k}={getattr(v, '__doc__', None) or v}" if callable(v)
                         else f"{k}={v}" for k, v in c.when.items())
        rows.append({
            "translator": translator, "direction": "dds->jaus", "message": c.message,
            "topic": c.topic, "query": "", "service": c.service, "rate": None,
            "fields": [{"dds": s.dds, "jaus": path, "note": _put_note(s)}
                       for path, s in c.fields.items()],
            "doc": "; ".join(x for x in (f"when {when}" if when else "", c.doc) if x),
        })
        if c.service_set:
            rows[-1]["service_set"] = c.service_set
    for name, why in not_translated:
        rows.append({"translator": translator, "direction": "none", "message": name,
                     "topic": "", "query": "", "service": "", "rate": None, "fields": [],
                     "doc": why})
    return rows


def _put_note(spec: Put | PutEach | Build) -> str:
    if isinstance(spec, Build):
        return spec.note
    if isinstance(spec, PutEach):
        return spec.note or "one element per item"
    parts = [spec.note] if spec.note else []
    if spec.low is not None or spec.high is not None:
        parts.append(f"clamped to [{spec.low}, {spec.high}]")
    if spec.optional:
        parts.append("absent = left out")
    return "; ".join(parts)
