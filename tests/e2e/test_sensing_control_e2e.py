"""Environment sensing control end to end: the simulated UGV on real UDP, the relay, and an
operator's Cyclone DDS participant that configures the camera and lidar, starts and stops
the video stream, takes a still image on demand and reads mounting and compressed scans."""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

import pytest

from edge_vis.config import from_mapping
from edge_vis.shell.relay import Runtime

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY_IP, SIM_IP = "127.0.0.171", "127.0.0.172"
VID = "ugv-sense-101"


async def collect(reader: Any, check: Any, timeout: float = 10.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in await asyncio.to_thread(reader.take, 0.1):
            if sample["vehicle_id"] == VID and check(sample):
                return sample
    raise AssertionError("no matching sample in time")


async def until(check: Any, what: str, publish: Any = None, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        if publish is not None:
            publish()
        await asyncio.sleep(0.1)


def test_camera_and_lidar_control_from_dds(domain_id: int, partition: str) -> None:
    from edge_vis.tools.sim.profile import parse_profile
    from edge_vis.tools.sim.runner import Simulation

    async def run() -> None:
        sim = Simulation(parse_profile({"seed": 3, "vehicles": [{
            "name": "ugv-sense", "subsystem": 101, "link": f"udp://{SIM_IP}:3794",
            "init_time": 0.2}]}))
        await sim.start()
        runtime = Runtime(from_mapping({
            "relay": {"jaus_id": "200.1.1"},
            "links": {"lan": {"url": f"udp://{RELAY_IP}:3794?peers={SIM_IP}:3794"}},
            "dds": {"domain": domain_id, "partitions": [partition]},
            "discovery": {"period": 0.5, "liveness_period": 0.5},
            "commands": {"rate": 10.0, "lifespan": 2.0, "deadman_timeout": 30.0},
            "access": {"any_operator": True},
            "translators": {"environment": {"range_compression": "deflate"}},
        }, file="e2e.toml"))
        operator = dds.DdsBridge(domain_id, (partition,))
        await runtime.start()
        (endpoint,) = sim.endpoints
        vehicle = endpoint.vehicle
        assert vehicle is not None
        try:
            infos, states = operator.reader("SensorInfo"), operator.reader("SensorState")
            scans, images = operator.reader("RangeScan"), operator.reader("ImageProduct")
            # mounting, from ReportSensorGeometricProperties
            info = await collect(infos, lambda s: s["mounted_on"] == "vehicle")
            assert info["mount_z"] == pytest.approx(1.2, abs=1e-3)
            assert info["mount_qw"] == pytest.approx(1.0, abs=1e-4)
            # scans asked for DEFLATE-compressed and decompressed by the relay
            scan = await collect(scans, lambda s: len(s["points"]) == 181)
            assert scan["points"][90]["bearing"] == pytest.approx(0.0, abs=1e-6)
            assert all(0.0 < p["range"] <= 40.0 + 1e-3 for p in scan["points"])
            # nothing is polled for stills, and nobody holds the vehicle: no image yet
            capture = {"vehicle_id": VID, "operator_id": "op1", "sensor_id": 1,
                       "action": "capture", "kind": "", "settings": ""}
            operator.publish("SensorCommand", capture)
            await asyncio.sleep(1.0)
            assert not [s for s in await asyncio.to_thread(images.take, 0.1)
                        if s["vehicle_id"] == VID]

            operator.publish("ControlRequest", {"vehicle_id": VID, "operator_id": "op1",
                                                "authority": 50, "action": "request"})
            sensors = next(c for c in vehicle.components.values()
                           if c.spec.name == "Sensors")
            await until(lambda: sensors.controller is not None, "control of the sensors")

            # still image on demand
            operator.publish("SensorCommand", capture)
            product = await collect(images, lambda s: True)
            assert product["format"] == "png"
            assert product["size_bytes"] > 1000 and len(product["sha256"]) == 64

            # configure the camera: confirmed, and the configuration read back shows it
            operator.publish("SensorCommand", {
                "vehicle_id": VID, "operator_id": "op1", "sensor_id": 1,
                "action": "configure", "kind": "visual", "settings": "zoom_level=40"})
            await until(lambda: math.isclose(
                vehicle.sensing.configurations["visual"]["zoom_level"], 40.0, abs_tol=0.01),
                "the new zoom")
            state = await collect(states, lambda s: s["kind"] == "visual"
                                  and s["confirmation"] == "accepted"
                                  and "zoom_level=40," in s["configuration"])

            # a lidar rate above its 20 Hz is refused by the vehicle, and the refusal shown
            operator.publish("SensorCommand", {
                "vehicle_id": VID, "operator_id": "op1", "sensor_id": 1,
                "action": "configure", "kind": "range", "settings": "update_rate=50"})
            state = await collect(states, lambda s: s["kind"] == "range"
                                  and s["confirmation"].startswith("refused"))
            assert "code 3" in state["confirmation"] and "20 Hz" in state["confirmation"]

            # the video stream: play, then stop
            for action, code in (("play", 0), ("stop", 2)):
                operator.publish("SensorCommand", {
                    "vehicle_id": VID, "operator_id": "op1", "sensor_id": 1,
                    "action": action, "kind": "", "settings": ""})
                await until(lambda code=code: vehicle.sensing.stream == code,
                            f"stream {action}")
                await collect(states, lambda s, a=action: s["kind"] == "digital_video"
                              and s["stream"] == a.upper())
            assert runtime.counters["encode errors"] == 0
        finally:
            await runtime.stop()
            operator.close()
            await sim.stop()

    asyncio.run(run())
