"""Table-driven tests of the mobility translator: report in -> sample out, sample in -> command.

Reports are built from real bytes (captures) or encoded by the catalogue, so the field
names are the generated ones.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Command, Publish
from edge_vis.kit.contract import TranslatorContext, VehicleView
from translators.mobility import MobilityTranslator

CAT = default_catalogue()
VIEW = VehicleView("ugv1", 150, name="UGV", address=JausAddress(150, 1, 1), online=True)
CTX = TranslatorContext(now=10.0, timestamp_ms=1_700_000_000_123, relay_id=JausAddress(42, 1, 1),
                        vehicle=VIEW, catalogue=CAT)
NAN = math.nan

# (payload hex from captures-jauspp.md / captures.md, topic, expected sample fields)
REPORT_CASES = [
    pytest.param(
        "02444701178696a8655e2146083f0f395e94402dd1b2", "GlobalPose",
        {"latitude": 28.538426, "longitude": -81.3792, "altitude": 30.0, "roll": NAN,
         "pitch": NAN, "yaw": 0.5}, id="jauspp-global-pose"),
    pytest.param(
        "03444300ffffff7fffffff7fff7f", "LocalPose",
        {"x": 0.0, "y": 0.0, "z": NAN, "roll": NAN, "pitch": NAN, "yaw": 0.0},
        id="jts-local-pose"),
    pytest.param(
        "044441013280328000808a39d1b2", "Velocity",
        {"vx": 0.5, "vy": NAN, "vz": NAN, "roll_rate": NAN, "pitch_rate": NAN,
         "yaw_rate": 0.0}, id="jauspp-velocity"),
]


@pytest.mark.parametrize(("payload", "topic", "expected"), REPORT_CASES)
def test_report_to_sample(payload: str, topic: str, expected: dict[str, float]) -> None:
    message = CAT.decode(bytes.fromhex(payload))
    actions = MobilityTranslator().on_message(message.name, message.fields, CTX)
    assert len(actions) == 1 and isinstance(actions[0], Publish)
    assert actions[0].topic == topic
    sample = actions[0].sample
    assert sample["vehicle_id"] == "ugv1"
    assert sample["timestamp_ms"] == 1_700_000_000_123
    for key, value in expected.items():
        if math.isnan(value):
            assert math.isnan(sample[key]), key
        else:
            assert sample[key] == pytest.approx(value, abs=1e-3), key


ZERO6 = dict.fromkeys(("propulsive_linear_effort_x", "propulsive_linear_effort_y",
                       "propulsive_linear_effort_z", "propulsive_rotational_effort_x",
                       "propulsive_rotational_effort_y", "propulsive_rotational_effort_z"), 0.0)
STOP = {"WrenchEffortCommand": ZERO6}

# (topic, sample, expected message name, expected fields, service suffix)
COMMAND_CASES = [
    pytest.param(
        "WrenchEffortCommand",
        {"propulsive_linear_x": 40.0, "propulsive_rotational_z": -25.5,
         "propulsive_linear_y": None},
        "SetWrenchEffort",
        {"propulsive_linear_effort_x": 40.0, "propulsive_rotational_effort_z": -25.5},
        "PrimitiveDriver", id="wrench-absent-fields-left-out"),
    pytest.param(
        "WrenchEffortCommand", {"propulsive_linear_x": 250.0, "propulsive_linear_y": -101,
                                "resistive_linear_x": -5.0, "resistive_rotational_z": 30.0},
        "SetWrenchEffort",
        {"propulsive_linear_effort_x": 100.0, "propulsive_linear_effort_y": -100.0,
         "resistive_linear_effort_x": 0.0, "resistive_rotational_effort_z": 30.0},
        "PrimitiveDriver", id="wrench-clamped"),
    pytest.param(
        "VelocityCommand", {"vx": 1.5, "yaw_rate": 0.25}, "SetVelocityCommand",
        {"command_type": 0, "velocity_x": 1.5, "velocity_y": 0.0, "velocity_z": 0.0,
         "roll_rate": 0.0, "pitch_rate": 0.0, "yaw_rate": 0.25},
        "VelocityStateDriver", id="velocity"),
]


@pytest.mark.parametrize(("topic", "sample", "name", "fields", "service"), COMMAND_CASES)
def test_sample_to_command(topic: str, sample: dict[str, Any], name: str,
                           fields: dict[str, Any], service: str) -> None:
    actions = MobilityTranslator().on_sample(
        topic, {"vehicle_id": "ugv1", "operator_id": "op1", **sample}, CTX)
    assert len(actions) == 1 and isinstance(actions[0], Command)
    command = actions[0]
    assert (command.vehicle_id, command.operator_id, command.name) == ("ugv1", "op1", name)
    assert dict(command.fields) == fields
    assert command.service == f"urn:jaus:jss:mobility:{service}"
    assert command.stop is not None and all(v == 0 for v in command.stop.values())
    if topic in STOP:
        assert dict(command.stop) == STOP[topic]
    # and the command really encodes
    payload = CAT.encode(name, command.fields)
    assert CAT.decode(payload).name == name


def test_wrench_without_any_effort_is_ignored() -> None:
    sample = {"vehicle_id": "ugv1", "operator_id": "op1", "propulsive_linear_x": None}
    assert MobilityTranslator().on_sample("WrenchEffortCommand", sample, CTX) == []


def test_wanted_reports_query_all_fields_and_encode() -> None:
    for spec in MobilityTranslator.reports:
        payload = CAT.encode(spec.query, spec.query_fields)
        # pose, velocity, acceleration, waypoints, path segments: every optional field of
        # the report; the list drivers' queries (QueryActiveElement...) have no fields
        optional = [f for f in CAT.by_name(spec.report).body.fields if f.optional]
        expected = {"presence_vector": (1 << len(optional)) - 1} if spec.query_fields else {}
        assert CAT.decode(payload).fields == expected
        assert spec.report in MobilityTranslator.messages
