"""The simulator's manipulator and pan-tilt, v2.0 and v1.0, over real UDP through a relay to a
real Cyclone DDS operator.

The sim runs the shipped ``profiles/sim/arm.toml`` vehicles (moved to the test's
addresses); the relay finds each by JAUS discovery, recognises its manipulator version from
the services it reports, and the operator sees the joint names and limits, moves the arm
and the pan-tilt, and changes the motion profile and the tool offset - each vehicle in its
own wire layout. The relay's mirrored capture then decodes with ``decode --dialect auto``.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

from edge_vis.cli import main
from edge_vis.config import from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.mirror import Mirror
from edge_vis.shell.relay import Runtime
from edge_vis.tools.sim.profile import load_profile
from edge_vis.tools.sim.runner import Simulation

from .test_translators_e2e import collect

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

CONTROLLED = 2
SHIPPED = Path(__file__).resolve().parents[2] / "profiles" / "sim" / "arm.toml"


def _moved(tmp_path: Path, name: str, sim_ip: str) -> Path:
    """The shipped profile with only vehicle ``name``, on ``sim_ip``."""
    profile = load_profile(SHIPPED)
    (vehicle,) = [v for v in profile.vehicles if v.name == name]
    assert vehicle.manipulator is not None
    text = (f'[[vehicles]]\nname = "{name}"\nsubsystem = {vehicle.subsystem}\n'
            f'link = "udp://{sim_ip}:3794"\ninit_time = 0.2\ncontrol_timeout = 10\n'
            f'[vehicles.manipulator]\nversion = "{vehicle.manipulator.version}"\n')
    path = tmp_path / "sim.toml"
    path.write_text(text)
    return path


async def _until(operator: Any, topic: str, sample: dict[str, Any], reader_topic: str,
                 check: Any, timeout: float = 10.0) -> dict[str, Any]:
    """Publish ``sample`` every 0.3 s until a ``reader_topic`` sample passes ``check``."""
    reader = operator.reader(reader_topic)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while loop.time() < deadline:
        operator.publish(topic, sample)
        for got in await asyncio.to_thread(reader.take, 0.3):
            if check(got):
                return got
    raise AssertionError(f"no {reader_topic} sample showed the effect of {topic}")


@pytest.mark.parametrize(("name", "octet", "names"), [
    ("eod-v2", 101, ["turret", "shoulder", "slide"]),
    ("eod-v1", 103, ["", "", ""]),
], ids=["v2.0", "v1.0"])
def test_simulated_arm_and_pan_tilt_end_to_end(name: str, octet: int, names: list[str],
                                               domain_id: int, partition: str,
                                               tmp_path: Path) -> None:
    relay_ip, sim_ip = f"127.0.0.{octet}", f"127.0.0.{octet + 1}"
    profile = load_profile(_moved(tmp_path, name, sim_ip))
    (spec,) = profile.vehicles
    vid = f"{name}"
    config = from_mapping({
        "relay": {"jaus_id": "200.1.1"},
        "links": {"lan": {"url": f"udp://{relay_ip}:3794?peers={sim_ip}:3794"}},
        "dds": {"domain": domain_id, "partitions": [partition]},
        "discovery": {"period": 0.5, "liveness_period": 0.5},
        "commands": {"rate": 10.0, "lifespan": 2.0, "deadman_timeout": 30.0},
        "vehicles": [{"vehicle_id": vid, "subsystem": spec.subsystem}],
    }, file="e2e.toml")

    capture = tmp_path / "relay.pcap"

    async def run() -> None:
        sim = Simulation(profile)
        await sim.start()
        runtime = Runtime(config, mirror=Mirror(pcap=capture))
        operator = dds.DdsBridge(domain_id, (partition,))
        await runtime.start()
        try:
            await body(sim, runtime, operator)
        finally:
            await runtime.stop()
            operator.close()
            await sim.stop()

    async def body(sim: Simulation, runtime: Runtime, operator: Any) -> None:
        spec_sample = await collect(
            operator, "JointSpecification",
            lambda s: s["vehicle_id"] == vid and s["device"] == "manipulator", timeout=10.0)
        assert spec_sample["names"] == names
        assert spec_sample["types"] == ["revolute", "revolute", "prismatic"]
        assert spec_sample["max_values"] == pytest.approx([3.14159, 1.5, 0.4], abs=1e-3)
        pan_tilt = await collect(
            operator, "JointSpecification",
            lambda s: s["vehicle_id"] == vid and s["device"] == "pan_tilt", timeout=10.0)
        assert pan_tilt["max_values"] == pytest.approx([3.0, 1.0], abs=1e-3)

        await _until(operator, "ControlRequest",
                     {"vehicle_id": vid, "operator_id": "op1", "authority": 50,
                      "action": "request"}, "ControlStatus",
                     lambda s: s["vehicle_id"] == vid and s["operator_id"] == "op1"
                     and s["state"] in (CONTROLLED, "CONTROLLED"))
        # the turret turns at the commanded 0.5 rad/s until the joint reports it moved
        moved = await _until(
            operator, "JointCommand",
            {"vehicle_id": vid, "operator_id": "op1", "device": "manipulator",
             "quantity": "velocity", "values": [0.5, 0.0, 0.0]}, "JointState",
            lambda s: s["vehicle_id"] == vid and s["device"] == "manipulator"
            and s["quantity"] == "position" and s["values"][0] > 0.3)
        assert moved["units"] == ["rad", "rad", "m"]
        # the pan-tilt goes to a commanded position
        await _until(
            operator, "JointCommand",
            {"vehicle_id": vid, "operator_id": "op1", "device": "pan_tilt",
             "quantity": "position", "values": [0.4, -0.2]}, "JointState",
            lambda s: s["vehicle_id"] == vid and s["device"] == "pan_tilt"
            and s["quantity"] == "position"
            and s["values"] == pytest.approx([0.4, -0.2], abs=0.02))
        # a new motion profile is stored and read back in the vehicle's layout
        await _until(
            operator, "JointCommand",
            {"vehicle_id": vid, "operator_id": "op1", "device": "manipulator",
             "quantity": "motion_profile", "values": [0.3, 0.6, 0.6, 0.2, 0.4, 0.4,
                                                      0.05, 0.1, 0.1],
             "units": ["rad", "rad", "m"]}, "JointState",
            lambda s: s["vehicle_id"] == vid and s["device"] == "manipulator"
            and s["quantity"] == "max_speed"
            and s["values"] == pytest.approx([0.3, 0.2, 0.05], abs=1e-3))
        # a longer tool: the offset reads back, and the tool point moves out with it
        await _until(
            operator, "EndEffectorCommand",
            {"vehicle_id": vid, "operator_id": "op1", "mode": "tool_offset", "x": 0.0,
             "y": 0.0, "z": 0.35}, "EndEffectorPose",
            lambda s: s["vehicle_id"] == vid and s["kind"] == "tool_offset"
            and s["z"] == pytest.approx(0.35, abs=1e-3))
        arm = JausAddress(spec.subsystem, 1, 5)
        assert ("manipulator-1.0" in runtime.engine.dialects_of(arm)) is (name == "eod-v1")
        (endpoint,) = sim.endpoints
        assert endpoint.vehicle is not None
        assert endpoint.vehicle.counters["commands_obeyed"] >= 4

    asyncio.run(run())
    # the relay's own capture decodes as the vehicle sent it: `decode --dialect auto`
    # learns the version from the ReportServices in it
    decoded = _decode(capture)
    reports = [o.get("report") or o for o in decoded]
    report = next(r for r in reports if r.get("message") == "ReportJointMotionProfile")
    v1 = name == "eod-v1"
    assert report.get("dialect") == ("manipulator-1.0" if v1 else None)
    assert list(report["fields"]) == (["motion_profile_list"] if v1
                                      else ["joint_motion_profile_list"])
    assert not [o for o in decoded if "error" in o]


def _decode(capture: Path) -> list[dict[str, Any]]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["decode", "--dialect", "auto", str(capture)]) == 0
    return [json.loads(line) for line in out.getvalue().splitlines()]
