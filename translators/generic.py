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
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
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
)


@dataclass(frozen=True, slots=True)
class GenericMapping:
    """One profile mapping: JAUS ``message`` -> DDS ``topic`` (type GenericReport)."""

    message: str
    topic: str
    fields: Mapping[str, str]
    query: str = ""
    service: str = ""
    rate: float = 1.0
    query_fields: Mapping[str, Any] = field(default_factory=dict)


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
    problems: list[tuple[str, str, str]] = []
    out: list[GenericMapping] = []
    items = options.get("mappings", [])
    if not isinstance(items, list):
        raise ConfigError([(source, f"{where}.mappings", "expected an array of tables")])
    for key in options:
        if key != "mappings":
            problems.append((source, f"{where}.{key}", "unknown key"))
    topics: dict[str, str] = {}
    for i, item in enumerate(items):
        at = f"{where}.mappings[{i}]"
        if not isinstance(item, Mapping):
            problems.append((source, at, "expected a table"))
            continue
        for key in item:
            if key not in ("message", "topic", "fields", "query", "service", "rate",
                           "query_fields"):
                problems.append((source, f"{at}.{key}", "unknown key"))
        message, topic = item.get("message"), item.get("topic")
        fields = item.get("fields", {})
        for key, value in (("message", message), ("topic", topic)):
            if not isinstance(value, str) or not value:
                problems.append((source, f"{at}.{key}", "missing (a non-empty string)"))
        if isinstance(topic, str) and topic and not topic.replace("_", "").isalnum():
            problems.append((source, f"{at}.topic", f"{topic!r}: letters, digits and '_' only"))
        if not isinstance(fields, Mapping) or not all(
                isinstance(v, str) and v for v in fields.values()):
            problems.append((source, f"{at}.fields",
                             "expected a table of DDS name = \"JAUS field path\""))
            fields = {}
        query, service = item.get("query", ""), item.get("service", "")
        if bool(query) != bool(service):
            problems.append((source, f"{at}.{'service' if query else 'query'}",
                             "query and service go together"))
        rate = item.get("rate", 1.0)
        if isinstance(rate, bool) or not isinstance(rate, int | float) or not (
                0 < float(rate) <= 1092):
            problems.append((source, f"{at}.rate", f"expected a rate in Hz (0..1092], "
                                                     f"got {rate!r}"))
            rate = 1.0
        query_fields = item.get("query_fields", {})
        if not isinstance(query_fields, Mapping):
            problems.append((source, f"{at}.query_fields", "expected a table"))
            query_fields = {}
        if isinstance(topic, str) and isinstance(message, str):
            if topics.get(message) is not None:
                problems.append((source, f"{at}.message",
                                 f"{message} is already mapped to {topics[message]}"))
            topics[message] = topic
            out.append(GenericMapping(message, topic, dict(fields), str(query), str(service),
                                      float(rate), dict(query_fields)))
    if problems:
        raise ConfigError(problems)
    return tuple(out)


class GenericTranslator(RuleTranslator):
    """Any JAUS message -> a ``GenericReport``-typed topic, mapped in the profile.

    Built empty (it translates nothing) until :meth:`configure` gives it the profile's
    ``[translators.generic]`` table, or ``mappings`` are passed in.
    """

    name = "generic"

    def __init__(self, mappings: Sequence[GenericMapping] = ()) -> None:
        self.mappings: tuple[GenericMapping, ...] = ()
        super().__init__()
        self._set(tuple(mappings))

    def configure(self, options: Mapping[str, Any], source: str = "") -> None:
        """Take the mappings from the profile table ``options`` (ConfigError if bad)."""
        self._set(parse_mappings(options, source))

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
