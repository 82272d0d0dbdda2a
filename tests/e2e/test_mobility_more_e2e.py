"""Mobility driver state and set-points end to end, and the manipulator's ExecuteList on
the wire: a scripted JAUS vehicle on real UDP, the relay, real Cyclone DDS."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .peer_sets import SetPeer
from .test_translators_e2e import collect, command_until, relay_with, take_control

pytestmark = pytest.mark.dds

MOB = "urn:jaus:jss:mobility:"
MANIP = "urn:jaus:jss:manipulator:"
OPEN = {"access": {"any_operator": True}}  # any operator may take control


def test_vector_driver_state_out_and_set_points_in(domain_id: int, partition: str) -> None:
    peer = SetPeer(JausAddress(84, 1, 1), (
        MOB + "GlobalVectorDriver", MOB + "GlobalPoseSensor", MOB + "PrimitiveDriver"), {
        "QueryGlobalVector": lambda f: ("ReportGlobalVector", {
            "speed": 2.5, "heading": -1.0, "altitude": 12.0}),
        "QueryGeomagneticProperty": lambda f: ("ReportGeomagneticProperty", {
            "magnetic_variation": 0.1}),
        "QueryWrenchEffort": lambda f: ("ReportWrenchEffort", {
            "propulsive_linear_effort_x": 40.0}),
        "QueryGlobalPose": lambda f: ("ReportGlobalPose", {"latitude": 1.0,
                                                           "longitude": 2.0}),
    }, name="Boat")
    vid = "Boat-84"

    async def body(runtime: Runtime, operator: Any) -> None:
        vector = await collect(operator, "VectorState", lambda s: s["vehicle_id"] == vid)
        assert vector["frame"] == "GLOBAL" and math.isnan(vector["z"])
        assert vector["speed"] == pytest.approx(2.5, abs=0.01)
        assert vector["heading"] == pytest.approx(-1.0, abs=1e-3)
        assert vector["altitude"] == pytest.approx(12.0, abs=1e-3)
        magnetic = await collect(operator, "GeomagneticProperty",
                                 lambda s: s["vehicle_id"] == vid)
        assert magnetic["magnetic_variation"] == pytest.approx(0.1, abs=1e-3)
        effort = await collect(operator, "WrenchEffortState", lambda s: s["vehicle_id"] == vid)
        assert effort["propulsive_linear_x"] == pytest.approx(40.0, abs=0.01)
        assert math.isnan(effort["resistive_linear_x"])
        await take_control(operator, peer, vid)
        fields = await command_until(operator, peer, "VectorCommand", {
            "vehicle_id": vid, "operator_id": "op1", "frame": "GLOBAL", "speed": 3.0,
            "heading": 3.5}, "SetGlobalVector")
        assert fields["speed"] == pytest.approx(3.0, abs=0.01)
        assert fields["heading"] == pytest.approx(3.5 - 2 * math.pi, abs=1e-3)
        assert "altitude" not in fields  # absent = unchanged
        fields = await command_until(operator, peer, "PoseCommand", {
            "vehicle_id": vid, "operator_id": "op1", "frame": "GLOBAL", "latitude": 10.5,
            "longitude": -20.25}, "SetGlobalPose")
        assert fields["latitude"] == pytest.approx(10.5, abs=1e-6)
        assert fields["longitude"] == pytest.approx(-20.25, abs=1e-6)

    asyncio.run(relay_with(peer, 61, domain_id, partition, body,
                           extra={**OPEN,
                                  "translators": {"mobility": {"extra_reports": ["*"]}}}))


def test_manipulator_execute_list_reaches_the_arm_as_its_own_message(
        domain_id: int, partition: str) -> None:
    peer = SetPeer(JausAddress(86, 1, 1), (MANIP + "ManipulatorJointPositionsListDriver",),
                   {}, name="Arm")
    vid = "Arm-86"

    async def body(runtime: Runtime, operator: Any) -> None:
        await take_control(operator, peer, vid)
        fields = await command_until(operator, peer, "JointCommand", {
            "vehicle_id": vid, "operator_id": "op1", "device": "manipulator",
            "quantity": "execute_list", "values": [4.0], "units": []}, "ExecuteList")
        # decoded by its code: the manipulator's ExecuteList has no speed
        assert fields == {"element_uid": 4}
        assert runtime.counters["encode errors"] == 0

    asyncio.run(relay_with(peer, 63, domain_id, partition, body, extra=OPEN))
