"""The cbrn translator: payload state and reports per station, commands by setting name."""

from __future__ import annotations

from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, check_command_rule, check_report_rule, command_sample

from edge_vis.codec.types import Enum
from edge_vis.dds.convert import converter_for
from edge_vis.kit import CommandRule
from translators.cbrn import KINDS, CbrnTranslator, station, station_bits

TR = CbrnTranslator
REPORTS = TR.report_rules
COMMANDS = TR.command_rules


@pytest.mark.parametrize("rule", REPORTS, ids=[f"{r.message}" for r in REPORTS])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


def setting(name: str, text: str = "", number: float = float("nan")) -> dict[str, Any]:
    return {"name": name, "text": text, "number": number}


@pytest.mark.parametrize(("rule", "values", "expected"), [
    (COMMANDS[0], {"station": 3, "settings": [setting("set_power_mode", "on"),
                                              setting("set_sampling_mode", "Start Sampling"),
                                              setting("set_clock", number=1.7e9)]},
     {"station_number": 4, "set_power_mode": 1, "set_sampling_mode": 1, "set_clock": 1.7e9}),
    (COMMANDS[1], {"station": 0, "settings": [setting("set_cbrn4_delivery_mode", "Continuous"),
                                              setting("set_call_sign", "ALPHA"),
                                              setting("set_sampling_interval", number=30)]},
     {"station_number": 0, "set_cbrn4_delivery_mode": 1, "set_call_sign": "ALPHA",
      "set_sampling_interval": 30}),
    (COMMANDS[2], {"station": 1, "settings": [setting("set_display_brightness_level",
                                                      "Night Vision")]},
     {"station_number": 1, "set_display_brightness_level": 4}),
], ids=[c.message for c in COMMANDS])
def test_every_declared_command(rule: CommandRule, values: dict[str, Any],
                                expected: dict[str, Any]) -> None:
    command = check_command_rule(TR(), rule, command_sample(rule, **values))
    assert dict(command.fields) == expected


@pytest.mark.parametrize("sample", [
    {"kind": "COMMAND", "settings": [setting("set_warp_drive", "on")]},
    {"kind": "COMMAND", "settings": [setting("set_power_mode", "Maybe")]},
    {"kind": "CONFIGURATION", "settings": [setting("set_call_sign", "B")]},  # mandatory one
    {"kind": "DISPLAY", "station": 33, "settings": []},
])
def test_bad_commands_are_refused_naming_the_setting(sample: dict[str, Any]) -> None:
    assert TR().on_sample("CbrnCommand", {"vehicle_id": "veh1", "operator_id": "op1",
                                          **sample}, CTX) == []


def test_settings_tables_match_the_catalogue() -> None:
    for message, table in KINDS.values():
        defn = CAT.by_name(message)
        fields = {f.name: f.type for f in defn.body.fields}
        assert set(table) == set(fields) - {"timestamp", "station_number"}, message
        for name, kind in table.items():
            if isinstance(kind, dict):
                assert isinstance(fields[name], Enum) and dict(fields[name].labels) == kind


def test_stations_are_bits_on_the_wire() -> None:
    assert [station(v) for v in (0, 1, 2, 4, 0x80000000, 6)] == [0, 1, 2, 3, 32, 6]
    assert [station_bits(v) for v in (0, 1, 3, 32)] == [0, 1, 4, 0x80000000]


def decoded(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    return CAT.decode(CAT.encode(name, fields)).fields or {}


def test_status_merges_the_three_reports_per_station() -> None:
    tr = TR()
    (a,) = tr.on_message("CBRNOperatingState", decoded("CBRNOperatingState", {
        "station_number": 2, "payload_state": 3, "battery_remaining": 77.0}), CTX)
    (b,) = tr.on_message("CBRNConfigurationState", decoded("CBRNConfigurationState", {
        "station_number": 2, "product_name": "JCAD", "identifier": "x1",
        "sw_firmware_version": "2.1", "payload_cbrn_type": 0, "power_mode": 1}), CTX)
    sample = b.sample
    assert (sample["station"], sample["payload_state"], sample["product_name"],
            sample["payload_type"], sample["power_mode"]) == (2, "Operating", "JCAD",
                                                             "Chemical", "On")
    assert {f["name"] for f in sample["configuration"]} >= {"product_name", "power_mode"}
    assert {f["name"] for f in sample["operating"]} == {"payload_state", "battery_remaining"}
    assert b.merge == ("vehicle_id", "station")
    converter_for(TYPES["CbrnStatus"]).to_struct(sample, "CbrnStatus")
    assert a.sample["battery_remaining"] == pytest.approx(77.0, abs=0.1)


def test_detections() -> None:
    (report,) = TR().on_message("CBRN4", decoded("CBRN4", {
        "station_number": 1, "detection_type": 1, "cbrn4_report_id": 5,
        "cbrn4": "ALFA/..."}), CTX)
    assert (report.sample["kind"], report.sample["detection"], report.sample["report_id"],
            report.sample["text"]) == ("CBRN4", "Above Threshold", 5, "ALFA/...")
    (measurement,) = TR().on_message("RNDetailedMeasurement", decoded(
        "RNDetailedMeasurement", {"station_number": 1, "measurement": "Cs-137 12 uSv/h"}), CTX)
    assert (measurement.sample["kind"], measurement.sample["text"]) == (
        "MEASUREMENT", "Cs-137 12 uSv/h")
