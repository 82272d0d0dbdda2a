"""The ``generic`` translator: JAUS <-> DDS mappings read from the deployment profile. No I/O.

Rules come from the deployment profile instead of Python, for messages a user loads
from JSIDL::

    [[translators.generic.mappings]]
    message = "ReportWaterQuality"        # a message of the user's JSIDL
    topic = "WaterQuality"                # DDS topic, typed from the JSIDL
    query = "QueryWaterQuality"           # optional: how to ask for it ...
    service = "urn:example:WaterQuality"  # ... from which service
    rate = 0.5                            # Hz
    fields = { turbidity = "turbidity", ph = "chemistry.ph" }   # DDS name = JAUS path
    # generic = true                      # the untyped GenericReport instead

    [[translators.generic.mappings]]      # a message carrying a file
    message = "ReportSnapshot"
    image = { data = "image_file", format = "png", sha256_field = "sha256" }

    [[translators.generic.mappings]]      # a message announcing a file the vehicle serves
    message = "ReportSurveyImage"         # (serve-images): the relay fetches it over UDT
    image = { name_field = "file_name", size_field = "size", sha256_field = "sha256" }

    [[translators.generic.commands]]      # DDS -> JAUS, only from the operator in control
    topic = "CameraPointing"
    message = "SetCameraPointing"
    service = "urn:example:CameraPod"
    fields = { pan = "pan", tilt = "tilt" }
    rate = 2.0                            # Hz, latest wins; default [commands].rate
    lifespan = 1.0                        # s; default [commands].lifespan

Each mapped topic's type is built from the JSIDL types of its fields
(:mod:`edge_vis.kit.shapes`): ``vehicle_id`` (key), the fields, ``timestamp_ms``; a command
topic has ``vehicle_id`` and ``operator_id``. Command values are clamped to the limits the
JSIDL declares (the codec scales them); the engine gates, throttles and expires them as it
does every command. An image mapping checks the file against the size and SHA-256 the
message declares and publishes it as ``ImageProduct`` + ``ImageData`` chunks
(:mod:`edge_vis.kit.imagery`); one without ``data`` announces a file the vehicle serves:
its ``ImageProduct`` has no transfer id yet, and the relay's bulk channel fetches the file
and fills it in, as for the uuv set's ReportAtrImageAvailable.

The tables are declared as dataclasses and read by the validation kit. Before the relay
starts (and in ``edge-vis check``), :meth:`GenericTranslator.verify` looks every message,
query, service and field path up in the live catalogue, the profile's own JSIDL included,
and names each one missing. Field paths start at the message's fields; a body that is one
record is flattened when decoded, and a path qualified by that record's name
(``water_quality_rec.turbidity``, as the JSIDL nests it) is read as the flattened one
(``turbidity``), in mappings, images and commands alike.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

from edge_vis.kit import (
    CHUNK_BYTES,
    NAN,
    Action,
    Build,
    CommandRule,
    Computed,
    ConfigError,
    Const,
    From,
    Publish,
    Put,
    PutEach,
    ReportRule,
    RuleTranslator,
    TopicDecl,
    TranslatorContext,
    declarations,
    get_path,
    path_problem,
    publish_image,
    read_table,
    resolve_path,
    setting,
)
from edge_vis.kit.imagery import IMAGE_DATA, IMAGE_PRODUCT
from edge_vis.kit.shapes import (
    MODULE,
    Member,
    StructShape,
    camel,
    field_at,
    idl_type,
    shape_of,
)


def _non_empty(text: str) -> str | None:
    return None if text else "missing (a non-empty string)"


def _topic_name(topic: str) -> str | None:
    if not topic:
        return "missing (a non-empty string)"
    return _topic_name_or_empty(topic)


def _topic_name_or_empty(topic: str) -> str | None:
    return None if not topic or topic.replace("_", "").isalnum() else \
        f"{topic!r}: letters, digits and '_' only"


def _member_name(name: str) -> str | None:
    return None if name.isidentifier() else \
        f"{name!r}: a DDS member name is letters, digits and '_', not starting with a digit"


@dataclass(frozen=True, slots=True)
class ImageOptions:
    """A mapping's ``image`` table: the variable-length field ``data`` holds an image (or,
    with ``kind = "file"``, any file), published as ``ImageProduct`` + ``ImageData``.

    The format is ``format`` or read from ``format_field`` (a value set gives its name);
    ``id_field`` names the image; ``size_field`` and ``sha256_field`` are what the message
    declares of the file, checked against the bytes that arrived.

    Without ``data`` the message announces a file the vehicle serves over the bulk
    channel (``serve-images``): ``size_field`` and ``sha256_field`` are then required (the
    relay fetches the file and verifies it by them), and ``name_field`` is the file's name
    on the vehicle (``<id>.<format>`` when left out).
    """

    data: str = setting("", doc="the variable-length field holding the file (none: the "
                                "message announces a file the vehicle serves)")
    kind: Literal["image", "file"] = "image"
    format: str = ""
    format_field: str = ""
    id_field: str = ""
    size_field: str = ""
    sha256_field: str = ""
    name_field: str = ""

    def validate(self) -> Iterator[tuple[str, str]]:
        """One source for the format; an announcement declares what to fetch."""
        if self.format and self.format_field:
            yield "format_field", "give format or format_field, not both"
        if self.data and self.name_field:
            yield "name_field", "a message carrying the file (data) names it by id_field"
        if not self.data:
            for key in ("size_field", "sha256_field"):
                if not getattr(self, key):
                    yield key, ("an announcement (no data) needs it: the relay fetches the "
                                "file and verifies it by its size and SHA-256")


@dataclass(frozen=True, slots=True)
class GenericMapping:
    """One profile mapping: JAUS ``message`` -> DDS ``topic``.

    ``fields`` maps each DDS member to a JAUS field path of ``message``; the topic's type
    is built from those fields' JSIDL types (``generic = true``: the untyped
    ``GenericReport`` instead). ``query`` asks ``service`` for the message, with
    ``query_fields``, at ``rate``. With ``image`` the message carries a file, published as
    ``ImageProduct`` plus ``ImageData`` chunks (``topic`` may then be left out).
    """

    message: str = setting(check=_non_empty, doc="the JAUS message to publish")
    topic: str = setting("", check=_topic_name_or_empty, doc="the DDS topic to publish it on")
    fields: Mapping[str, str] = setting(factory=dict, check=_non_empty,
                                        unit="a JAUS field path")
    query: str = ""
    service: str = ""
    rate: float = setting(1.0, gt=0, le=1092, unit="Hz")
    query_fields: Mapping[str, Any] = setting(factory=dict)
    generic: bool = False
    image: ImageOptions | None = None

    def validate(self) -> Iterator[tuple[str, str]]:
        """A query is sent to a service: one without the other cannot be used."""
        if bool(self.query) != bool(self.service):
            yield ("service" if self.query else "query"), "query and service go together"
        if self.image is None:
            if not self.topic:
                yield "topic", "missing (a non-empty string)"
            for dds in self.fields:
                if problem := _member_name(dds):
                    yield f"fields.{dds}", problem
        else:
            if self.topic not in ("", IMAGE_PRODUCT):
                yield "topic", f"an image mapping publishes on {IMAGE_PRODUCT}: leave topic out"
            if self.fields:
                yield "fields", "an image mapping takes its fields from image (no fields)"
            if self.generic:
                yield "generic", "an image mapping publishes ImageProduct, not GenericReport"

    @property
    def out_topic(self) -> str:
        """The topic this mapping publishes on."""
        return IMAGE_PRODUCT if self.image is not None else self.topic


@dataclass(frozen=True, slots=True)
class GenericCommand:
    """One profile command: a sample of DDS ``topic`` -> JAUS command ``message`` to the
    component offering ``service``, sent only while the operator holds the vehicle.

    ``fields`` maps each DDS member to a JAUS field path, as in mappings; ``constants``
    fixes JAUS fields. ``rate`` and ``lifespan`` throttle it (the
    profile's ``[commands]`` when left out), per vehicle and ``kind`` (default: the
    topic). ``stop`` (JAUS path = value) makes it a motion command: refused in emergency,
    and sent by the relay itself when the operator goes quiet (dead-man).
    """

    topic: str = setting(check=_topic_name, doc="the DDS topic operators publish")
    message: str = setting(check=_non_empty, doc="the JAUS command to send")
    service: str = setting(check=_non_empty, doc="the service that executes it")
    fields: Mapping[str, str] = setting(factory=dict, check=_non_empty,
                                        unit="a JAUS field path")
    constants: Mapping[str, Any] = setting(factory=dict)
    kind: str = ""
    rate: float | None = setting(None, gt=0, le=1092, unit="Hz")
    lifespan: float | None = setting(None, gt=0, unit="s")
    stop: Mapping[str, Any] = setting(factory=dict)

    def validate(self) -> Iterator[tuple[str, str]]:
        """DDS member names are identifiers and not the ones every command carries."""
        for dds in self.fields:
            if problem := _member_name(dds):
                yield f"fields.{dds}", problem
            elif dds in ("vehicle_id", "operator_id"):
                yield f"fields.{dds}", f"{dds!r} is a member of every command topic already"


@dataclass(frozen=True, slots=True)
class GenericOptions:
    """The ``[translators.generic]`` table: ``[[translators.generic.mappings]]`` (JAUS to
    DDS) and ``[[translators.generic.commands]]`` (DDS to JAUS)."""

    mappings: tuple[GenericMapping, ...] = ()
    commands: tuple[GenericCommand, ...] = ()

    def validate(self) -> Iterator[tuple[str, str]]:
        """Each JAUS message goes to one topic; a command topic is not a report topic."""
        topics: dict[str, str] = {}
        for i, m in enumerate(self.mappings):
            if m.message in topics:
                yield f"mappings[{i}].message", f"{m.message} is already mapped to " \
                                                f"{topics[m.message]}"
            topics[m.message] = m.out_topic
        published = set(topics.values())
        seen: set[str] = set()
        for i, c in enumerate(self.commands):
            if c.topic in published:
                yield f"commands[{i}].topic", f"{c.topic} is a report topic of a mapping"
            if c.topic in seen:
                yield f"commands[{i}].topic", f"{c.topic} already drives another command"
            seen.add(c.topic)


def generic_value(value: Any) -> dict[str, Any]:
    """One ``GenericField`` value: text always, number when it is one."""
    if isinstance(value, bool):
        return {"text": str(value).lower(), "number": float(value)}
    if isinstance(value, int | float):
        return {"text": repr(value) if isinstance(value, float) else str(value),
                "number": float(value)}
    if isinstance(value, bytes | bytearray):
        return {"text": bytes(value).hex(), "number": NAN}
    if value is None:
        return {"text": "", "number": NAN}
    return {"text": str(value), "number": NAN}


def parse_mappings(options: Mapping[str, Any], source: str = "",
                   where: str = "translators.generic") -> tuple[GenericMapping, ...]:
    """Validate the generic translator's profile table; ConfigError lists every problem."""
    return read_options(options, source, where).mappings


def read_options(options: Mapping[str, Any], source: str = "",
                 where: str = "translators.generic") -> GenericOptions:
    """The generic translator's profile table as :class:`GenericOptions`."""
    return read_table(GenericOptions, options, file=source, path=where)


def catalogue_problems(mapping: GenericMapping, catalogue: Any) -> Iterator[tuple[str, str]]:
    """What ``mapping`` names that ``catalogue`` lacks, as ``(key, reason)``."""
    names = sorted({d.name for d in catalogue})
    defn = _lookup(catalogue, mapping.message)
    if defn is None:
        yield "message", f"no message {mapping.message!r} in the catalogue" \
                         f"{_close(mapping.message, names)}"
    else:
        for dds, path in mapping.fields.items():
            if problem := path_problem(defn.body, path):
                yield f"fields.{dds}", f"{path!r} of {mapping.message}: {problem}"
        if mapping.image is not None:
            yield from _image_problems(mapping.image, defn)
    if mapping.query:
        query = _lookup(catalogue, mapping.query)
        if query is None:
            yield "query", f"no message {mapping.query!r} in the catalogue" \
                           f"{_close(mapping.query, names)}"
        else:
            known = [f.name for f in query.body.fields]
            for key in mapping.query_fields:
                if key not in known:
                    yield f"query_fields.{key}", (f"no field {key!r} in {mapping.query} "
                                                  f"(fields: {', '.join(known) or 'none'})")
    if mapping.service:
        yield from _service_problems(mapping.service, catalogue)


def _image_problems(image: ImageOptions, defn: Any) -> Iterator[tuple[str, str]]:
    wanted = {"data": ("octets",), "format_field": ("string", "int"),
              "id_field": ("string", "int"), "size_field": ("int",),
              "sha256_field": ("string", "octets"), "name_field": ("string",)}
    for key, kinds in wanted.items():
        path = getattr(image, key)
        if not path:
            continue
        path, problem = resolve_path(defn.body, path)
        if problem:
            yield f"image.{key}", f"{getattr(image, key)!r} of {defn.name}: {problem}"
            continue
        shape = shape_of(field_at(defn.body, path)[0], "_")
        kind = "int" if isinstance(shape, str) and "int" in shape else shape
        if kind not in kinds:
            what = {"octets": "a variable-length field (bytes)", "string": "a string",
                    "int": "an integer"}
            yield f"image.{key}", (f"{path!r} of {defn.name} is {idl_type(shape)}; "
                                   f"{key} needs {' or '.join(what[k] for k in kinds)}")


def _service_problems(service: str, catalogue: Any) -> Iterator[tuple[str, str]]:
    services = sorted({uri for d in catalogue for uri, _version in d.services})
    if service not in services:
        yield "service", f"no service {service!r} declares a message in the " \
                         f"catalogue{_close(service, services)}"


def command_problems(command: GenericCommand, catalogue: Any) -> Iterator[tuple[str, str]]:
    """What ``command`` names that ``catalogue`` lacks, or leaves out, as ``(key, reason)``."""
    names = sorted({d.name for d in catalogue})
    yield from _service_problems(command.service, catalogue)
    defn = _lookup(catalogue, command.message)
    if defn is None:
        yield "message", f"no message {command.message!r} in the catalogue" \
                         f"{_close(command.message, names)}"
        return
    paths = {**{p: f"fields.{d}" for d, p in command.fields.items()},
             **{p: f"constants.{p}" for p in command.constants}}
    for path, key in [*paths.items(), *((p, f"stop.{p}") for p in command.stop)]:
        if problem := path_problem(defn.body, path):
            yield key, f"{path!r} of {command.message}: {problem}"
    paths = {resolve_path(defn.body, p)[0]: key for p, key in paths.items()}
    missing = [f.name for f in defn.body.fields if not f.optional
               and not any(p == f.name or p.startswith(f.name + ".") for p in paths)]
    if missing:
        yield "fields", (f"{command.message} needs {', '.join(missing)}: map "
                         f"{'it' if len(missing) == 1 else 'them'} in fields or constants")
    declared = [uri for uri, _version in defn.services]
    if declared and command.service not in declared:
        yield "service", (f"{command.service!r} does not declare {command.message} "
                          f"(declared by {', '.join(declared)})")


def resolved(mapping: GenericMapping, catalogue: Any) -> GenericMapping:
    """``mapping`` with its field paths (and its image's) as decoded fields hold them: a
    record-qualified path of a flattened body loses the record's name."""
    defn = _lookup(catalogue, mapping.message)
    if defn is None:
        return mapping

    def path(p: str) -> str:
        return resolve_path(defn.body, p)[0] if p else p

    image = mapping.image
    if image is not None:
        image = replace(image, data=path(image.data), format_field=path(image.format_field),
                        id_field=path(image.id_field), size_field=path(image.size_field),
                        sha256_field=path(image.sha256_field),
                        name_field=path(image.name_field))
    return replace(mapping, fields={dds: path(p) for dds, p in mapping.fields.items()},
                   image=image)


def resolved_command(command: GenericCommand, catalogue: Any) -> GenericCommand:
    """``command`` with its field paths as the encoder takes them (see :func:`resolved`)."""
    defn = _lookup(catalogue, command.message)
    if defn is None:
        return command

    def path(p: str) -> str:
        return resolve_path(defn.body, p)[0]

    return replace(command, fields={dds: path(p) for dds, p in command.fields.items()},
                   constants={path(p): v for p, v in command.constants.items()},
                   stop={path(p): v for p, v in command.stop.items()})


def _lookup(catalogue: Any, name: str) -> Any:
    try:
        return catalogue.by_name(name)
    except KeyError:
        return None


def _close(name: str, names: Sequence[str]) -> str:
    import difflib  # only for a profile's typo: not in a running relay's memory

    near = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return f"{hint} (a message set of your own needs its JSIDL in catalogue.jsidl)"


class GenericTranslator(RuleTranslator):
    """JAUS messages -> typed topics (or ``GenericReport``, or images), and DDS topics ->
    JAUS commands, mapped in the profile.

    Built empty (it translates nothing) until :meth:`configure` gives it the profile's
    ``[translators.generic]`` table, or ``mappings`` are passed in. Topic types and command
    limits come from the JSIDL, so :meth:`verify` (with the live catalogue) completes the
    rules; what the engine needs before that (messages, topics, controlled services) is
    known from the table alone.
    """

    name = "generic"
    options_type = GenericOptions

    def __init__(self, mappings: Sequence[GenericMapping] = (),
                 commands: Sequence[GenericCommand] = ()) -> None:
        self.mappings: tuple[GenericMapping, ...] = ()
        self.commands: tuple[GenericCommand, ...] = ()
        super().__init__()
        self._images: dict[str, tuple[GenericMapping, Mapping[int, str]]] = {}
        self._set(tuple(mappings), tuple(commands))

    def apply_options(self, options: GenericOptions) -> None:
        """Take the mappings and commands of the validated profile table."""
        self._set(options.mappings, options.commands)

    def verify(self, catalogue: Any, source: str = "") -> None:
        """Every message, query, service and field path must exist in ``catalogue``; a
        command must set every field its message requires. Record-qualified paths are then
        read as the flattened ones, and the topic types and the command limits are built
        from the JSIDL."""
        where = f"translators.{self.name}"
        problems = [(source, f"{where}.mappings[{i}].{key}", reason)
                    for i, m in enumerate(self.mappings)
                    for key, reason in catalogue_problems(m, catalogue)]
        problems += [(source, f"{where}.commands[{i}].{key}", reason)
                     for i, c in enumerate(self.commands)
                     for key, reason in command_problems(c, catalogue)]
        if problems:
            raise ConfigError(problems)
        self._set(tuple(resolved(m, catalogue) for m in self.mappings),
                  tuple(resolved_command(c, catalogue) for c in self.commands), catalogue)

    def _set(self, mappings: tuple[GenericMapping, ...], commands: tuple[GenericCommand, ...],
             catalogue: Any = None) -> None:
        self.mappings, self.commands = mappings, commands
        defs = {name: _lookup(catalogue, name) if catalogue is not None else None
                for name in {*(m.message for m in mappings), *(c.message for c in commands)}}
        rules = tuple(self._rule(m, defs[m.message]) for m in mappings)
        command_rules = tuple(_command_rule(c, defs[c.message]) for c in commands)
        # instance attributes: this translator's declarations come from the profile
        self.report_rules = rules  # type: ignore[misc]
        self.command_rules = command_rules  # type: ignore[misc]
        extra = (IMAGE_DATA,) if any(m.image is not None and m.image.data for m in mappings) else ()
        for name, value in declarations(rules, command_rules, (), extra).items():
            setattr(self, name, value)
        self._by_message = {}
        for rule in rules:
            self._by_message.setdefault(rule.message, []).append(rule)
        self._by_topic = {}
        for command in command_rules:
            self._by_topic.setdefault(command.topic, []).append(command)
        self._images = {m.message: (m, _labels(defs[m.message], m.image.format_field))
                        for m in mappings if m.image is not None}
        self.topic_types = self._topic_specs(defs)  # type: ignore[misc]

    @staticmethod
    def _rule(m: GenericMapping, defn: Any) -> ReportRule:
        spec: dict[str, Any]
        if m.image is not None:
            spec = {"image_id": Computed(lambda e: "", f"{m.message}-<{m.image.id_field}>")}
            if m.image.data:
                spec["data"] = From(m.image.data, note="ImageData chunks")
                doc = f"{m.image.kind}: ImageProduct + ImageData chunks of <= {CHUNK_BYTES} bytes"
            else:
                spec.update(size_bytes=From(m.image.size_field),
                            sha256=From(m.image.sha256_field))
                doc = f"{m.image.kind} announced; the bulk channel fetches it"
            return ReportRule(m.message, IMAGE_PRODUCT, spec, query=m.query,
                              service=m.service, query_fields=m.query_fields, rate=m.rate,
                              stamp=False, doc=doc)
        if m.generic:
            def fields_of(jaus: Mapping[str, Any], m: GenericMapping = m) -> list[dict[str, Any]]:
                return [{"name": dds, **generic_value(value)} for dds, path in m.fields.items()
                        if (value := get_path(jaus, path)) is not None]

            spec = {"message": Const(m.message),
                    "fields": Computed(fields_of,
                                       "; ".join(f"{d}<-{p}" for d, p in m.fields.items()))}
        else:
            spec = {dds: From(path, default=None, note=_note(defn, path))
                    for dds, path in m.fields.items()}
        return ReportRule(
            m.message, m.topic, spec,
            query=m.query, service=m.service, query_fields=m.query_fields, rate=m.rate,
            doc="profile mapping" + (" (GenericReport)" if m.generic else ""),
        )

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        if name not in self._images:
            return super().on_message(name, fields, ctx)
        if ctx.vehicle is None:
            return []
        mapping, labels = self._images[name]
        return image_actions(mapping, labels, fields, ctx)

    def _topic_specs(self, defs: Mapping[str, Any]) -> tuple[TopicDecl, ...]:
        decls: list[TopicDecl] = []
        for m in self.mappings:
            if m.image is not None or m.topic == "GenericReport":
                continue
            if m.generic:
                decls.append(TopicDecl(m.topic, "GenericReport", "telemetry"))
            elif defs[m.message] is not None:
                shape = topic_shape(m.topic, defs[m.message], m.fields, command=False)
                decls.append(TopicDecl(m.topic, shape.name, "telemetry", shape))
        for c in self.commands:
            if defs[c.message] is not None:
                shape = topic_shape(c.topic, defs[c.message], c.fields, command=True)
                decls.append(TopicDecl(c.topic, shape.name, "command", shape))
        return tuple(dict.fromkeys(decls))

    def describe(self) -> list[dict[str, Any]]:
        rows = super().describe()
        for row, m in zip(rows, self.mappings, strict=False):
            if m.generic:
                row["fields"] = [{"dds": f"fields[name={d}]", "jaus": p, "note": ""}
                                 for d, p in m.fields.items()]
        return rows


def topic_shape(topic: str, defn: Any, fields: Mapping[str, str], *,
                command: bool) -> StructShape:
    """The type of a mapping's topic: ``vehicle_id`` (key), the mapped JAUS fields with
    their JSIDL types, then ``timestamp_ms`` (a report) or ``operator_id`` (a command)."""
    type_name = f"{MODULE}::{topic}"
    members = [Member("vehicle_id", "string", key=True)]
    if command:
        members.append(Member("operator_id", "string"))
    for dds, path in fields.items():
        field_type, optional, units = field_at(defn.body, path)
        members.append(Member(dds, shape_of(field_type, topic + camel(dds)), optional,
                              units=units))
    if not command:
        members.append(Member("timestamp_ms", "int64"))
    return StructShape(type_name, tuple(members))


def _note(defn: Any, path: str) -> str:
    if defn is None:
        return ""
    field_type, optional, units = field_at(defn.body, path)
    shape = shape_of(field_type, "_")
    parts = [idl_type(shape) if not isinstance(shape, StructShape) else "struct"]
    if units:
        parts.append(units)
    if optional:
        parts.append("optional")
    return ", ".join(parts)


def _command_rule(c: GenericCommand, defn: Any) -> CommandRule:
    """The kit's command rule for a profile command: numbers clamped to the limits the
    JSIDL declares for each field (the codec scales them), integers made integers."""
    puts: dict[str, Put | PutEach | Build] = {}
    for dds, path in c.fields.items():
        low = high = None
        convert = None
        optional = False
        if defn is not None:
            field_type, optional, _units = field_at(defn.body, path)
            low, high, convert = _limits(field_type)
        puts[path] = Put(dds, low, high, convert=convert, optional=optional)
    for path, value in c.constants.items():
        puts[path] = Build("", lambda _sample, value=value: value, f"= {value!r}")
    return CommandRule(c.topic, c.message, c.service, c.kind or c.topic, puts,
                       stop=dict(c.stop) or None, rate=c.rate, lifespan=c.lifespan,
                       doc="profile command")


def _limits(field_type: Any) -> tuple[float | None, float | None, Any]:
    raw = getattr(field_type, "raw", field_type)
    if hasattr(field_type, "lower") and hasattr(field_type, "upper"):
        return field_type.lower, field_type.upper, None
    if hasattr(raw, "bits") and hasattr(raw, "signed"):  # an integer: its own range
        return raw.min, raw.max, _integer
    return None, None, None


def _integer(value: Any) -> int:
    if isinstance(value, float) and not value.is_integer():
        raise ValueError(f"{value} is not a whole number")
    return int(value)


def _labels(defn: Any, path: str) -> Mapping[int, str]:
    if defn is None or not path:
        return {}
    return dict(getattr(field_at(defn.body, path)[0], "labels", {}) or {})


_SHA256_HEX = re.compile("[0-9a-f]{64}")
"""A SHA-256 as lower-case hex: what an announcement must declare to be fetched."""


def _declared_sha256(fields: Mapping[str, Any], image: ImageOptions) -> str:
    """The SHA-256 a message declares, as lower-case hex ("" when it declares none)."""
    declared = get_path(fields, image.sha256_field) if image.sha256_field else None
    return declared.hex() if isinstance(declared, bytes | bytearray) else \
        str(declared or "").strip().lower()


def image_actions(mapping: GenericMapping, labels: Mapping[int, str],
                  fields: Mapping[str, Any], ctx: TranslatorContext) -> list[Action]:
    """An image mapping's ``ImageProduct`` and ``ImageData`` for one message, after
    checking the file against the size and SHA-256 the message declares (a mismatch is
    refused with a ValueError: the translator's error counter and log say why); for an
    announcement (no ``data``), the ``ImageProduct`` alone, without a transfer id, for the
    relay's bulk channel to fetch."""
    assert ctx.vehicle is not None and mapping.image is not None
    image = mapping.image
    what = f"{mapping.message} from {ctx.vehicle.vehicle_id}"
    data: bytes | None = None
    if image.data:
        raw = get_path(fields, image.data)
        if not isinstance(raw, bytes | bytearray):
            raise ValueError(f"{mapping.message}: no {image.data} bytes in the message")
        data = bytes(raw)
        digest, size = hashlib.sha256(data).hexdigest(), len(data)
        declared = get_path(fields, image.size_field) if image.size_field else None
        if declared is not None and int(declared) != size:
            raise ValueError(f"{what}: {size} bytes arrived, {image.size_field} "
                             f"declares {declared}; dropped")
        text = _declared_sha256(fields, image)
        if text and text != digest:
            raise ValueError(f"{what}: SHA-256 {digest[:16]}... differs from "
                             f"{image.sha256_field} {text[:16]}...; dropped")
    else:
        digest, declared = _declared_sha256(fields, image), get_path(fields, image.size_field)
        if not _SHA256_HEX.fullmatch(digest) or not isinstance(declared, int) or declared < 0:
            raise ValueError(f"{what}: announces no file to fetch ({image.size_field} "
                             f"{declared!r}, {image.sha256_field} {digest[:16]!r}); dropped")
        size = declared
    ident = get_path(fields, image.id_field) if image.id_field else None
    image_id = f"{mapping.message}-{ident}" if ident is not None else \
        f"{mapping.message}-{digest[:16]}"
    fmt = image.format
    if image.format_field:
        value = get_path(fields, image.format_field)
        fmt = labels.get(value, str(value)) if isinstance(value, int) else str(value or "")
    fmt = fmt.lower() or ("bin" if image.kind == "file" else "")
    name = get_path(fields, image.name_field) if image.name_field else None
    product = {"vehicle_id": ctx.vehicle.vehicle_id, "image_id": image_id,
               "file_name": str(name or f"{image_id}.{fmt or 'img'}"), "size_bytes": size,
               "sha256": digest, "format": fmt, "capture_time_ms": ctx.timestamp_ms}
    if data is None:
        return [Publish(IMAGE_PRODUCT, {**product, "transfer_id": "", "targets": []})]
    return list(publish_image(product, data))
