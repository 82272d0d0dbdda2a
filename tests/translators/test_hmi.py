"""The hmi translator: an operator interface's input devices on ``HmiInput``."""

from __future__ import annotations

import math

import pytest
from rulekit import CAT, CTX, TYPES, check_report_rule

from edge_vis.dds.convert import converter_for
from translators.hmi import NOT_TRANSLATED, HmiTranslator

RULES = HmiTranslator.report_rules


@pytest.mark.parametrize("rule", RULES, ids=[r.message for r in RULES])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(HmiTranslator(), rule) > 0


def decoded(name: str, fields: dict) -> dict:  # type: ignore[type-arg]
    return CAT.decode(CAT.encode(name, fields)).fields or {}


@pytest.mark.parametrize(("message", "fields", "want"), [
    ("ReportDCM", {"dcm_reference": 7, "dcm_state_code": 0},
     {"device": "dcm_7", "code": 7, "state": "PRESSED"}),
    ("ReportKeyboardAction", {"key": 65, "key_state": 1},
     {"device": "keyboard", "code": 65, "state": "PRESSED"}),
    ("ReportPointingDeviceAction", {"button": 2, "state": 1, "x": 320, "y": -4, "valid": 1},
     {"device": "pointer", "state": "RIGHT DOWN", "x": 320.0, "y": -4.0, "valid": True}),
    ("ReportPointingDeviceMovement", {"x": 10, "y": 20, "valid": 0},
     {"device": "pointer", "x": 10.0, "y": 20.0, "valid": False}),
    ("ReportAnalogAction", {"reference": 2, "longitudinal": {"byte": 127},
                            "lateral": {"short_integer": -16384},
                            "yaw": {"integer": -2147483648}},
     {"device": "analog_2", "x": 1.0, "y": -16384 / 32767, "yaw": -1.0}),
])
def test_input_devices(message: str, fields: dict, want: dict) -> None:  # type: ignore[type-arg]
    (action,) = HmiTranslator().on_message(message, decoded(message, fields), CTX)
    assert action.topic == "HmiInput"
    for key, value in want.items():
        assert action.sample[key] == pytest.approx(value), key
    converter_for(TYPES["HmiInput"]).to_struct(action.sample, "HmiInput")


def test_analog_device_names_merge_with_its_axes() -> None:
    tr = HmiTranslator()
    tr.on_message("ReportAnalogDevices", decoded("ReportAnalogDevices", {
        "report_analog_devices_list": [{"reference": 2, "name": "left stick"},
                                       {"reference": 3, "name": "right stick"}]}), CTX)
    (action,) = tr.on_message("ReportAnalogAction", decoded("ReportAnalogAction", {
        "reference": 3, "pitch": {"byte": -64}}), CTX)
    assert action.sample["name"] == "right stick"
    assert action.sample["pitch"] == pytest.approx(-64 / 127)
    assert math.isnan(action.sample["roll"])  # not sent: NaN, never 0


def test_the_rest_of_the_hmi_set_is_listed_with_reasons() -> None:
    hmi = {d.name for d in CAT if d.service_set == "hmi"}
    translated = {r.message for r in RULES} | {r.query for r in RULES}
    listed = {name for name, why in NOT_TRANSLATED if why}
    assert hmi == translated | listed and not translated & listed
