"""Table-driven checks of rule translators, generated from their own declarations.

For every :class:`ReportRule` a report is made from the message's definition (random
values, every optional field present or absent), encoded to real bytes and decoded by the
catalogue; the translator's samples must carry exactly the declared values and convert
into the topic's DDS type. For every :class:`CommandRule` a DDS sample made from the topic
type's defaults (plus the rule's selector) must give exactly one command that the
catalogue encodes. The test modules add hand-written expected values for the important
messages on top.
"""

from __future__ import annotations

import dataclasses
import math
import random
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # .../tests, for strategies

from strategies import random_value

from edge_vis.catalogue import default_catalogue
from edge_vis.codec.types import Enum, FieldType, List, Record, Variant
from edge_vis.dds import model
from edge_vis.dds.convert import converter_for
from edge_vis.jaus.address import JausAddress
from edge_vis.kit import (
    CommandRule,
    Const,
    Each,
    From,
    ReportRule,
    RuleTranslator,
    get_path,
)
from edge_vis.kit.actions import Command, Publish
from edge_vis.kit.contract import TranslatorContext, VehicleView

CAT = default_catalogue()
VIEW = VehicleView("veh1", 150, name="Veh", address=JausAddress(150, 1, 1), online=True)
CTX = TranslatorContext(now=10.0, timestamp_ms=1_700_000_000_123,
                        relay_id=JausAddress(42, 1, 1), vehicle=VIEW, catalogue=CAT)
TYPES: dict[str, Any] = {t.__name__: t for t in model.STRUCTS}


def labelled(ft: FieldType, rng: random.Random, present: float = 0.7) -> Any:
    """A random value of ``ft`` whose enumerations use their listed values."""
    if isinstance(ft, Enum) and ft.labels:
        return rng.choice(sorted(ft.labels))
    if isinstance(ft, Record):
        return {f.name: labelled(f.type, rng, present) for f in ft.fields
                if not f.optional or rng.random() < present}
    if isinstance(ft, List):
        return [labelled(ft.element, rng, present) for _ in range(rng.randint(1, 3))]
    if isinstance(ft, Variant):
        alt = rng.choice(ft.alternatives)
        return {alt.name: labelled(alt.type, rng, present)}
    return random_value(ft, rng)


def report(message: str, rng: random.Random, present: float = 0.7) -> dict[str, Any]:
    """Decoded fields of a random ``message`` that went through real bytes."""
    defn = CAT.by_name(message)
    payload = CAT.encode(message, labelled(defn.body, rng, present))
    decoded = CAT.decode(payload)
    assert decoded.name == message
    return decoded.fields or {}


def same(a: Any, b: Any) -> bool:
    """Equality with NaN == NaN and a little float tolerance."""
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-9,
                                                                 abs_tol=1e-9)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(a == b)


def expected_value(spec: Any, root: Mapping[str, Any]) -> Any:
    """What a From/Const/Each spec must give, computed independently of the translator."""
    if isinstance(spec, From):
        raw = get_path(root, spec.path)
        if raw is None:
            return spec.default
        return spec.convert(raw) if spec.convert else raw
    if isinstance(spec, Const):
        return spec.value
    if isinstance(spec, Each):
        items = get_path(root, spec.path) or []
        if isinstance(spec.item, Mapping):
            return [{k: expected_value(v, e) for k, v in spec.item.items()} for e in items]
        return [expected_value(spec.item, e) for e in items]
    return None  # Computed: checked by hand-written cases


def check_report_rule(translator: RuleTranslator, rule: ReportRule, seeds: int = 6) -> int:
    """Run ``rule`` on random reports; returns how many samples were checked."""
    checked = 0
    converter = converter_for(TYPES[rule.topic])
    for seed in range(seeds):
        rng = random.Random(f"{rule.message}-{seed}")
        fields = report(rule.message, rng, present=0.3 if seed % 2 else 0.9)
        actions = translator.on_message(rule.message, fields, CTX)
        published = [a.sample for a in actions
                     if isinstance(a, Publish) and a.topic == rule.topic]
        samples = type(translator)().samples(rule, fields, CTX)  # this rule's share
        assert all(any(same(s, p) for p in published) for s in samples), rule.message
        roots = (get_path(fields, rule.split) or []) if rule.split else [fields]
        roots = [r for r in roots if not rule.require or get_path(r, rule.require) is not None]
        assert len(samples) == len(roots), (rule.message, len(samples), len(roots))
        for sample, root in zip(samples, roots, strict=True):
            assert sample["vehicle_id"] == "veh1"
            if rule.stamp:
                assert sample["timestamp_ms"] == CTX.timestamp_ms
            for member, spec in rule.fields.items():
                want = expected_value(spec, root)
                if want is not None:
                    assert same(sample[member], want), (rule.message, member, sample[member],
                                                        want)
            converter.to_struct(sample, rule.topic)  # a valid DDS sample of the topic
            checked += 1
    if rule.query:
        payload = CAT.encode(rule.query, rule.query_fields)
        assert CAT.decode(payload).name == rule.query
    return checked


def command_sample(rule: CommandRule, **values: Any) -> dict[str, Any]:
    """A DDS sample of ``rule.topic``: the type's defaults, the selector, ``values``."""
    sample: dict[str, Any] = {"vehicle_id": "veh1", "operator_id": "op1"}
    for fld in dataclasses.fields(TYPES[rule.topic]):
        if fld.default is not dataclasses.MISSING:
            sample.setdefault(fld.name, fld.default)
        elif fld.default_factory is not dataclasses.MISSING:
            sample.setdefault(fld.name, fld.default_factory())
    for key, wanted in rule.when.items():
        sample[key] = wanted[0] if isinstance(wanted, tuple) else wanted
    sample.update(values)
    return sample


def check_command_rule(translator: RuleTranslator, rule: CommandRule,
                       sample: Mapping[str, Any]) -> Command:
    """``sample`` gives exactly ``rule``'s command, and the catalogue encodes it."""
    converter_for(TYPES[rule.topic]).to_struct(dict(sample), rule.topic)  # valid DDS
    actions = translator.on_sample(rule.topic, sample, CTX)
    commands = [a for a in actions if isinstance(a, Command)]
    assert len(commands) == 1, (rule.message, actions)
    command = commands[0]
    assert (command.name, command.service, command.kind) == (rule.message, rule.service,
                                                             rule.kind)
    assert (command.vehicle_id, command.operator_id) == ("veh1", "op1")
    payload = encode(command)
    assert CAT.decode(payload).name == command.name
    if command.stop is not None:
        encode(command, command.stop)
    return command


def encode(action: Any, fields: Mapping[str, Any] | None = None) -> bytes:
    """The payload of a Command or SendMessage, encoded as the runtime does: by name, or
    by the code of that name in the action's ``service_set``."""
    name: str | int = action.name
    if action.service_set is not None:
        name = CAT.by_name(action.name, action.service_set).code
    return CAT.encode(name, dict(action.fields if fields is None else fields))


class Relay:
    """A sans-I/O engine with a fake clock; every message goes through real bytes."""

    def __init__(self, profile: Any, translators: Any = None) -> None:
        from edge_vis.engine.engine import Engine

        self.engine = Engine(profile, translators, catalogue=CAT)
        self.now = 0.0
        self.actions: list[Any] = []

    def deliver(self, source: str, name: str, fields: Mapping[str, Any] | None = None
                ) -> list[Any]:
        message = CAT.decode(CAT.encode(name, dict(fields or {})))
        self.engine.receive_message(JausAddress.parse(source), message, self.now)
        return self.drain()

    def sample(self, topic: str, sample: Mapping[str, Any]) -> list[Any]:
        self.engine.receive_sample(topic, dict(sample), self.now)
        return self.drain()

    def advance(self, seconds: float) -> list[Any]:
        end, out = self.now + seconds, []
        while True:
            deadline = self.engine.next_deadline()
            if deadline is None or deadline > end:
                break
            self.now = max(self.now, deadline)
            self.engine.on_timer(self.now)
            out.extend(self.drain())
        self.now = end
        self.engine.on_timer(self.now)
        return out + self.drain()

    def drain(self) -> list[Any]:
        from edge_vis.kit.actions import SendMessage

        actions = self.engine.drain_actions()
        for action in actions:
            if isinstance(action, SendMessage):
                encode(action)  # encodable as emitted
        self.actions.extend(actions)
        return actions

    def sent(self, name: str) -> list[Any]:
        from edge_vis.kit.actions import SendMessage

        return [a for a in self.actions if isinstance(a, SendMessage) and a.name == name]

    def published(self, topic: str) -> list[Mapping[str, Any]]:
        return [a.sample for a in self.actions if isinstance(a, Publish) and a.topic == topic]
