"""The ugv translator: odometry, platform, power plants and devices; device commands."""

from __future__ import annotations

import math
from typing import Any

import pytest
from rulekit import CAT, CTX, check_command_rule, check_report_rule, command_sample

from edge_vis.cli.mappings import collect
from edge_vis.kit import CommandRule
from translators.ugv import NOT_TRANSLATED, UgvTranslator

TR = UgvTranslator
REPORTS = TR.report_rules
COMMANDS = TR.command_rules


@pytest.mark.parametrize("rule", REPORTS, ids=[r.message for r in REPORTS])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


COMMAND_CASES: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "SetSkidSteerEffort": ({"left_effort": 140.0, "right_effort": -35.5},
                           {"left_side_propulsive_effort": 100.0,
                            "right_side_propulsive_effort": -35.5}),
    "SetAckermannConfiguration": (
        {"steering_angle": 2.0, "throttle_effort": 40.0, "brake_effort": -3.0,
         "max_steering_rate": 0.5},
        {"steering_angle": math.pi / 2, "throttle_effort": 40.0, "brake_effort": 0.0,
         "max_steering_rate": 0.5}),
    "SetParkingBrake": ({"value": 130.0}, {"parking_brake": 100.0}),
    "SetIlluminationState": (
        {"state": "Headlights, brake_lights, variable_light1=7, variable_light2"},
        {"illumination": {"headlights": 1, "brake_lights": 1, "variable_light1": 7,
                          "variable_light2": 15}}),
    "SetTransmissionState": ({"state": "drive"}, {"transmission_state": 4}),
    "SetTransferCaseState": ({"state": "AUTO_4WD"}, {"transfer_case_state": 2}),
    "SetAnnunciatorState": ({"state": "horn=3"}, {"annunciator": {"horn": 3}}),
    "ResetOdometry": ({"state": "trip_b"}, {"odometry_type": 3}),
    "SetStabilizerPosition": ({"device": "stabilizer_2", "value": -4.0},
                              {"stabilizer_position": [{"stabilizer_id": 2,
                                                        "position": -math.pi}]}),
    "SetStabilizerEffort": ({"device": "Stabilizer_1_effort", "value": 40.0},
                            {"stabilizer_effort": [{"stabilizer_id": 1, "effort": 40.0}]}),
    "SetPowerPlantConfiguration": (
        {"device": "power_plant_3", "state": "POWER_OFF"},
        {"power_plant_configuration_list": [{
            "power_plant_id": {"power_plant_id": 3},
            "power_plant_configuration_var": {"battery_configuration_rec": {
                "power_state": 2}}}]}),
}


def test_every_command_rule_has_a_case() -> None:
    assert {r.message for r in COMMANDS} == set(COMMAND_CASES)


@pytest.mark.parametrize("rule", COMMANDS, ids=[r.message for r in COMMANDS])
def test_every_declared_command(rule: CommandRule) -> None:
    values, expected = COMMAND_CASES[rule.message]
    command = check_command_rule(TR(), rule, command_sample(rule, **values))
    for key, value in expected.items():
        got = command.fields[key]
        if isinstance(value, dict) and key in ("illumination", "annunciator"):
            # bit fields: the named members set, every other one 0
            assert {k: v for k, v in got.items() if v} == value
        else:
            assert got == value


@pytest.mark.parametrize(("device", "state", "value"), [
    ("transmission", "WARP", 0.0), ("illumination", "laser", 0.0),
    ("odometer", "PLATFORM", 0.0), ("transmission", "", 0.0),
    ("power_plant_1", "ON", 0.0), ("power_plant_256", "POWER_ON", 0.0),
    ("stabilizer_1", "", math.nan)])
def test_bad_device_states_are_refused_not_guessed(device: str, state: str,
                                                   value: float) -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "device": device, "state": state,
              "value": value}
    assert TR().on_sample("DeviceCommand", sample, CTX) == []


def test_unknown_device_is_ignored() -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "device": "flux_capacitor"}
    assert TR().on_sample("DeviceCommand", sample, CTX) == []


def decoded(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    return CAT.decode(CAT.encode(name, fields)).fields or {}


def test_parking_brake_and_transmission_status() -> None:
    tr = TR()
    (brake,) = tr.on_message("ReportParkingBrake", decoded("ReportParkingBrake", {
        "commanded_parking_brake": 100.0, "actual_parking_brake": 0.0}), CTX)
    assert brake.topic == "DeviceStatus"
    assert brake.sample["device"] == "parking_brake" and brake.sample["state"] == "RELEASED"
    assert brake.sample["commanded_value"] == pytest.approx(100.0)
    (gear,) = tr.on_message("ReportTransmissionState", decoded("ReportTransmissionState", {
        "requested_transmission_state": 3, "actual_transmission_state": 1}), CTX)
    assert (gear.sample["state"], gear.sample["commanded_state"]) == ("PARK", "REVERSE")


def test_power_plants_one_sample_each() -> None:
    fields = decoded("ReportPowerPlantStatus", {"power_plant_status_list": [
        {"power_plant_desc_rec": {"power_plant_id": 1, "description": "main battery"},
         "power_plant_status_var": {"battery_status": [{
             "percent_charge_remaining": 81.5, "voltage": 24.2, "battery_temp": -10.0}]}},
        {"power_plant_desc_rec": {"power_plant_id": 2, "description": "generator"},
         "power_plant_status_var": {"diesel_engine_status": {"engine_hours": 1234}}},
    ]})
    actions = TR().on_message("ReportPowerPlantStatus", fields, CTX)
    samples = [a.sample for a in actions if a.topic == "PowerPlantStatus"]
    assert [s["plant_id"] for s in samples] == [1, 2]
    # the battery also fills HealthStatus (merged with the health monitor's level)
    (health,) = [a for a in actions if a.topic == "HealthStatus"]
    assert health.merge == ("vehicle_id",)
    assert health.sample["battery_percent"] == pytest.approx(81.5, abs=0.01)
    assert health.sample["supply_voltage"] == pytest.approx(24.2, abs=0.02)
    assert "level" not in health.sample
    battery, diesel = samples
    assert battery["kind"] == "battery" and battery["description"] == "main battery"
    assert battery["remaining_percent"] == pytest.approx(81.5, abs=0.01)
    assert battery["voltage"] == pytest.approx(24.2, abs=0.02)
    assert battery["temperature"] == pytest.approx(-10.0, abs=0.01)  # below zero
    assert battery["current"] != battery["current"]  # not reported: NaN
    assert diesel["kind"] == "diesel_engine" and diesel["hours"] == 1234.0


def test_odometry_in_metres() -> None:
    (odo,) = TR().on_message("ReportOdometry",
                             decoded("ReportOdometry", {"odom": 2, "odometry": 4_294_967_295}),
                             CTX)
    assert odo.sample["odometer"] == "TRIP_A" and odo.sample["distance"] == 4_294_967_295.0


def test_not_translated_messages_are_listed_by_the_mappings_command() -> None:
    rows = [r for r in collect(only=["ugv"]) if r["direction"] == "none"]
    assert {r["message"] for r in rows} == {name for name, _ in NOT_TRANSLATED}
    assert all(name in CAT for name, _ in NOT_TRANSLATED)  # real UGV messages


def test_drive_commands_are_motion_commands_with_safe_stops() -> None:
    base = {"vehicle_id": "veh1", "operator_id": "op1"}
    (skid,) = TR().on_sample("SkidSteerCommand", {**base, "left_effort": 30.0,
                                                  "right_effort": 30.0}, CTX)
    assert skid.stop == {"left_side_propulsive_effort": 0.0,
                         "right_side_propulsive_effort": 0.0}
    (ack,) = TR().on_sample("AckermannCommand", {**base, "steering_angle": 0.3,
                                                 "throttle_effort": 60.0,
                                                 "brake_effort": 0.0}, CTX)
    assert "max_steering_rate" not in ack.fields  # absent: left out
    assert ack.stop == {"steering_angle": pytest.approx(0.3), "throttle_effort": 0.0,
                        "brake_effort": 100.0}


def test_capabilities() -> None:
    tr = TR()
    (lights,) = tr.on_message("ReportIlluminationConfiguration", decoded(
        "ReportIlluminationConfiguration", {"types": {"headlights": 1, "ir_light_source": 1}}),
        CTX)
    assert (lights.topic, lights.sample["device"], lights.sample["supported"]) == (
        "DeviceCapabilities", "illumination", ["headlights", "ir_light_source"])
    gears, case = tr.on_message("ReportTransmissionCapabilities", decoded(
        "ReportTransmissionCapabilities", {"transmission_bf": {"park": 1, "drive": 1,
                                                               "reverse": 1},
                                           "transfer_case_bf": {"high_awd": 1}}), CTX)
    assert gears.sample["supported"] == ["park", "reverse", "drive"]
    assert (case.sample["device"], case.sample["supported"]) == ("transfer_case",
                                                                 ["high_awd"])
    (flipper,) = tr.on_message("ReportStabilizerCapabilities", decoded(
        "ReportStabilizerCapabilities", {"stabilizer_capabilities": [{
            "stabilizer_capabilities_rec": {"stabilizer_id": 2, "maximum_up_angle": 1.5,
                                            "maximum_down_angle": -0.5},
            "stabilizer_dimensions_list": [{"point_x": 0.4, "point_y": -0.2,
                                            "point_z": 0.0}]}]}), CTX)
    assert flipper.sample["device"] == "stabilizer_2"
    assert [(x["name"], x["text"]) for x in flipper.sample["limits"]] == [
        ("maximum_up_angle", "rad"), ("maximum_down_angle", "rad")]
    assert flipper.sample["limits"][1]["number"] == pytest.approx(-0.5, abs=1e-4)
    assert flipper.sample["points"][0]["x"] == pytest.approx(0.4, abs=1e-3)
    (plant,) = tr.on_message("ReportPowerPlantCapabilities", decoded(
        "ReportPowerPlantCapabilities", {"power_plant_capabilities_list": [{
            "power_plant_desc_rec": {"power_plant_id": 4, "description": "genset"},
            "power_plant_capabilities_var": {"diesel_engine_capabilities_rec": {
                "fuel_capacity": 40.0}}}]}), CTX)
    assert (plant.sample["device"], plant.sample["supported"]) == ("power_plant_4",
                                                                   ["diesel_engine"])
    assert plant.sample["limits"][0]["name"] == "fuel_capacity"
    assert plant.sample["limits"][0]["text"] == "l"
