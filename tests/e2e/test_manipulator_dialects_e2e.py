"""A manipulator v1.0 and a v2.0 one, each a JAUS peer on real UDP sockets, through a relay
to a real Cyclone DDS operator: the relay recognises the version from the services each
reports, reads each one's motion profile and specifications in its own layout into the same
topics, and commands each in its own layout.

The v1.0 peer's catalogue holds the v1.0 definitions only (its names and layouts replace
v2.0's), so it reads and writes exactly what a v1.0 implementation would."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .peer_sets import SetPeer
from .test_translators_e2e import collect, command_until, relay_with, take_control

pytestmark = pytest.mark.dds

MANIP = "urn:jaus:jss:manipulator:"


def v1_catalogue() -> Catalogue:
    """A catalogue that speaks manipulator v1.0 only: the peer's own view of the wire."""
    cat = default_catalogue().copy()
    cat.add(default_catalogue().dialects()["manipulator-1.0"], source="v1.0", replace=True)
    return cat


def _joint1(names: bool) -> dict[str, Any]:
    spec: dict[str, Any] = {
        "first_joint_parameters": {"revolute_joint1_offset_rec": {
            "joint1_offset": 0.1, "joint1_min_value": -1.5, "joint1_max_value": 1.5,
            "joint1_max_speed": 2.0}},
        "joint_specification_list": [{"prismatic_joint_specification_rec": {
            "link_length": 0.5, "twist_angle": 0.0, "joint_angle": 0.0, "min_value": 0.0,
            "max_value": 0.25}}]}
    if names:
        spec["joint_names_list"] = [{"description": "shoulder"}, {"description": "slide"}]
    return spec


V1 = {
    "services": (MANIP + "ManipulatorJointPositionSensor",
                 MANIP + "ManipulatorJointPositionDriver",
                 MANIP + "ManipulatorJointVelocitiesDriver", MANIP + "PrimitiveManipulator"),
    "reports": {
        "QueryMotionProfile": lambda f: ("ReportMotionProfile", {"motion_profile_list": [
            {"revolute_motion_profile_rec": {"joint_max_speed": 1.0,
                                             "joint_max_acceleration_rate": 2.0,
                                             "joint_max_deceleration_rate": 3.0}}]}),
        "QueryManipulatorSpecifications": lambda f: ("ReportManipulatorSpecifications",
                                                     _joint1(names=False)),
    },
    "velocity": "SetJointVelocities", "profile": "SetMotionProfile",
    "profile_list": "motion_profile_list", "names": ["", ""],
}
V2 = {
    "services": (MANIP + "ManipulatorJointPositionSensor",
                 MANIP + "ManipulatorJointMotionProfile",
                 MANIP + "ManipulatorJointVelocityDriver",
                 MANIP + "ManipulatorSpecificationService"),
    "reports": {
        "QueryJointMotionProfile": lambda f: ("ReportJointMotionProfile", {
            "joint_motion_profile_list": [{"revolute_joint_motion_profile_rec": {
                "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
                "joint_max_deceleration_rate": 3.0}}]}),
        "QueryManipulatorSpecifications": lambda f: ("ReportManipulatorSpecifications",
                                                     _joint1(names=True)),
    },
    "velocity": "SetJointVelocity", "profile": "SetJointMotionProfile",
    "profile_list": "joint_motion_profile_list", "names": ["shoulder", "slide"],
}


@pytest.mark.parametrize(("case", "octet"), [(V1, 171), (V2, 173)], ids=["v1.0", "v2.0"])
def test_a_manipulator_of_either_version_end_to_end(case: dict[str, Any], octet: int,
                                                    domain_id: int, partition: str) -> None:
    v1 = case is V1
    address = JausAddress(84 if v1 else 85, 1, 1)
    vid = f"Arm-{address.subsystem}"
    peer = SetPeer(address, case["services"], case["reports"], name="Arm",
                   catalogue=v1_catalogue() if v1 else None, version=(1, 0) if v1 else (2, 0))

    async def body(runtime: Runtime, operator: Any) -> None:
        profile = await collect(operator, "JointState",
                                lambda s: s["vehicle_id"] == vid and s["quantity"] == "max_speed")
        assert profile["values"] == pytest.approx([1.0], abs=1e-6)
        assert profile["units"] == ["rad/s"]
        spec = await collect(operator, "JointSpecification",
                             lambda s: s["vehicle_id"] == vid and s["device"] == "manipulator")
        assert spec["names"] == case["names"]
        assert spec["types"] == ["revolute", "prismatic"] and spec["units"] == ["rad", "m"]
        assert spec["min_values"] == pytest.approx([-1.5, 0.0], abs=1e-6)
        assert spec["max_values"] == pytest.approx([1.5, 0.25], abs=1e-6)
        await take_control(operator, peer, vid)
        velocity = await command_until(
            operator, peer, "JointCommand",
            {"vehicle_id": vid, "operator_id": "op1", "device": "manipulator",
             "quantity": "velocity", "values": [0.5]}, case["velocity"])
        assert velocity["joint_velocity_list"][0]["joint_velocity"]["radian_per_second"] == \
            pytest.approx(0.5, abs=1e-6)
        sent = await command_until(
            operator, peer, "JointCommand",
            {"vehicle_id": vid, "operator_id": "op1", "device": "manipulator",
             "quantity": "motion_profile", "values": [0.5, 1.0, 1.5], "units": ["rad"]},
            case["profile"])
        (joint,) = sent[case["profile_list"]]
        assert list(next(iter(joint.values())).values()) == pytest.approx([0.5, 1.0, 1.5],
                                                                          abs=1e-6)

    asyncio.run(relay_with(peer, octet, domain_id, partition, body))
