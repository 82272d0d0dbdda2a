"""The translator in the README's Plugins section runs as written: it imports only the kit,
its report reaches its DDS topic's type, and its command is built from a DDS sample."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from rulekit import CTX, TYPES, command_sample

from edge_vis.catalogue import default_catalogue
from edge_vis.codec.types import Scaled, f, message, u8, u16
from edge_vis.dds.convert import converter_for
from edge_vis.kit import Command, Publish, RuleTranslator

README = Path(__file__).resolve().parents[2] / "README.md"
SERVICE = ("urn:example:BatteryPack", "1.0")
# the user's message set, as their JSIDL would define it
MESSAGES = (
    message(0xD101, "QueryBatteryPack", service_set="battery", services=(SERVICE,)),
    message(0xD401, "ReportBatteryPack", f("pack_id", u8),
            f("charge_pct", Scaled(u8, 0.0, 100.0)), f("volts", Scaled(u16, 0.0, 60.0)),
            service_set="battery", services=(SERVICE,)),
    message(0xD001, "SetChargeLimit", f("limit_pct", u8), service_set="battery",
            services=(SERVICE,)),
)


def readme_translator() -> type[RuleTranslator]:
    text = README.read_text()
    block = re.search(r"<!-- example:translator -->\n```python\n(.*?)```", text, re.S)
    assert block, "the README lost its translator example"
    source = block.group(1)
    assert re.findall(r"^from (\S+) import", source, re.M) == ["edge_vis.kit"]
    scope: dict[str, Any] = {}
    exec(compile(source, "README.md", "exec"), scope)
    cls = scope["BatteryTranslator"]
    assert issubclass(cls, RuleTranslator)
    return cls


def test_the_readme_translator_maps_both_ways() -> None:
    tr = readme_translator()()
    catalogue = default_catalogue().copy()
    catalogue.add(MESSAGES, source="test battery set")
    assert (tr.messages, tr.publishes, tr.subscribes) == (
        ("ReportBatteryPack",), ("PowerPlantStatus",), ("DeviceCommand",))
    (spec,) = tr.reports
    assert catalogue.decode(catalogue.encode(spec.query, {})).name == "QueryBatteryPack"

    wire = catalogue.decode(catalogue.encode(
        "ReportBatteryPack", {"pack_id": 2, "charge_pct": 75.0, "volts": 48.0}))
    (action,) = tr.on_message(wire.name, wire.fields, CTX)
    assert isinstance(action, Publish) and action.topic == "PowerPlantStatus"
    sample = converter_for(TYPES["PowerPlantStatus"]).to_struct(action.sample, action.topic)
    assert (sample.plant_id, sample.kind) == (2, "battery")
    assert abs(sample.remaining_percent - 75.0) < 0.5 and abs(sample.voltage - 48.0) < 0.5

    rule = tr.command_rules[0]
    (command,) = tr.on_sample("DeviceCommand",
                              command_sample(rule, device="charge_limit", value=140.0), CTX)
    assert isinstance(command, Command) and command.name == "SetChargeLimit"
    assert dict(command.fields) == {"limit_pct": 100}  # clamped to the rule's range
    assert (command.kind, command.service) == ("charge_limit", "urn:example:BatteryPack")
    assert catalogue.decode(catalogue.encode(command.name, command.fields)).fields == {
        "limit_pct": 100}
    assert not tr.on_sample("DeviceCommand", command_sample(rule, device="horn"), CTX)
