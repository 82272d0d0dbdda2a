"""Robots that read discovery wildcards their own way, served end to end with no vehicle profile.

A JAUS++ robot (empty ReportServices for node/component 255) and the JAUS Toolset example
(no ReportConfiguration, node 1 listed twice) on real UDP sockets on loopback, the relay,
and an operator on real Cyclone DDS.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from collections.abc import Callable
from typing import Any

import pytest
from discovery_peers import JausppRobot, JtsExample, UdpPeer, names

from edge_vis.catalogue import default_catalogue
from edge_vis.config import from_mapping
from edge_vis.shell.relay import Runtime

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY_IP, JAUSPP_IP, JTS_IP = "127.0.0.81", "127.0.0.82", "127.0.0.83"
JAUSPP_ID, JTS_ID = "JausppRobot-150", "SimulatedVehicle-126"


async def wait_for(check: Callable[[], Any], timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while not (value := check()):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.02)
    return value


async def sample_of(reader: Any, vehicle_id: str, timeout: float) -> dict[str, Any]:
    """The first sample of ``vehicle_id`` ``reader`` takes within ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in await asyncio.to_thread(reader.take, 0.2):
            if sample["vehicle_id"] == vehicle_id:
                return sample
    raise AssertionError(f"no {vehicle_id} sample in {timeout} s")


def test_jauspp_and_jts_robots_served_without_profiles(
    domain_id: int, partition: str, caplog: pytest.LogCaptureFixture
) -> None:
    catalogue = default_catalogue()
    robot, jts = JausppRobot(catalogue), JtsExample()

    async def main() -> None:
        loop = asyncio.get_running_loop()
        peers = [UdpPeer(robot, catalogue), UdpPeer(jts, catalogue)]
        for peer, ip in zip(peers, (JAUSPP_IP, JTS_IP), strict=True):
            await loop.create_datagram_endpoint(lambda p=peer: p, local_addr=(ip, 3794))
        profile = from_mapping({
            "relay": {"jaus_id": "42.1.1"},
            "links": {"lan": {"url": f"udp://{RELAY_IP}:3794"
                                     f"?peers={JAUSPP_IP}:3794,{JTS_IP}:3794"}},
            "dds": {"domain": domain_id, "partitions": [partition]},
            "discovery": {"period": 1.0, "liveness_period": 0.5, "response_timeout": 1.0},
            "commands": {"rate": 10.0, "lifespan": 2.0, "deadman_timeout": 30.0},
        }, file="e2e.toml")
        assert not profile.vehicles
        runtime = Runtime(profile)
        operator = dds.DdsBridge(domain_id, (partition,))
        await runtime.start()
        try:
            idents = operator.reader("VehicleIdentification", depth=64)
            global_poses = operator.reader("GlobalPose", depth=64)
            local_poses = operator.reader("LocalPose", depth=64)
            poses = await asyncio.to_thread(global_poses.collect, 3, 15.0)
            assert {p["vehicle_id"] for p in poses} == {JAUSPP_ID}
            assert poses[-1]["latitude"] == pytest.approx(28.538426, abs=1e-5)
            await sample_of(local_poses, JTS_ID, 15.0)  # polled: JTS ignores CreateEvent
            latest = {}
            for sample in await asyncio.to_thread(idents.collect, 64, 1.0):
                latest[sample["vehicle_id"]] = sample
            uris = {s["uri"] for s in latest[JAUSPP_ID]["services"]}
            assert "urn:jaus:jss:mobility:PrimitiveDriver" in uris
            assert "urn:jaus:jss:mobility:LocalWaypointListDriver" in {
                s["uri"] for s in latest[JTS_ID]["services"]}
            # the wildcard came back empty from JAUS++; the relay asked it by ID
            assert [q["node_list"][0]["node_rec"]["node_id"]
                    for q in names(robot, "QueryServices")] == [255, 1]
            assert names(robot, "CreateEvent")

            # control and a command to the JAUS++ robot
            operator.publish("ControlRequest", {"vehicle_id": JAUSPP_ID, "operator_id": "op1",
                                                "authority": 50, "action": "request"})
            await wait_for(lambda: robot.status == 1, 10, "the robot READY under control")
            drive = {"vehicle_id": JAUSPP_ID, "operator_id": "op1", "propulsive_linear_x": 40.0}
            operator.publish("WrenchEffortCommand", drive)
            await wait_for(lambda: robot.commands, 5, "SetWrenchEffort at the robot")
            assert robot.commands[0][1]["propulsive_linear_effort_x"] == pytest.approx(
                40.0, abs=0.01)
            with caplog.at_level(logging.INFO, logger="edge_vis.shell.relay"):
                await runtime.stop()
        finally:
            await runtime.stop()
            operator.close()
            for peer in peers:
                peer.close()
        totals = runtime.totals()
        assert totals["discovery empty answers"] >= 1
        assert totals["discovery fallbacks"] >= 1
        assert totals["discovery queries sent"] >= 4
        line = next(r.getMessage() for r in caplog.records if "totals: " in r.getMessage())
        logged = json.loads(line.split("totals: ", 1)[1])
        assert logged["discovery fallbacks"] == totals["discovery fallbacks"]

    asyncio.run(main())
