"""The iop translator: platform state/mode, health, resources, paths, measurements."""

from __future__ import annotations

from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, check_command_rule, check_report_rule, command_sample

from edge_vis.dds.convert import converter_for
from edge_vis.kit import CommandRule
from translators.iop import IopTranslator

TR = IopTranslator
REPORTS = TR.report_rules
COMMANDS = TR.command_rules


@pytest.mark.parametrize("rule", REPORTS, ids=[r.message for r in REPORTS])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


@pytest.mark.parametrize(("rule", "values", "expected"), [
    (COMMANDS[0], {"platform_state": "operational", "platform_mode": ""}, {"platform_state": 1}),
    (COMMANDS[1], {"platform_mode": "Maintenance", "platform_state": ""}, {"platform_mode": 2}),
    (COMMANDS[2], {"update_health": True, "platform_state": "", "platform_mode": ""}, {}),
    (COMMANDS[3], {"url": "rtsp://10.0.0.9/cam", "server_type": "rtsp", "request_id": 4,
                   "jaus_address": "150.1.3", "resource_id": 2},
     {"request_id_rec": {"request_id": 4}, "digital_resource_endpoint_rec": {
         "server_type": 0, "server_url": "rtsp://10.0.0.9/cam", "resource_id": 2,
         "jaus_id": {"subsystem_id": 150, "node_id": 1, "component_id": 3}}}),
    (COMMANDS[4], {"endpoint_id": 17, "request_id": 5}, {"id": 17, "request_id": 5}),
], ids=[c.message for c in COMMANDS])
def test_every_declared_command(rule: CommandRule, values: dict[str, Any],
                                expected: dict[str, Any]) -> None:
    command = check_command_rule(TR(), rule, command_sample(rule, **values))
    assert dict(command.fields) == expected and command.stop is None


def test_platform_command_state_and_mode_or_nothing() -> None:
    base = {"vehicle_id": "veh1", "operator_id": "op1"}
    both = TR().on_sample("PlatformCommand", {**base, "platform_state": "Emergency",
                                              "platform_mode": "Training"}, CTX)
    assert [(c.name, dict(c.fields)) for c in both] == [
        ("SetPlatformState", {"platform_state": 4}), ("SetPlatformMode", {"platform_mode": 1})]
    assert TR().on_sample("PlatformCommand", base, CTX) == []  # empty = unchanged
    assert TR().on_sample("PlatformCommand", {**base, "platform_state": "Flying"}, CTX) == []


def decoded(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    return CAT.decode(CAT.encode(name, fields)).fields or {}


def test_platform_status_merges_state_mode_and_answers() -> None:
    tr = TR()
    (a,) = tr.on_message("ReportPlatformState",
                         decoded("ReportPlatformState", {"platform_state": 1}), CTX)
    assert a.sample["platform_state"] == "Operational" and "platform_mode" not in a.sample
    (b,) = tr.on_message("ReportPlatformMode", decoded("ReportPlatformMode", {
        "platform_mode": 1, "status": 1}), CTX)
    assert (b.sample["platform_state"], b.sample["platform_mode"], b.sample["mode_status"]) \
        == ("Operational", "Training", "Active")
    (c,) = tr.on_message("ConfirmPlatformStateRequest", decoded(
        "ConfirmPlatformStateRequest", {"platform_state": 3, "response_code": 1}), CTX)
    assert (c.sample["platform_state"], c.sample["last_response"]) == ("System_Abort",
                                                                       "InvalidState")
    assert c.sample["platform_mode"] == "Training"
    (d,) = tr.on_message("ReportSupportedPlatformModes", decoded(
        "ReportSupportedPlatformModes", {"supported_platform_modes_list": [
            {"platform_mode": 0}, {"platform_mode": 2}]}), CTX)
    assert d.sample["supported_modes"] == ["Standard_Operating", "Maintenance"]
    converter_for(TYPES["PlatformStatus"]).to_struct(d.sample, "PlatformStatus")
    # another vehicle starts from scratch
    from dataclasses import replace

    other = replace(CTX, vehicle=replace(CTX.vehicle, vehicle_id="veh2"))
    (e,) = tr.on_message("ReportPlatformMode", decoded("ReportPlatformMode", {
        "platform_mode": 0, "status": 0}), other)
    assert "platform_state" not in e.sample


def test_health_summary() -> None:
    fields = decoded("ReportUGVSummary", {
        "ugv_severity_rec": {"severity": 3},
        "severity_list": [
            {"node_id": {"node_id": 1}, "severity_rec": {"severity": 2}},
            {"node_id": {"node_id": 2}, "severity_rec": {"severity": 1}},
            {"node_id": {"node_id": 7}, "severity_rec": {"severity": 4}}]})
    (action,) = TR().on_message("ReportUGVSummary", fields, CTX)
    assert action.topic == "HealthStatus"
    assert action.sample["level"] == "HEALTH_FAULT"
    assert action.sample["faults"] == ["node 1: WARN", "node 7: FAIL"]
    converter_for(TYPES["HealthStatus"]).to_struct(action.sample, "HealthStatus")


def test_digital_resources_one_per_endpoint() -> None:
    fields = decoded("ReportDigitalResourceEndpoint", {"digital_resource_endpoint_list": [
        {"server_type": 0, "server_url": "rtsp://10.0.0.5/front",
         "jaus_id": {"component_id": 3, "node_id": 2, "subsystem_id": 150}, "resource_id": 9},
        {"server_type": 5, "server_url": "http://10.0.0.5/logs"}]})
    samples = [a.sample for a in TR().on_message("ReportDigitalResourceEndpoint", fields, CTX)]
    assert [(s["url"], s["server_type"], s["jaus_address"], s["resource_id"])
            for s in samples] == [("rtsp://10.0.0.5/front", "RTSP", "150.2.3", 9),
                                  ("http://10.0.0.5/logs", "HTTP", "", -1)]


def test_planned_local_path() -> None:
    fields = decoded("ReportPath", {"path_var": {"planned_local_path": [
        {"x": 1.0, "y": -2.0}, {"x": 3.5, "y": 0.0, "z": -1.0}]}})
    (action,) = TR().on_message("ReportPath", fields, CTX)
    sample = action.sample
    assert (sample["path_type"], sample["frame"]) == ("PlannedLocalPath", "LOCAL")
    flat = [p[axis] for p in sample["points"] for axis in ("x", "y", "z")]
    assert flat == pytest.approx([1.0, -2.0, 0.0, 3.5, 0.0, -1.0], abs=1e-3)
    converter_for(TYPES["PathReport"]).to_struct(sample, "PathReport")


def test_measurement() -> None:
    fields = decoded("ReportMeasurement", {
        "device_rec": {"device_name": "gas", "classification": "CO2"},
        "readings_list": [{"reading_rec": {"sensor": "s1", "source": "air", "type": "ppm",
                                           "alert_level": 2},
                           "value_list": [{"value": 412.5}, {"value": -3.0}]}],
        "global_pose_rec": {"latitude": 48.1, "longitude": 11.5}})
    (action,) = TR().on_message("ReportMeasurement", fields, CTX)
    sample = action.sample
    assert sample["device"] == "gas" and sample["classification"] == "CO2"
    reading = sample["readings"][0]
    assert reading["alert_level"] == "MIDDLE" and reading["unit"] == ""
    assert reading["values"] == pytest.approx([412.5, -3.0], abs=1e-3)
    assert sample["latitude"] == pytest.approx(48.1, abs=1e-6)
    assert sample["altitude"] != sample["altitude"]  # not reported: NaN


@pytest.mark.parametrize("sample", [
    {"action": "REGISTER", "url": ""},
    {"action": "REGISTER", "url": "ftp://x", "server_type": "GOPHER"},
    {"action": "REGISTER", "url": "ftp://x", "jaus_address": "150.1"},
])
def test_bad_resource_registrations_are_refused(sample: dict[str, Any]) -> None:
    assert TR().on_sample("DigitalResourceCommand", {"vehicle_id": "veh1",
                                                     "operator_id": "op1", **sample}, CTX) == []


def test_handoff_status_from_the_vehicle_view() -> None:
    from dataclasses import replace

    from edge_vis.kit import HandoffView

    view = replace(CTX.vehicle, controller="op1", handoff_timeout=30.0, handoffs=(
        HandoffView(3, "op2", 20, "survey", "PENDING"),
        HandoffView(4, "jaus:300.1.5", 9, "", "DENIED", "refused by op1", "150.1.1")))
    (status,) = TR().on_vehicle("handoff", replace(CTX, vehicle=view))
    sample = status.sample
    assert (sample["holder"], sample["handoff_timeout"]) == ("op1", 30.0)
    assert [(r["request_id"], r["requester"], r["state"], r["via"])
            for r in sample["requests"]] == [(3, "op2", "PENDING", ""),
                                              (4, "jaus:300.1.5", "DENIED", "150.1.1")]
    converter_for(TYPES["HandoffStatus"]).to_struct(sample, "HandoffStatus")
    # control changes without requests publish nothing
    assert TR().on_vehicle("control", CTX) == []
