"""Table-driven tests of the core translator: vehicle changes and reports -> samples."""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Publish
from edge_vis.kit.contract import HolderView, TranslatorContext, VehicleView
from translators.core import CoreTranslator

BASE = VehicleView(
    "SimulatedVehicle-126", 126, name="SimulatedVehicle", vehicle_type="VEHICLE",
    address=JausAddress(126, 1, 199),
    services=(("urn:jaus:jss:mobility:LocalPoseSensor", "1.0"),), online=True,
    state="STANDBY", link="radio", last_seen=5.0, last_seen_ms=1_700_000_005_000,
)


def ctx(**changes: Any) -> TranslatorContext:
    from dataclasses import replace

    return TranslatorContext(now=5.0, timestamp_ms=1_700_000_005_000,
                             relay_id=JausAddress(42, 1, 1), vehicle=replace(BASE, **changes))


NO_ESTOP = {"emergency": False, "emergency_operator": "", "emergency_reason": ""}

CASES = [
    pytest.param("identified", {}, "VehicleIdentification", {
        "vehicle_id": "SimulatedVehicle-126", "name": "SimulatedVehicle", "jaus_subsystem": 126,
        "jaus_address": "126.1.199", "vehicle_type": "VEHICLE",
        "services": [{"uri": "urn:jaus:jss:mobility:LocalPoseSensor", "version": "1.0"}]},
        id="identification"),
    pytest.param("online", {"relay": "201.1.1"}, "VehicleStatus", {
        "vehicle_id": "SimulatedVehicle-126", "state": "STANDBY", "link": "radio",
        "online": True, "last_seen_ms": 1_700_000_005_000, **NO_ESTOP, "relay": "201.1.1"},
                 id="online"),
    pytest.param("offline", {"online": False, "state": "OFFLINE"}, "VehicleStatus", {
        "vehicle_id": "SimulatedVehicle-126", "state": "OFFLINE", "link": "radio",
        "online": False, "last_seen_ms": 1_700_000_005_000, **NO_ESTOP, "relay": ""},
                 id="offline"),
    pytest.param("control", {}, "ControlStatus", {
        "vehicle_id": "SimulatedVehicle-126", "operator_id": "", "authority": 0,
        "state": "NOT_CONTROLLED", "rejected_commands": 0, "last_rejection": "",
        "timestamp_ms": 1_700_000_005_000, "emergency": False, "holders": []}, id="free"),
    pytest.param("control", {"controller": "op1", "controller_authority": 7,
                             "jaus_control": "controlled", "holders": (
                                 HolderView(JausAddress(126, 1, 1), JausAddress(42, 1, 1), 7,
                                            7, True),
                                 HolderView(JausAddress(126, 1, 2), JausAddress(9, 1, 1), 200,
                                            200, False),
                                 HolderView(JausAddress(126, 1, 3), None, 0, 5, False))},
                 "ControlStatus", {
        "vehicle_id": "SimulatedVehicle-126", "operator_id": "op1", "authority": 7,
        "state": "CONTROLLED", "rejected_commands": 0, "last_rejection": "",
        "timestamp_ms": 1_700_000_005_000, "emergency": False, "holders": [
            {"component": "126.1.1", "controller": "42.1.1", "authority": 7,
             "current_authority": 7, "is_relay": True},
            {"component": "126.1.2", "controller": "9.1.1", "authority": 200,
             "current_authority": 200, "is_relay": False},
            {"component": "126.1.3", "controller": "", "authority": 0,
             "current_authority": 5, "is_relay": False}]}, id="held"),
    pytest.param("control", {"controller": "op1", "controller_authority": 7,
                             "jaus_control": "requesting", "rejected_commands": 3,
                             "last_rejection": "SetWrenchEffort from op2 refused"},
                 "ControlStatus", {
        "vehicle_id": "SimulatedVehicle-126", "operator_id": "op1", "authority": 7,
        "state": "REQUESTED", "rejected_commands": 3,
        "last_rejection": "SetWrenchEffort from op2 refused",
        "timestamp_ms": 1_700_000_005_000, "emergency": False,
        "holders": []}, id="requested-with-rejections"),
    pytest.param("control", {"controller": "op1", "jaus_control": "refused"}, "ControlStatus", {
        "vehicle_id": "SimulatedVehicle-126", "operator_id": "op1", "authority": 0,
        "state": "REJECTED", "rejected_commands": 0, "last_rejection": "",
        "timestamp_ms": 1_700_000_005_000, "emergency": False,
        "holders": []}, id="vehicle-refused"),
    pytest.param("emergency", {"emergency": True, "emergency_operator": "op1",
                               "emergency_reason": "set by op1", "state": "EMERGENCY"},
                 "VehicleStatus", {
        "vehicle_id": "SimulatedVehicle-126", "state": "EMERGENCY", "link": "radio",
        "online": True, "last_seen_ms": 1_700_000_005_000, "emergency": True,
        "emergency_operator": "op1", "emergency_reason": "set by op1", "relay": ""},
                 id="emergency"),
]


@pytest.mark.parametrize(("change", "view", "topic", "sample"), CASES)
def test_vehicle_change_to_sample(change: str, view: dict[str, Any], topic: str,
                                  sample: dict[str, Any]) -> None:
    actions = CoreTranslator().on_vehicle(change, ctx(**view))
    assert actions[0] == Publish(topic, sample)
    # an emergency stop shows in ControlStatus too
    assert [a.topic for a in actions[1:]] == (["ControlStatus"] if change == "emergency" else [])


@pytest.mark.parametrize("name", ["ReportStatus", "ReportHeartbeatPulse"])
def test_status_and_heartbeat_publish_vehicle_status(name: str) -> None:
    actions = CoreTranslator().on_message(name, {"status": 2, "reserved": 0}, ctx())
    assert [a.topic for a in actions if isinstance(a, Publish)] == ["VehicleStatus"]
    assert actions[0].sample["state"] == "STANDBY"


def test_a_relay_taking_a_vehicle_over_publishes_its_whole_state() -> None:
    actions = CoreTranslator().on_vehicle("serving", ctx(relay="202.1.1"))
    assert [a.topic for a in actions] == ["VehicleIdentification", "VehicleStatus",
                                          "ControlStatus"]
    assert actions[1].sample["relay"] == "202.1.1"


def test_status_change_is_not_published_twice() -> None:
    assert CoreTranslator().on_vehicle("status", ctx()) == []
