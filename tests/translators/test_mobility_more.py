"""The mobility translator beyond pose and waypoints: driver states, vectors, limits,
magnetic variation and pose resets.

Reports come from real bytes (hand-written payloads, or fields encoded by the catalogue)
and must give the listed sample; samples must give exactly the listed command, which the
catalogue must encode, and whose values survive the JSIDL scaling. Edge cases sit on the
scaled limits of each field.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, check_command_rule, check_report_rule, command_sample

from edge_vis.dds.convert import converter_for
from edge_vis.errors import ConfigError
from edge_vis.kit.actions import Command, Publish
from translators.mobility import (
    COMMAND_RULES,
    OPTIONAL_REPORTS,
    REPORT_RULES,
    MobilityTranslator,
    wrap_angle,
)

NAN = math.nan
PI = math.pi
MOB = "urn:jaus:jss:mobility:"
NEW_REPORTS = ("ReportWrenchEffort", "ReportVelocityCommand", "ReportGlobalVector",
               "ReportLocalVector", "ReportAccelerationLimit", "ReportGeomagneticProperty")
NEW_COMMANDS = ("SetGlobalVector", "SetLocalVector", "SetAccelerationLimit", "SetGlobalPose",
                "SetLocalPose")


def _close(got: Any, want: Any, tol: float) -> bool:
    if isinstance(want, float) and math.isnan(want):
        return isinstance(got, float) and math.isnan(got)
    if isinstance(want, float) or isinstance(got, float):
        return math.isclose(float(got), float(want), abs_tol=tol)
    return bool(got == want)


def _publish(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    (action,) = MobilityTranslator().on_message(name, fields, CTX)
    assert isinstance(action, Publish)
    converter_for(TYPES[action.topic]).to_struct(dict(action.sample), action.topic)
    return {"topic": action.topic, **action.sample}


# ------------------------------------------------------------------ JAUS bytes -> samples

# (hand-written payload: code LE + body, expected topic, expected members, tolerance)
BYTE_CASES = [
    pytest.param("12440000", "GeomagneticProperty", {"magnetic_variation": -PI}, 1e-9,
                 id="magvar-raw-0-is-minus-pi"),
    pytest.param("1244ffff", "GeomagneticProperty", {"magnetic_variation": PI}, 1e-9,
                 id="magvar-raw-max-is-pi"),
    # pv 0x05: speed (raw 0xFFFF = 327.67 m/s) and heading (raw 0 = -pi); the rest absent
    pytest.param("074405ffff0000", "VectorState",
                 {"frame": "GLOBAL", "speed": 327.67, "heading": -PI, "altitude": NAN,
                  "z": NAN, "roll": NAN, "pitch": NAN}, 1e-9, id="global-vector-limits"),
    # pv 0x02: z only, raw 0 = -10000 m
    pytest.param("08440200000000", "VectorState",
                 {"frame": "LOCAL", "z": -10_000.0, "speed": NAN, "heading": NAN,
                  "altitude": NAN}, 1e-9, id="local-vector-z-lower-limit"),
    # pv 0x0001 with propulsive linear x raw 0 = -100 %; pv bit 6 resistive x raw 255 = 100 %
    pytest.param("054441000000ff", "WrenchEffortState",
                 {"propulsive_linear_x": -100.0, "resistive_linear_x": 100.0,
                  "propulsive_linear_y": NAN, "resistive_rotational_z": NAN}, 1e-9,
                 id="wrench-effort-limits"),
]


@pytest.mark.parametrize(("payload", "topic", "expected", "tol"), BYTE_CASES)
def test_report_bytes_to_sample(payload: str, topic: str, expected: dict[str, Any],
                                tol: float) -> None:
    message = CAT.decode(bytes.fromhex(payload))
    sample = _publish(str(message.name), message.fields or {})
    assert sample["topic"] == topic
    assert sample["vehicle_id"] == "veh1" and sample["timestamp_ms"] == CTX.timestamp_ms
    for member, want in expected.items():
        assert _close(sample[member], want, tol), (member, sample[member], want)


# (report, fields encoded by the catalogue, topic, expected members, tolerance)
FIELD_CASES = [
    pytest.param("ReportWrenchEffort",
                 {"propulsive_linear_effort_x": 100.0, "propulsive_rotational_effort_z": -37.5,
                  "resistive_linear_effort_z": 0.0},
                 "WrenchEffortState",
                 {"propulsive_linear_x": 100.0, "propulsive_rotational_z": -37.5,
                  "resistive_linear_z": 0.0, "propulsive_linear_y": NAN}, 5e-3,
                 id="wrench-effort"),
    pytest.param("ReportVelocityCommand",
                 {"command_type": 0, "velocity_x": -327.68, "yaw_rate": 32.767},
                 "VelocityCommandState",
                 {"command_type": "CURRENT", "vx": -327.68, "yaw_rate": 32.767, "vy": NAN},
                 1e-3, id="velocity-command-current-limits"),
    pytest.param("ReportVelocityCommand", {"command_type": 1, "velocity_x": 5.0},
                 "VelocityCommandState", {"command_type": "MAXIMUM", "vx": 5.0}, 1e-3,
                 id="velocity-command-maximum"),
    pytest.param("ReportGlobalVector",
                 {"speed": 1.5, "altitude": 35_000.0, "heading": 0.5, "roll": 0.0,
                  "pitch": -0.1},
                 "VectorState",
                 {"frame": "GLOBAL", "speed": 1.5, "altitude": 35_000.0, "heading": 0.5,
                  "roll": 0.0, "pitch": -0.1, "z": NAN}, 1e-3, id="global-vector"),
    pytest.param("ReportLocalVector", {"speed": 0.0, "z": -2.5, "heading": PI},
                 "VectorState",
                 {"frame": "LOCAL", "speed": 0.0, "z": -2.5, "heading": PI, "altitude": NAN},
                 1e-3, id="local-vector"),
    pytest.param("ReportAccelerationLimit",
                 {"command_type": 1, "acceleration_x": 1310.68,
                  "yaw_acceleration": -13106.8},
                 "AccelerationLimit",
                 {"limit": "MAXIMUM", "ax": 1310.68, "yaw_acceleration": -13106.8, "ay": NAN},
                 1e-2, id="acceleration-limit-maximum"),
    pytest.param("ReportAccelerationLimit", {"command_type": 2, "acceleration_z": -0.5},
                 "AccelerationLimit", {"limit": "MINIMUM", "az": -0.5}, 1e-3,
                 id="acceleration-limit-minimum"),
    pytest.param("ReportGeomagneticProperty", {"magnetic_variation": -0.2},
                 "GeomagneticProperty", {"magnetic_variation": -0.2}, 1e-4,
                 id="magnetic-variation"),
]


@pytest.mark.parametrize(("report", "fields", "topic", "expected", "tol"), FIELD_CASES)
def test_report_fields_to_sample(report: str, fields: dict[str, Any], topic: str,
                                 expected: dict[str, Any], tol: float) -> None:
    decoded = CAT.decode(CAT.encode(report, fields))
    sample = _publish(report, decoded.fields or {})
    assert sample["topic"] == topic
    for member, want in expected.items():
        assert _close(sample[member], want, tol), (member, sample[member], want)


@pytest.mark.parametrize("rule", [r for r in REPORT_RULES if r.message in NEW_REPORTS],
                         ids=lambda r: r.message)
def test_new_report_rules_hold_on_random_reports(rule: Any) -> None:
    """Every declared member, for random reports with few or most optional fields."""
    assert check_report_rule(MobilityTranslator(), rule) == 6


def test_every_new_row_is_in_the_mapping_table() -> None:
    rows = MobilityTranslator().describe()
    reports = {r["message"] for r in rows if r["direction"] == "jaus->dds"}
    commands = {r["message"] for r in rows if r["direction"] == "dds->jaus"}
    assert set(NEW_REPORTS) <= reports and set(NEW_COMMANDS) <= commands
    assert {r.message for r in COMMAND_RULES} <= commands


# ------------------------------------------------------------------ samples -> commands

# (topic, sample members, message, exact fields, tolerance after encoding)
COMMAND_CASES = [
    pytest.param("VectorCommand", {"frame": "GLOBAL", "speed": 400.0, "heading": 3.5,
                                   "altitude": 50_000.0},
                 "SetGlobalVector",
                 {"speed": 327.67, "heading": 3.5 - 2 * PI, "altitude": 35_000.0}, 1e-3,
                 id="global-vector-clamped-and-wrapped"),
    pytest.param("VectorCommand", {"frame": "LOCAL", "heading": -PI, "z": -12_000.0,
                                   "pitch": 0.25},
                 "SetLocalVector", {"heading": -PI, "z": -10_000.0, "pitch": 0.25}, 1e-3,
                 id="local-vector"),
    pytest.param("VectorCommand", {"frame": 1, "speed": -1.0},
                 "SetLocalVector", {"speed": 0.0}, 1e-9, id="local-by-number-speed-floor"),
    pytest.param("AccelerationLimitCommand",
                 {"limit": "maximum", "ax": 2000.0, "yaw_acceleration": -20_000.0},
                 "SetAccelerationLimit",
                 {"command_type": 1, "acceleration_x": 1310.68,
                  "yaw_acceleration": -13106.8}, 1e-2, id="acceleration-limit-clamped"),
    pytest.param("AccelerationLimitCommand", {"limit": "MINIMUM", "az": -0.5},
                 "SetAccelerationLimit", {"command_type": 2, "acceleration_z": -0.5}, 1e-3,
                 id="acceleration-limit-minimum"),
    pytest.param("PoseCommand",
                 {"frame": "GLOBAL", "latitude": 91.0, "longitude": -181.0, "altitude": 12.0,
                  "yaw": 7.0, "position_rms": 250.0, "attitude_rms": -1.0},
                 "SetGlobalPose",
                 {"latitude": 90.0, "longitude": -180.0, "altitude": 12.0,
                  "yaw": 7.0 - 2 * PI, "position_rms": 100.0, "attitude_rms": 0.0}, 1e-3,
                 id="global-pose-reset-clamped"),
    pytest.param("PoseCommand", {"frame": "LOCAL", "x": 150_000.0, "y": -3.5, "yaw": 0.5},
                 "SetLocalPose", {"x": 100_000.0, "y": -3.5, "yaw": 0.5}, 1e-3,
                 id="local-pose-reset"),
    pytest.param("PoseCommand", {"magnetic_variation": 4.0}, "SetGeomagneticProperty",
                 {"magnetic_variation": 4.0 - 2 * PI}, 1e-3, id="magnetic-variation-wrapped"),
]


@pytest.mark.parametrize(("topic", "members", "message", "fields", "tol"), COMMAND_CASES)
def test_sample_to_command(topic: str, members: dict[str, Any], message: str,
                           fields: dict[str, Any], tol: float) -> None:
    rule = next(r for r in COMMAND_RULES if r.message == message)
    command = check_command_rule(MobilityTranslator(), rule, command_sample(rule, **members))
    assert command.service_set is None  # these names are unique in the catalogue
    assert set(command.fields) == set(fields)
    for name, want in fields.items():
        assert _close(command.fields[name], want, 1e-9), (name, command.fields[name], want)
    decoded = CAT.decode(CAT.encode(message, command.fields)).fields or {}
    for name, want in fields.items():
        assert _close(decoded[name], want, tol), (name, decoded[name], want)


def test_a_pose_reset_with_magnetic_variation_sets_both() -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "frame": "GLOBAL",
              "latitude": 10.0, "magnetic_variation": -0.2}
    pose, geomagnetic = MobilityTranslator().on_sample("PoseCommand", sample, CTX)
    assert (pose.name, pose.fields) == ("SetGlobalPose", {"latitude": 10.0})
    assert geomagnetic.name == "SetGeomagneticProperty"
    assert geomagnetic.service == MOB + "GlobalPoseSensor" and geomagnetic.stop is None
    assert geomagnetic.fields == {"magnetic_variation": pytest.approx(-0.2)}
    assert pose.kind != geomagnetic.kind  # neither replaces the other in the throttle


def test_vector_commands_are_motion_commands_that_stop_at_speed_zero() -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "frame": "GLOBAL", "speed": 2.0}
    (command,) = MobilityTranslator().on_sample("VectorCommand", sample, CTX)
    assert isinstance(command, Command)
    assert command.stop == {"speed": 0.0} and command.kind == "vector"
    assert command.service == MOB + "GlobalVectorDriver"
    assert CAT.decode(CAT.encode("SetGlobalVector", command.stop)).fields == {"speed": 0.0}


def test_pose_resets_and_limits_are_not_motion_commands() -> None:
    base = {"vehicle_id": "veh1", "operator_id": "op1"}
    tr = MobilityTranslator()
    (pose,) = tr.on_sample("PoseCommand", {**base, "frame": "LOCAL", "x": 1.0}, CTX)
    (limit,) = tr.on_sample("AccelerationLimitCommand", {**base, "ax": 1.0}, CTX)
    assert isinstance(pose, Command) and isinstance(limit, Command)
    assert pose.stop is None and limit.stop is None
    assert pose.service == MOB + "LocalPoseSensor"
    assert limit.service == MOB + "VelocityStateDriver" and limit.fields["command_type"] == 1


@pytest.mark.parametrize(("topic", "members"), [
    ("VectorCommand", {"frame": "GLOBAL"}),
    ("VectorCommand", {"frame": "LOCAL", "speed": None, "heading": NAN}),
    ("PoseCommand", {"frame": "GLOBAL", "x": 5.0}),  # x is a LOCAL member
    ("AccelerationLimitCommand", {"limit": "MAXIMUM"}),
    ("AccelerationLimitCommand", {"limit": "SIDEWAYS", "ax": 1.0}),
    ("AccelerationLimitCommand", {"limit": "CURRENT", "ax": 1.0}),  # not a limit
])
def test_commands_that_set_nothing_or_are_unusable_are_not_sent(
        topic: str, members: dict[str, Any]) -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", **members}
    assert MobilityTranslator().on_sample(topic, sample, CTX) == []


@pytest.mark.parametrize(("value", "want"), [
    (0.0, 0.0), (PI, PI), (-PI, -PI), (3.5, 3.5 - 2 * PI), (-7.0, -7.0 + 2 * PI),
    (4 * PI + 0.25, 0.25),
])
def test_angles_are_wrapped_not_clamped(value: float, want: float) -> None:
    assert wrap_angle(value) == pytest.approx(want, abs=1e-12)
    assert -PI <= wrap_angle(value) <= PI


# ------------------------------------------------------------------ which reports are asked for


def test_driver_state_reports_are_asked_for_only_when_the_profile_says_so() -> None:
    default = {s.report for s in MobilityTranslator.reports}
    assert not default & set(OPTIONAL_REPORTS)
    assert set(OPTIONAL_REPORTS) <= set(MobilityTranslator.messages)  # taken when they come
    tr = MobilityTranslator()
    tr.configure({"extra_reports": ["ReportGlobalVector", "ReportGeomagneticProperty"]})
    assert {s.report for s in tr.reports} - default == {"ReportGlobalVector",
                                                        "ReportGeomagneticProperty"}
    assert {s.report for s in MobilityTranslator.reports} == default  # class untouched
    everything = MobilityTranslator()
    everything.configure({"extra_reports": ["*"]})
    extra = [s for s in everything.reports if s.report in OPTIONAL_REPORTS]
    assert {s.report for s in extra} == set(OPTIONAL_REPORTS)
    for spec in extra:
        # every query asks for every optional field of its report, and encodes
        decoded = CAT.decode(CAT.encode(spec.query, spec.query_fields)).fields or {}
        assert decoded == dict(spec.query_fields)
        optional = [f for f in CAT.by_name(spec.report, "mobility").body.fields if f.optional]
        if optional:
            assert decoded["presence_vector"] == (1 << len(optional)) - 1, spec.report
        assert spec.service.startswith(MOB)


def test_bad_extra_reports_are_config_errors_naming_the_key() -> None:
    with pytest.raises(ConfigError) as info:
        MobilityTranslator().configure({"extra_reports": ["ReportGlobalPose", 3],
                                        "rate": 2})
    keys = {key for _, key, _ in info.value.problems}
    assert keys == {"translators.mobility.extra_reports[0]",  # not an optional report
                    "translators.mobility.extra_reports[1]",  # not a name
                    "translators.mobility.rate"}
    with pytest.raises(ConfigError) as info:
        MobilityTranslator().configure({"extra_reports": ["ReportGlobalPose"]})
    (problem,) = info.value.problems
    assert problem[1] == "translators.mobility.extra_reports[0]"
    assert "ReportWrenchEffort" in problem[2]  # lists what may be asked for
