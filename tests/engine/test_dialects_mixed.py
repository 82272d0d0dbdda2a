"""A vehicle reporting both manipulator 1.x and 2.x services reads each message the way the
service carrying it defines it; the IOP copy of manipulator v1.0 reads its specifications as
v1.0 does."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from edge_vis.catalogue import Catalogue, Dialects, default_catalogue
from edge_vis.jaus.address import JausAddress

from .conftest import Harness, profile, published, sent

CAT = default_catalogue()
V1 = "manipulator-1.0"
MANIP = "urn:jaus:jss:manipulator:"
CORE = [("urn:jaus:jss:core:AccessControl", "1.0"), ("urn:jaus:jss:core:Management", "1.0"),
        ("urn:jaus:jss:core:Events", "1.0")]
SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"

#: a partly upgraded arm: v1.0 drivers and sensors, the v2.0 motion profile service
MIXED = [(MANIP + "ManipulatorJointPositionSensor", "1.0"),
         (MANIP + "ManipulatorJointPositionDriver", "1.0"),
         (MANIP + "ManipulatorJointVelocitiesDriver", "1.0"),
         (MANIP + "ManipulatorJointMotionProfile", "2.0")]
V2_PROFILE = {"joint_motion_profile_list": [{"revolute_joint_motion_profile_rec": {
    "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
    "joint_max_deceleration_rate": 3.0}}]}


def test_a_code_carried_by_a_v2_service_keeps_the_v2_definition() -> None:
    choice = CAT.speaks(MIXED)
    assert tuple(choice) == (V1,)  # its v1.0 services: manipulator-1.0
    assert {0x0607, 0x4607} <= choice.base  # ... but the motion profile is a 2.0 service's
    assert 0x4600 not in choice.base  # specifications: still the v1.0 drivers' reading
    read = CAT.decode(CAT.encode("ReportJointMotionProfile", V2_PROFILE), choice)
    assert read.dialect == "" and list(read.fields or {}) == ["joint_motion_profile_list"]
    assert read.fields == CAT.decode(CAT.encode("ReportJointMotionProfile", V2_PROFILE)).fields
    v1_specs = {d.code: d for d in CAT.dialects()[V1]}[0x4600]
    assert CAT.definition(0x4600, choice) is v1_specs
    assert CAT.definition(0x4607, choice) is CAT.get(0x4607)
    # the pure cases are unchanged
    v1_only = CAT.speaks(MIXED[:3])
    assert tuple(v1_only) == (V1,) and not v1_only.base
    assert tuple(CAT.speaks([(u, "2.0") for u, _ in MIXED])) == ()


def test_a_profile_naming_its_dialects_is_taken_at_its_word() -> None:
    assert not Dialects((V1,)).base
    h = _vehicle({"1": MIXED}, dialects=[V1])
    assert h.engine.dialects_of(JausAddress.parse("150.1.1")) == (V1,)
    assert getattr(h.engine.dialects_of(JausAddress.parse("150.1.1")), "base", frozenset()) \
        == frozenset()


def _vehicle(components: dict[str, list[tuple[str, str]]], **vehicle: Any) -> Harness:
    from translators.core import CoreTranslator
    from translators.manipulator import ManipulatorTranslator

    vehicles = [{"vehicle_id": "arm", "subsystem": 150, **vehicle}] if vehicle else []
    h = Harness(CAT, profile(vehicles=vehicles) if vehicles else profile(),
                [CoreTranslator(), ManipulatorTranslator()])
    h.advance(0.1)
    h.deliver("150.1.1", "ReportIdentification", {"query_type": 2, "type": 10001,
                                                  "identification": "Arm"})
    h.deliver("150.1.1", "ReportServices", {"node_list": [{"node_rec": {"node_id": 1},
        "component_list": [{"component_rec": {"component_id": int(c), "instance_id": 0},
                            "service_list": [
                                {"uri": u, "major_version_number": int(v[0]),
                                 "minor_version_number": int(v[2])}
                                for u, v in CORE + services]}
                           for c, services in components.items()]}]})
    return h


@pytest.mark.parametrize("components", [
    {"1": MIXED},                                              # one component, both versions
    {"1": [(MANIP + "ManipulatorJointMotionProfile", "2.0"),  # a v2.0 arm beside
           (MANIP + "ManipulatorJointPositionDriver", "2.0")],
     "2": [(MANIP + "PanTiltJointPositionDriver", "1.0"),      # a v1.0 pan-tilt
           (MANIP + "PrimitivePanTilt", "1.0")]},
], ids=["one-component", "two-components"])
def test_mixed_vehicle_reads_and_writes_the_motion_profile_as_v2(
        components: dict[str, list[tuple[str, str]]]) -> None:
    h = _vehicle(components)
    arm = JausAddress.parse("150.1.1")
    dialects = h.engine.dialects_of(arm)
    assert V1 in dialects  # it does speak v1.0 somewhere
    payload = CAT.encode("ReportJointMotionProfile", V2_PROFILE)  # sent the v2.0 way
    h.engine.receive_message(arm, CAT.decode(payload, dialects), h.now)
    samples = {s["quantity"]: s for s in published(h.drain(), "JointState")}
    assert [round(samples[q]["values"][0], 3) for q in
            ("max_speed", "max_acceleration", "max_deceleration")] == [1.0, 2.0, 3.0]
    # and a new profile goes out under the v2.0 names, encodable in what it speaks
    h.sample("ControlRequest", {"vehicle_id": "Arm-150", "operator_id": "op1",
                                "authority": 10, "action": "request"})
    for component in components:
        h.deliver(f"150.1.{component}", "ConfirmControl", {"response_code": 0})
        h.deliver(f"150.1.{component}", "ReportStatus", {"status": 1, "reserved": 0})
    out = h.sample("JointCommand", {"vehicle_id": "Arm-150", "operator_id": "op1",
                                    "device": "manipulator", "quantity": "motion_profile",
                                    "values": [0.5, 1.0, 1.5], "units": ["rad"]})
    out += h.advance(0.2)
    (send,) = sent(out, "SetJointMotionProfile")
    assert "joint_motion_profile_list" in send.fields
    body = CAT.decode(CAT.encode(send.name, send.fields, dialects), dialects)
    assert body.definition is not None and body.definition.name == "SetJointMotionProfile"


# -- the IOP copy of manipulator v1.0 --------------------------------------------------------


@pytest.mark.skipif(not (SHARED / "jsidl-iop").is_dir(), reason="../shared/jaus not present")
def test_the_iop_copy_specifications_read_as_v1() -> None:
    """jsidl-iop's older manipulator set is v1.0 with other labels: its services report
    1.0 (so the vehicle speaks manipulator-1.0) and its ReportManipulatorSpecifications,
    encoded by its own JSIDL, decodes to the same values with the v1.0 definition."""
    from edge_vis.catalogue.jsidl import load_jsidl

    folder = SHARED / "jsidl-iop" / "urn.jaus.jss.manipulator"
    (iop,) = [m for m in load_jsidl(folder) if m.code == 0x4600]
    assert {version for _uri, version in iop.services} == {"1.0"}
    assert V1 in CAT.speaks(iop.services)
    fields = {
        "first_joint_parameters": {"prismatic_joint1_angle_rec": {
            "joint1_angle": 0.0, "joint1_min_value": 0.0, "joint1_max_value": 0.5,
            "joint1_max_speed": 0.2, "joint1_max_force": 300.0}},
        "joint_specification_list": [{"prismatic_joint_specification_rec": {
            "link_length": 0.5, "twist_angle": 0.0, "joint_angle": 0.0, "min_value": 0.0,
            "max_value": 0.25, "max_force": 150.0}}]}
    payload = Catalogue([iop]).encode(0x4600, fields)
    read = CAT.decode(payload, (V1,))
    assert read.dialect == V1
    assert read.fields == Catalogue([iop]).decode(payload).fields
    rec = read.fields["joint_specification_list"][0]["prismatic_joint_specification_rec"]
    assert rec["max_force"] == pytest.approx(150.0, abs=0.01)
    assert read.fields["first_joint_parameters"]["prismatic_joint1_angle_rec"][
        "joint1_max_force"] == pytest.approx(300.0, abs=0.01)


@pytest.mark.parametrize(("version", "dialect"), [("0.6", "iop"), ("1.0", "")])
def test_iop_acceleration_is_read_as_the_reported_service_version_defines_it(
        version: str, dialect: str) -> None:
    """IOP publishes AccelerationStateSensor as version 0.6 (accelerations mandatory), the
    SAE set as 1.0: an IOP vehicle reporting 1.0 sends the SAE layout."""
    choice = CAT.speaks([("urn:jaus:jss:iop:PlatformMode", "1.0"),
                         ("urn:jaus:jss:mobility:AccelerationStateSensor", version)])
    assert tuple(choice) == ("iop",)
    fields = {"acceleration_x": 0.5, "acceleration_y": 0.0, "acceleration_z": -9.75}
    sent_as = ("iop",) if dialect else ()
    if dialect:
        fields |= {"roll_acceleration": 0.0, "pitch_acceleration": 0.0,
                   "yaw_acceleration": 0.25}
    read = CAT.decode(CAT.encode("ReportAccelerationState", fields, sent_as), choice)
    assert read.dialect == dialect
    assert read.fields is not None
    assert read.fields["acceleration_z"] == pytest.approx(-9.75, abs=0.01)
