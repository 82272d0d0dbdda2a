"""The ``generic`` translator: JAUS -> DDS mappings read from the deployment profile. No I/O.

Rules come from the deployment profile instead of Python, for messages a user loads
from JSIDL::

    [[translators.generic.mappings]]
    message = "ReportWaterQuality"        # a message of the user's JSIDL
    topic = "WaterQuality"                # DDS topic (type edge_vis::GenericReport)
    query = "QueryWaterQuality"           # optional: how to ask for it ...
    service = "urn:example:WaterQuality"  # ... from which service
    rate = 0.5                            # Hz
    fields = { turbidity = "turbidity", ph = "chemistry.ph" }   # DDS name = JAUS path

The table is declared as dataclasses (:class:`GenericOptions`, :class:`GenericMapping`)
and read by the validation kit. Before the relay starts (and in ``edge-vis check``),
:meth:`GenericTranslator.verify` looks every message, query, service and field path up in
the live catalogue, the profile's own JSIDL included, and names each one missing. Field
paths start at the message's fields; a body that is one record is flattened when decoded,
and a path qualified by that record's name (``water_quality_rec.turbidity``, as the JSIDL
nests it) is read as the flattened one (``turbidity``): both publish the same value.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from edge_vis.kit import (
    NAN,
    Computed,
    ConfigError,
    Const,
    ReportRule,
    RuleTranslator,
    TopicDecl,
    declarations,
    get_path,
    path_problem,
    read_table,
    resolve_path,
    setting,
)


def _non_empty(text: str) -> str | None:
    return None if text else "missing (a non-empty string)"


def _topic_name(topic: str) -> str | None:
    if not topic:
        return "missing (a non-empty string)"
    return None if topic.replace("_", "").isalnum() else \
        f"{topic!r}: letters, digits and '_' only"


@dataclass(frozen=True, slots=True)
class GenericMapping:
    """One profile mapping: JAUS ``message`` -> DDS ``topic`` (type GenericReport).

    ``fields`` maps each DDS field name to a JAUS field path of ``message``; ``query``
    asks ``service`` for the message, with ``query_fields``, at ``rate``.
    """

    message: str = setting(check=_non_empty, doc="the JAUS message to publish")
    topic: str = setting(check=_topic_name, doc="the DDS topic to publish it on")
    fields: Mapping[str, str] = setting(factory=dict, check=_non_empty,
                                        unit="a JAUS field path")
    query: str = ""
    service: str = ""
    rate: float = setting(1.0, gt=0, le=1092, unit="Hz")
    query_fields: Mapping[str, Any] = setting(factory=dict)

    def validate(self) -> Iterator[tuple[str, str]]:
        """A query is sent to a service: one without the other cannot be used."""
        if bool(self.query) != bool(self.service):
            yield ("service" if self.query else "query"), "query and service go together"


@dataclass(frozen=True, slots=True)
class GenericOptions:
    """The ``[translators.generic]`` table: ``[[translators.generic.mappings]]``."""

    mappings: tuple[GenericMapping, ...] = ()

    def validate(self) -> Iterator[tuple[str, str]]:
        """Each JAUS message goes to one topic."""
        topics: dict[str, str] = {}
        for i, m in enumerate(self.mappings):
            if m.message in topics:
                yield f"mappings[{i}].message", f"{m.message} is already mapped to " \
                                                f"{topics[m.message]}"
            topics[m.message] = m.topic


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
        services = sorted({uri for d in catalogue for uri, _version in d.services})
        if mapping.service not in services:
            yield "service", f"no service {mapping.service!r} declares a message in the " \
                             f"catalogue{_close(mapping.service, services)}"


def resolved(mapping: GenericMapping, catalogue: Any) -> GenericMapping:
    """``mapping`` with its field paths as decoded fields hold them (a record-qualified
    path of a flattened body loses the record's name)."""
    defn = _lookup(catalogue, mapping.message)
    if defn is None:
        return mapping
    return replace(mapping, fields={dds: resolve_path(defn.body, path)[0]
                                    for dds, path in mapping.fields.items()})


def _lookup(catalogue: Any, name: str) -> Any:
    try:
        return catalogue.by_name(name)
    except KeyError:
        return None


def _close(name: str, names: Sequence[str]) -> str:
    near = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return f"{hint} (a message set of your own needs its JSIDL in catalogue.jsidl)"


class GenericTranslator(RuleTranslator):
    """Any JAUS message -> a ``GenericReport``-typed topic, mapped in the profile.

    Built empty (it translates nothing) until :meth:`configure` gives it the profile's
    ``[translators.generic]`` table, or ``mappings`` are passed in.
    """

    name = "generic"
    options_type = GenericOptions

    def __init__(self, mappings: Sequence[GenericMapping] = ()) -> None:
        self.mappings: tuple[GenericMapping, ...] = ()
        super().__init__()
        self._set(tuple(mappings))

    def apply_options(self, options: GenericOptions) -> None:
        """Take the mappings of the validated profile table."""
        self._set(options.mappings)

    def verify(self, catalogue: Any, source: str = "") -> None:
        """Every message, query, service and field path must exist in ``catalogue``;
        record-qualified paths are then read as the flattened ones."""
        where = f"translators.{self.name}.mappings"
        problems = [(source, f"{where}[{i}].{key}", reason)
                    for i, m in enumerate(self.mappings)
                    for key, reason in catalogue_problems(m, catalogue)]
        if problems:
            raise ConfigError(problems)
        self._set(tuple(resolved(m, catalogue) for m in self.mappings))

    def _set(self, mappings: tuple[GenericMapping, ...]) -> None:
        self.mappings = mappings
        rules = tuple(self._rule(m) for m in mappings)
        # instance attributes: this translator's declarations come from the profile
        self.report_rules = rules  # type: ignore[misc]
        for name, value in declarations(rules, ()).items():
            setattr(self, name, value)
        self._by_message = {}
        for rule in rules:
            self._by_message.setdefault(rule.message, []).append(rule)
        self.topic_types = self._topic_specs()  # type: ignore[misc]

    @staticmethod
    def _rule(m: GenericMapping) -> ReportRule:
        def fields_of(jaus: Mapping[str, Any], m: GenericMapping = m) -> list[dict[str, Any]]:
            return [{"name": dds, **generic_value(get_path(jaus, path))}
                    for dds, path in m.fields.items() if get_path(jaus, path) is not None]

        return ReportRule(
            m.message, m.topic,
            {"message": Const(m.message),
             "fields": Computed(fields_of, "; ".join(f"{d}<-{p}" for d, p in m.fields.items()))},
            query=m.query, service=m.service, query_fields=m.query_fields, rate=m.rate,
            doc="profile mapping",
        )

    def _topic_specs(self) -> tuple[TopicDecl, ...]:
        return tuple(dict.fromkeys(TopicDecl(m.topic, "GenericReport", "telemetry")
                                   for m in self.mappings if m.topic != "GenericReport"))

    def describe(self) -> list[dict[str, Any]]:
        rows = super().describe()
        for row, m in zip(rows, self.mappings, strict=False):
            row["fields"] = [{"dds": f"fields[name={d}]", "jaus": p, "note": ""}
                             for d, p in m.fields.items()]
        return rows
