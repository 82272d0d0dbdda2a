"""The ``cbrn`` translator (IOP CBRNSensor): CBRN payload state, reports and commands. No I/O.

JAUS -> DDS, per payload station (the JSIDL numbers stations bitwise: 0x1 station 1 ...
0x80000000 station 32; ``station`` is that number, 0 for all):

* CBRNOperatingState, CBRNConfigurationState, CBRNScanWindowOperatingState ->
  ``CbrnStatus`` (merged): the main states as labels, and every field each report
  carries in ``operating``, ``configuration`` and ``scan_window``;
* CBRN4 (ATP-45 report text) and RNDetailedMeasurement -> ``CbrnDetection``.

DDS -> JAUS (behind control, as the service requires): ``CbrnCommand`` by ``kind`` ->
CBRNCommand, CBRNConfigurationCommand or CBRNDisplayConfigurationCommand, each setting
by its JAUS field name, enumerations by label.

What the public definitions do not allow is listed as not translated: CBRNDetection
cannot be read as published (14 optional fields behind an 8-bit presence vector);
CBDetailedMeasurement shares its code and layout with RNDetailedMeasurement (decoded as
that); CBRNScanWindowConfigurationCommand shares its code with MeasurementSensor's
QueryMeasurement; CBRNDetailedInfoRequest/Response are commented out of the JSIDL.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    NAN,
    Build,
    Command,
    Computed,
    Const,
    From,
    ReportRule,
    RuleTranslator,
    code_of,
    label,
)
from edge_vis.kit import CommandRule as Cmd

CBRN = "urn:jaus:jss:iop:CBRNSensor"
#: the pseudo path whose built dict becomes the message's fields (one per setting)
SETTINGS = "(settings)"
ALL = {"station_number": 0}

PAYLOAD_STATES = {0: "Has Faults", 1: "Has Warnings", 2: "Above Threshold", 3: "Operating",
                  4: "Powered Off", 5: "Starting Up", 6: "Calibrating", 7: "Testing"}
OPERATING_STATES = {0: "Operating", 1: "Standby", 2: "Training"}
SAMPLING_STATES = {0: "Idle", 1: "Sampling", 2: "Sensing Component Test (Confidence Test)",
                   3: "Scanning", 4: "Tracking"}
PAYLOAD_TYPES = {0: "Chemical", 1: "Biological", 2: "Radiological", 3: "Nuclear",
                 4: "Chemical Standoff", 5: "Biological Standoff", 6: "Radiological Standoff",
                 7: "Nuclear Standoff"}
DETECTIONS = {0: "Below Threshold", 1: "Above Threshold", 2: "Above Threshold Update",
              3: "NIL (Detection Cleared)"}

# the settings of the three commands: JAUS field -> its labels (an enumeration) or type
ON_OFF = {0: "Off", 1: "On"}
OPERATE = {0: "Operate", 1: "Standby", 2: "Training"}
REBOOT = {0: "Normal Operation", 1: "Reboot"}
RESET = {0: "Normal Operation", 1: "Reset"}
SAMPLING = {0: "Stop Sampling", 1: "Start Sampling", 2: "Stop Scanning", 3: "Start Scanning",
            4: "Stop Tracking", 5: "Start Tracking"}
TESTS = {0: "Self Test (all Payload Components)", 1: "Audio Test", 2: "Control Component Test",
         3: "Power Distribution and Interface Logic Component Test",
         4: "Sensing Component Test (Confidence Test)", 5: "Wireless Comms Component Test",
         6: "Dismounted Power Component Test",
         7: "User Interface Component Test (Display Test)"}
TEST_MODE = {0: "Stop Test", 1: "Start Test"}
ALARM = {0: "Silence Alarm", 1: "Activate Alarm"}
KEYGUARD = {0: "Unlocked", 1: "Locked"}
COMMAND_FIELDS: dict[str, Any] = {
    "set_power_mode": ON_OFF,
    "set_operating_mode": OPERATE,
    "reboot": REBOOT,
    "operating_reset_type": int,
    "operating_reset_state": RESET,
    "reset_configuration_state": RESET,
    "set_sampling_mode": SAMPLING,
    "test_type": TESTS,
    "set_test_mode": TEST_MODE,
    "set_local_alarm_enunciation": ALARM,
    "set_keyguard": KEYGUARD,
    "set_clock": float,
}
EXERCISE = {0: "Exercise", 1: "Operation"}
POSITIONING = {0: "Manual", 1: "GPS"}
SENSITIVITY = {0: "Normal", 1: "High"}
SUBTRACT = {0: "Do Not Subtract", 1: "Subtract"}
AUTO_MANUAL = {0: "Automatic", 1: "Manual"}
DETECTION_MODE = {0: "Automatic", 1: "Manual", 2: "Standby"}
DETECTION_LEVEL = {0: "Standard", 1: "Miosis", 2: "ICT5", 3: "ICT50", 4: "Operational", 5: "Low"}
AUDIO = {0: "High", 1: "Medium", 2: "Low", 3: "Off"}
DELIVERY = {0: "Threat Related", 1: "Continuous"}
LANGUAGE = {0: "English", 1: "French"}
CONFIGURATION_FIELDS: dict[str, Any] = {
    "set_exer_oper_name": str,
    "set_exer_oper_flag": EXERCISE,
    "set_call_sign": str,
    "set_positioning_mode": POSITIONING,
    "set_payload_latitude": float,
    "set_payload_longitude": float,
    "set_payload_altitude": float,
    "set_payload_sensitivity": SENSITIVITY,
    "set_background_level_subtract_mode": SUBTRACT,
    "set_background_level_mode": AUTO_MANUAL,
    "set_background_level": float,
    "set_detection_mode": DETECTION_MODE,
    "set_detection_level": DETECTION_LEVEL,
    "set_detection_operational_threshold_level": float,
    "set_detection_low_threshold_level": float,
    "set_detection_threshold_delay": float,
    "set_sampling_interval": int,
    "set_sampling_duration": int,
    "set_sampling_volume": float,
    "set_audio_level": AUDIO,
    "set_detection_above_threshold_update_frequency": float,
    "set_location_label": str,
    "set_group_location_label": str,
    "set_cbrn4_delivery_mode": DELIVERY,
    "set_language": LANGUAGE,
}
BRIGHTNESS = {0: "Off", 1: "Low", 2: "Medium", 3: "High", 4: "Night Vision"}
DISPLAY_MODE = {0: "Power Save", 1: "Continuous"}
DISPLAY_FIELDS: dict[str, Any] = {
    "set_display_brightness_level": BRIGHTNESS,
    "set_display_mode": DISPLAY_MODE,
    "set_display_contrast": float,
    "set_other_visual_indicators_brightness_level": BRIGHTNESS,
}
#: CbrnCommand.kind -> (JAUS message, its settings)
KINDS: dict[str, tuple[str, dict[str, Any]]] = {
    "COMMAND": ("CBRNCommand", COMMAND_FIELDS),
    "CONFIGURATION": ("CBRNConfigurationCommand", CONFIGURATION_FIELDS),
    "DISPLAY": ("CBRNDisplayConfigurationCommand", DISPLAY_FIELDS),
}


def station(value: Any) -> int:
    """A bitwise station number (0x4) -> the station (3); 0 (all) or a non-power of two
    stays as it is."""
    number = int(value or 0)
    return number.bit_length() if number and not number & (number - 1) else number


def station_bits(value: Any) -> int:
    """A station (3) -> its bit (0x4); 0 = all stations."""
    number = int(value or 0)
    if not 0 <= number <= 32:
        raise ValueError(f"station {number}: 1..32, or 0 for all")
    return 1 << (number - 1) if number else 0


def _fields(f: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every reported field but the station, as GenericField (name, text, number)."""
    out = []
    for name, value in f.items():
        if name == "station_number":
            continue
        number = float(value) if isinstance(value, int | float) else NAN
        out.append({"name": name, "text": str(value), "number": number})
    return out


def settings(kind: str) -> Any:
    """Builder: the settings of a CbrnCommand -> the JAUS fields of ``kind``'s message."""
    table = KINDS[kind][1]

    def build(sample: Mapping[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for item in sample.get("settings") or []:
            name = str(item.get("name", ""))
            if name not in table:
                raise ValueError(f"{name!r} is not a setting of {KINDS[kind][0]} "
                                 f"(settings: {', '.join(table)})")
            kind_of, text = table[name], str(item.get("text") or "")
            number = item.get("number")
            if isinstance(kind_of, dict):
                out[name] = code_of(kind_of)(text if text else number)
            elif kind_of is str:
                out[name] = text
            else:
                out[name] = kind_of(number if number == number and number is not None
                                    else text)
        if kind == "CONFIGURATION" and "set_cbrn4_delivery_mode" not in out:
            raise ValueError("CBRNConfigurationCommand needs set_cbrn4_delivery_mode")
        return out

    return build


def _station_of(sample: Mapping[str, Any]) -> int:
    return station_bits(sample.get("station", 0))


def _command(kind: str) -> Cmd:
    message = KINDS[kind][0]
    return Cmd("CbrnCommand", message, CBRN, "cbrn_" + kind.lower(), {
        "station_number": Build("station", _station_of, "station -> its bit, 0 = all"),
        SETTINGS: Build("settings", settings(kind), "settings[] by JAUS field name; labels for "
                                              "enumerations")},
        when={"kind": kind})


class CbrnTranslator(RuleTranslator):
    """IOP CBRNSensor <-> ``CbrnStatus``, ``CbrnDetection`` and ``CbrnCommand``."""

    name = "cbrn"
    report_rules = (
        ReportRule("CBRNOperatingState", "CbrnStatus", {
            "station": From("station_number", convert=station),
            "payload_state": From("payload_state", convert=label(PAYLOAD_STATES), default=""),
            "operating_mode": From("operating_mode", convert=label(OPERATING_STATES),
                                   default=""),
            "sampling_state": From("sampling_state", convert=label(SAMPLING_STATES),
                                   default=""),
            "battery_remaining": From("battery_remaining", note="percent"),
            "operating": Computed(_fields, "every field, by name"),
        }, query="QueryCBRNOperatingState", service=CBRN, query_fields=ALL, rate=0.5,
            keys=("station",), merge=True, doc="all stations asked (0)"),
        ReportRule("CBRNConfigurationState", "CbrnStatus", {
            "station": From("station_number", convert=station),
            "product_name": From("product_name", default=""),
            "payload_type": From("payload_cbrn_type", convert=label(PAYLOAD_TYPES),
                                 default=""),
            "power_mode": From("power_mode", convert=label({0: "Off", 1: "On"}), default=""),
            "configuration": Computed(_fields, "every field, by name"),
        }, query="QueryCBRNConfiguration", service=CBRN, query_fields=ALL, rate=0.1,
            on_change=True, keys=("station",), merge=True),
        ReportRule("CBRNScanWindowOperatingState", "CbrnStatus", {
            "station": From("station_number", convert=station),
            "scan_window": Computed(_fields, "every field, by name"),
        }, query="QueryCBRNScanWindowOperatingState", service=CBRN, query_fields=ALL,
            rate=0.5, keys=("station",), merge=True),
        ReportRule("CBRN4", "CbrnDetection", {
            "station": From("station_number", convert=station),
            "kind": Const("CBRN4"),
            "detection": From("detection_type", convert=label(DETECTIONS), default=""),
            "report_id": From("cbrn4_report_id", default=-1),
            "text": From("cbrn4", default=""),
            "time": From("timestamp", note="s since 1970"),
        }, query="QueryCBRN4", service=CBRN,
            query_fields={"cbrn4_report_id": 0, "station_number": 0}, rate=0.2,
            on_change=True, doc="the last report (ID 0) of all stations"),
        ReportRule("RNDetailedMeasurement", "CbrnDetection", {
            "station": From("station_number", convert=station),
            "kind": Const("MEASUREMENT"),
            "detection": From("detection_type", convert=label(DETECTIONS), default=""),
            "text": From("measurement", default=""),
            "time": From("timestamp", note="s since 1970"),
        }, query="QueryRNDetailedMeasurement", service=CBRN, query_fields=ALL, rate=0.2,
            on_change=True, doc="also CBDetailedMeasurement: the same code and layout"),
    )
    command_rules = tuple(_command(kind) for kind in KINDS)
    not_translated = (
        ("CBRNDetection", "cannot be read as published: 14 optional fields behind an 8-bit "
                          "presence vector (JSIDL 0xF931)"),
        ("CBDetailedMeasurement", "shares 0xF932 and its layout with RNDetailedMeasurement: "
                                  "decoded and published as that"),
        ("CBRNScanWindowConfigurationCommand", "shares 0xF92A with MeasurementSensor's "
                                               "QueryMeasurement, which the catalogue keeps"),
        ("CBRNDetailedInfoRequest", "commented out of the public JSIDL (and shares 0xF927 "
                                    "with CBRNCommand)"),
        ("CBRNDetailedInfoResponse", "commented out of the public JSIDL"),
        ("QueryCBRNDetection", "asks for CBRNDetection, which cannot be read as published"),
        ("QueryCBDetailedMeasurement", "its answer is read as RNDetailedMeasurement, asked "
                                       "with QueryRNDetailedMeasurement"),
    )

    def command(self, rule: Cmd, sample: Mapping[str, Any]) -> Command | None:
        """The rule's command, its settings spread over the message's fields."""
        command = super().command(rule, sample)
        if command is None or SETTINGS not in command.fields:
            return command
        fields = {k: v for k, v in command.fields.items() if k != SETTINGS}
        return dataclasses.replace(command, fields={**fields, **command.fields[SETTINGS]})
