"""Message dialects: a code defined differently by manipulator v1.0 and v2.0, or by the IOP
and SAE readings, is decoded and encoded per vehicle with the definition it speaks, chosen
by its profile, recognised from the services it reports, or the base one by default."""

from __future__ import annotations

import math
from typing import Any

import pytest

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress

from .conftest import Harness, profile, published, sent

CAT = default_catalogue()
V1 = "manipulator-1.0"
MANIP = "urn:jaus:jss:manipulator:"
CORE = ["urn:jaus:jss:core:AccessControl", "urn:jaus:jss:core:Management",
        "urn:jaus:jss:core:Events"]

#: (dialect, base name, dialect name, fields as the dialect writes them)
CASES: list[tuple[str, str, str, dict[str, Any]]] = [
    (V1, "SetJointVelocity", "SetJointVelocities",
     {"joint_velocity_list": [{"joint_velocity": {"radian_per_second": 0.5}}]}),
    (V1, "ReportJointVelocity", "ReportJointVelocities",
     {"joint_velocity_list": [{"joint_velocity": {"meter_per_second": -0.25}}]}),
    (V1, "ReportJointEffort", "ReportJointEfforts",
     {"joint_effort_list": [{"joint_effort": 12.5}]}),
    (V1, "ReportJointMotionProfile", "ReportMotionProfile",
     {"motion_profile_list": [{"revolute_motion_profile_rec": {
         "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
         "joint_max_deceleration_rate": 3.0}}]}),
    (V1, "SetJointMotionProfile", "SetMotionProfile",
     {"motion_profile_list": [{"prismatic_motion_profile_rec": {
         "joint_max_speed": 0.5, "joint_max_acceleration_rate": 1.0,
         "joint_max_deceleration_rate": 1.5}}]}),
    (V1, "ReportManipulatorSpecifications", "ReportManipulatorSpecifications",
     {"first_joint_parameters": {"revolute_joint1_offset_rec": {
         "joint1_offset": 0.25, "joint1_min_value": -1.0, "joint1_max_value": 1.0}},
      "joint_specification_list": []}),
    ("iop", "SetGlobalVector", "SetGlobalVector", {"speed": 1.5, "heading": 0.5}),
    ("iop", "ReportAccelerationState", "ReportAccelerationState",
     {"acceleration_x": 0.5, "acceleration_y": 0.0, "acceleration_z": -9.75,
      "roll_acceleration": 0.0, "pitch_acceleration": 0.0, "yaw_acceleration": 0.25}),
    ("iop", "ReportStabilizerPosition", "ReportStabilizerPosition",
     {"stabilizer_position": [{"stabilizer_id": 2, "position": 0.5}]}),
]


def _close(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(a, b, abs_tol=5e-3)
    return bool(a == b)


@pytest.mark.parametrize(("dialect", "base", "name", "fields"), CASES,
                         ids=[f"{c[0]}:{c[2]}" for c in CASES])
def test_a_dialect_message_round_trips_under_its_base_name(
        dialect: str, base: str, name: str, fields: dict[str, Any]) -> None:
    payload = CAT.encode(base, fields, (dialect,))
    assert CAT.encode(name, fields, (dialect,)) == payload  # its own name says the same
    message = CAT.decode(payload, (dialect,))
    assert message.name == base and message.dialect == dialect
    assert message.definition is not None and message.definition.name == name
    assert _close(message.fields, fields)
    assert message.code == CAT.by_name(base).code


@pytest.mark.parametrize(("dialect", "base", "name", "fields"),
                         [c for c in CASES if c[0] == "iop" or c[1].endswith("Profile")],
                         ids=lambda v: v if isinstance(v, str) else "")
def test_the_base_definition_reads_those_bytes_otherwise(
        dialect: str, base: str, name: str, fields: dict[str, Any]) -> None:
    payload = CAT.encode(base, fields, (dialect,))
    try:
        decoded = CAT.decode(payload).fields
    except Exception:  # a different layout may not decode at all
        return
    assert not _close(decoded, fields)


def test_every_manipulator_v1_name_is_known() -> None:
    v1_names = ["SetJointEfforts", "SetJointVelocities", "SetMotionProfile",
                "SetPanTiltJointEfforts", "SetPanTiltJointVelocities", "QueryJointEfforts",
                "QueryJointPosition", "QueryJointVelocities", "QueryMotionProfile",
                "QueryCommandedJointVelocities", "QueryPanTiltJointEfforts",
                "QueryPanTiltJointVelocities", "QueryCommandedPanTiltJointVelocities",
                "ReportJointEfforts", "ReportJointPosition", "ReportJointVelocities",
                "ReportMotionProfile", "ReportCommandedJointVelocities",
                "ReportPanTiltJointEfforts", "ReportPanTiltJointVelocities",
                "ReportCommandedPanTiltJointVelocities"]
    assert [n for n in v1_names if n not in CAT] == []
    assert CAT.canonical("ReportJointVelocities") == "ReportJointVelocity"
    assert CAT.canonical("ReportJointPosition") == "ReportJointPositions"
    # another name of a code whose v1.0 layout is v2.0's: encodes as that code
    assert CAT.encode("ReportJointPosition", {"joint_position_list": []}) == \
        CAT.encode("ReportJointPositions", {"joint_position_list": []})


@pytest.mark.parametrize(("services", "expected"), [
    ([(MANIP + "PrimitiveManipulator", "1.0")], (V1,)),
    ([(MANIP + "PrimitiveManipulator", "2.0")], ()),
    ([("urn:jaus:jss:iop:PlatformMode", "1.0"), ("urn:jaus:jss:mobility:GlobalVectorDriver",
                                                "1.0")], ("iop",)),
    ([("urn:jaus:jss:mobility:GlobalVectorDriver", "1.0")], ()),
    ([], ()),
])
def test_dialects_are_recognised_from_services(services: list[tuple[str, str]],
                                              expected: tuple[str, ...]) -> None:
    assert set(CAT.recognise(services)) == set(expected)


def test_a_dialect_cannot_redefine_an_unknown_code() -> None:
    from edge_vis.codec.types import Dialect, message
    from edge_vis.errors import PluginLoadError

    cat = Catalogue()
    with pytest.raises(PluginLoadError, match="not a code of the catalogue"):
        cat.add_dialect(Dialect("x", messages=(message(0x0999, "Nope", service_set="x"),)))


# -- chosen per vehicle by the engine -------------------------------------------------------


def _vehicle(services: list[tuple[str, str]], **vehicle: Any) -> Harness:
    from translators.core import CoreTranslator
    from translators.manipulator import ManipulatorTranslator

    vehicles = [{"vehicle_id": "arm", "subsystem": 150, **vehicle}] if vehicle else []
    h = Harness(CAT, profile(vehicles=vehicles) if vehicles else profile(),
                [CoreTranslator(), ManipulatorTranslator()])
    h.advance(0.1)
    h.deliver("150.1.1", "ReportIdentification", {"query_type": 2, "type": 10001,
                                                  "identification": "Arm"})
    h.deliver("150.1.1", "ReportServices", {"node_list": [{"node_rec": {"node_id": 1},
        "component_list": [{"component_rec": {"component_id": 1, "instance_id": 0},
                            "service_list": [
                                {"uri": u, "major_version_number": int(v[0]),
                                 "minor_version_number": int(v[2])}
                                for u, v in [(c, "1.0") for c in CORE] + services]}]}]})
    return h


V1_SERVICES = [(MANIP + "ManipulatorJointPositionSensor", "1.0"),
               (MANIP + "ManipulatorJointVelocitiesDriver", "1.0")]
V2_SERVICES = [(MANIP + "ManipulatorJointPositionSensor", "2.0"),
               (MANIP + "ManipulatorJointMotionProfile", "2.0")]


@pytest.mark.parametrize(("services", "vehicle", "expected"), [
    (V1_SERVICES, {}, (V1,)),                          # recognised from v1.0 services
    (V2_SERVICES, {}, ()),                             # default: the base definitions
    (V2_SERVICES, {"dialects": [V1]}, (V1,)),          # the profile says so
    (V1_SERVICES, {"dialects": []}, ()),               # the profile overrides recognition
])
def test_the_engine_chooses_each_vehicles_dialects(services: list[tuple[str, str]],
                                                   vehicle: dict[str, Any],
                                                   expected: tuple[str, ...]) -> None:
    h = _vehicle(services, **vehicle)
    assert h.engine.dialects_of(JausAddress.parse("150.1.7")) == expected
    assert h.engine.dialects_of(JausAddress.parse("151.1.1")) == ()


@pytest.mark.parametrize("services", [V1_SERVICES, V2_SERVICES], ids=["v1.0", "v2.0"])
def test_both_versions_publish_the_same_motion_profile(services: list[tuple[str, str]]) -> None:
    h = _vehicle(services)
    dialects = h.engine.dialects_of(JausAddress.parse("150.1.1"))
    # the vehicle answers in its own layout; the relay decodes it as it speaks
    list_name, alt = ("motion_profile_list", "revolute_motion_profile_rec") if dialects \
        else ("joint_motion_profile_list", "revolute_joint_motion_profile_rec")
    payload = CAT.encode("ReportJointMotionProfile", {list_name: [{alt: {
        "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
        "joint_max_deceleration_rate": 3.0}}]}, dialects)
    h.engine.receive_message(JausAddress.parse("150.1.1"), CAT.decode(payload, dialects), h.now)
    samples = {s["quantity"]: s for s in published(h.drain(), "JointState")}
    assert [round(samples[q]["values"][0], 3) for q in
            ("max_speed", "max_acceleration", "max_deceleration")] == [1.0, 2.0, 3.0]
    assert samples["max_speed"]["units"] == ["rad/s"]


@pytest.mark.parametrize("services", [V1_SERVICES, V2_SERVICES], ids=["v1.0", "v2.0"])
def test_a_motion_profile_command_goes_out_in_the_vehicles_layout(
        services: list[tuple[str, str]]) -> None:
    h = _vehicle([*services, (MANIP + "ManipulatorJointPositionDriver", services[0][1])])
    h.sample("ControlRequest", {"vehicle_id": "Arm-150", "operator_id": "op1",
                                "authority": 10, "action": "request"})
    h.deliver("150.1.1", "ConfirmControl", {"response_code": 0})
    h.deliver("150.1.1", "ReportStatus", {"status": 1, "reserved": 0})
    out = h.sample("JointCommand", {"vehicle_id": "Arm-150", "operator_id": "op1",
                                    "device": "manipulator", "quantity": "motion_profile",
                                    "values": [1.0, 2.0, 3.0], "units": ["rad"]})
    out += h.advance(0.2)
    (send,) = sent(out, "SetJointMotionProfile")
    dialects = h.engine.dialects_of(send.destination)
    payload = CAT.encode(send.name, send.fields, dialects)
    body = CAT.decode(payload, dialects)
    assert body.definition is not None
    assert body.definition.name == ("SetMotionProfile" if dialects else "SetJointMotionProfile")
    (joint,) = next(iter(body.fields.values()))
    assert [round(v, 3) for v in next(iter(joint.values())).values()] == [1.0, 2.0, 3.0]


def test_check_refuses_an_unknown_dialect() -> None:
    from edge_vis.errors import ConfigError

    with pytest.raises(ConfigError, match=r"vehicles\[0\]\.dialects.*no dialect "
                       r"'manipulator-3\.0' \(dialects: iop, manipulator-1\.0\)"):
        profile(vehicles=[{"vehicle_id": "arm", "subsystem": 150,
                           "dialects": ["manipulator-3.0"]}])
