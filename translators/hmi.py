"""The ``hmi`` translator (AS6060-era HMI services): an operator interface's inputs. No I/O.

The HMI services come in two kinds. DigitalControl, Keyboard, PointingDevice and
AnalogControl are offered by an *operator interface* (a hand-held controller or panel on
the vehicle's JAUS network) so that remote assets can read what its operator does; the
relay reads them the same way and publishes each device on ``HmiInput``, so an operator
station sees a local operator's buttons, keys, pointer and joystick:

* ReportDCM -> ``dcm_<reference>``: PRESSED / RELEASED;
* ReportKeyboardAction -> ``keyboard``: the key code, PRESSED / RELEASED;
* ReportPointingDeviceAction / ReportPointingDeviceMovement -> ``pointer``: button and
  state (``LEFT DOWN``), position, validity;
* ReportAnalogAction -> ``analog_<reference>``: the six axes as a share of full deflection
  (-1..1: the JSIDL sends each as a signed byte, short or integer, full scale its limit);
  ReportAnalogDevices names each device.

Drawing (a vehicle's remote display: graphics commands over referenced data) and SetDCM
(a remote asset styling an operator interface's button) are listed as not translated, with
the reason, in :data:`NOT_TRANSLATED`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import Computed, Const, From, ReportRule, RuleTranslator, label

HMI = "urn:jaus:jss:HMI:"
DIGITAL_CONTROL = HMI + "DigitalControl"
KEYBOARD = HMI + "Keyboard"
POINTING_DEVICE = HMI + "PointingDevice"
ANALOG_CONTROL = HMI + "AnalogControl"

#: full scale of an analog axis by the variant alternative carrying it
FULL_SCALE = {"byte": 127.0, "short_integer": 32767.0, "integer": 2147483647.0}
BUTTONS = {0: "LEFT", 1: "MIDDLE", 2: "RIGHT"}
#: the analog device the relay asks about (QueryAnalogAction names one; all six axes)
ANALOG_DEVICE = 1


def _axis(name: str) -> Computed:
    """An analog axis as a share of full deflection, clamped to -1..1 (NaN if absent)."""

    def share(f: Mapping[str, Any]) -> float:
        value = f.get(name)
        if not value:
            return float("nan")
        ((width, raw),) = value.items()
        return max(-1.0, min(1.0, float(raw) / FULL_SCALE[width]))

    return Computed(share, f"{name}.* / full scale of its width")


def _button(f: Mapping[str, Any]) -> str:
    button = int(f["button"])
    return f"{BUTTONS.get(button, f'BUTTON_{button}')} {'DOWN' if int(f['state']) else 'UP'}"


def _valid(f: Mapping[str, Any]) -> bool:
    return int(f.get("valid", 1)) == 1


def _input(message: str, query: str, service: str, fields: Mapping[str, Any],
           split: str = "", doc: str = "",
           query_fields: Mapping[str, Any] | None = None) -> ReportRule:
    return ReportRule(message, "HmiInput", fields, query=query, service=service, rate=1.0,
                      on_change=True, split=split, keys=("device",), merge=True,
                      query_fields=query_fields or {},
                      doc=doc or "every change (an event), merged per device")


REPORT_RULES: tuple[ReportRule, ...] = (
    _input("ReportDCM", "QueryDCM", DIGITAL_CONTROL, {
        "device": Computed(lambda f: f"dcm_{f['dcm_reference']}", "dcm_<dcm_reference>"),
        "code": From("dcm_reference"),
        "state": From("dcm_state_code", label({0: "PRESSED", 1: "RELEASED"}))}),
    _input("ReportKeyboardAction", "QueryKeyboardAction", KEYBOARD, {
        "device": Const("keyboard"), "code": From("key"),
        "state": From("key_state", label({0: "RELEASED", 1: "PRESSED"}))}),
    _input("ReportPointingDeviceAction", "QueryPointingDeviceAction", POINTING_DEVICE, {
        "device": Const("pointer"), "state": Computed(_button, "button + state"),
        "x": From("x", float, note="px"), "y": From("y", float, note="px"),
        "valid": Computed(_valid, "valid == Valid")}),
    _input("ReportPointingDeviceMovement", "QueryPointingDeviceMovement", POINTING_DEVICE, {
        "device": Const("pointer"),
        "x": From("x", float, note="px"), "y": From("y", float, note="px"),
        "valid": Computed(_valid, "valid == Valid")}),
    _input("ReportAnalogAction", "QueryAnalogAction", ANALOG_CONTROL, {
        "device": Computed(lambda f: f"analog_{f['reference']}", "analog_<reference>"),
        "code": From("reference"),
        "x": _axis("longitudinal"), "y": _axis("lateral"), "z": _axis("vertical"),
        "roll": _axis("roll"), "pitch": _axis("pitch"), "yaw": _axis("yaw")},
        query_fields={"presence_vector": 0x3F, "analog_reference": ANALOG_DEVICE},
        doc=f"every change (an event) of device {ANALOG_DEVICE}: the query names one "
            f"device; events of others are translated too"),
    _input("ReportAnalogDevices", "QueryAnalogDevices", ANALOG_CONTROL, {
        "device": Computed(lambda e: f"analog_{e['reference']}", "analog_<reference>"),
        "code": From("reference"), "name": From("name", default="")},
        split="report_analog_devices_list", doc="one sample per device: its name"),
)

_DRAWING = ("a vehicle's remote display: graphics commands (pages, pens, labels) over "
            "data structures it references; operator stations draw their own displays from "
            "the typed topics instead")
NOT_TRANSLATED: tuple[tuple[str, str], ...] = (
    ("ReportDrawingDefinition", _DRAWING),
    ("ReportDataDefinition", _DRAWING),
    ("ReportData", _DRAWING),
    ("QueryDrawingDefinition", "Drawing is not read (see ReportDrawingDefinition)"),
    ("QueryDataDefinition", "Drawing is not read (see ReportDrawingDefinition)"),
    ("QueryData", "Drawing is not read (see ReportDrawingDefinition)"),
    ("SetDCM", "a remote asset styles a button on an operator interface offering "
               "DigitalControl; the relay offers no services, so none is sent to it, and "
               "styling another station's buttons is not an operator's command"),
)


class HmiTranslator(RuleTranslator):
    """HMI input devices -> ``HmiInput``; the rest listed with its reason."""

    name = "hmi"
    report_rules = REPORT_RULES
    not_translated = NOT_TRANSLATED
