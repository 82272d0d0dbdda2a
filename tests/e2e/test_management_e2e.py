"""Management commands, who holds control and vehicles' clocks, end to end.

Real UDP on loopback, the relay in-process, a real Cyclone DDS participant as the operator:
once against :class:`~tests.e2e.control_peers.ContestedRobot` (a robot another client
controls, written in the tests), once against two simulated UGVs.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

import pytest
from discovery_peers import UdpPeer

from edge_vis.config import from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .control_peers import FOREIGN, READY, SHUTDOWN, STANDBY, ContestedRobot

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY = JausAddress(200, 1, 1)


def relay_profile(relay_ip: str, peers: list[str], domain: int, partition: str,
                  **extra: dict[str, Any]) -> Any:
    data: dict[str, Any] = {
        "relay": {"jaus_id": str(RELAY), "authority": 100},
        "links": {"lan": {"url": f"udp://{relay_ip}:3794?peers="
                                 + ",".join(f"{p}:3794" for p in peers)}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "management", "mobility"]},
        "discovery": {"period": 0.5, "liveness_period": 0.5},
        "control": {"retry_period": 0.5, "response_timeout": 0.5, "holder_query_period": 1.0},
        "commands": {"rate": 10.0, "lifespan": 1.0, "deadman_timeout": 30.0},
    }
    for key, value in extra.items():
        data[key] = {**data.get(key, {}), **value}
    return from_mapping(data, file="management-e2e.toml")


class Latest:
    """The newest sample of a topic per vehicle, read in the background of the test."""

    def __init__(self, operator: Any, topic: str) -> None:
        self.reader = operator.reader(topic)
        self.by_vehicle: dict[str, dict[str, Any]] = {}
        self.seen: list[dict[str, Any]] = []

    async def until(self, vehicle: str | None, check: Callable[[dict[str, Any]], bool],
                    what: str, timeout: float = 10.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            for sample in await asyncio.to_thread(self.reader.take, 0.1):
                self.seen.append(sample)
                self.by_vehicle[sample["vehicle_id"]] = sample
                if (vehicle is None or sample["vehicle_id"] == vehicle) and check(sample):
                    return sample
            if time.monotonic() > deadline:
                last = self.by_vehicle.get(vehicle or "", self.seen[-1] if self.seen else None)
                raise AssertionError(f"timed out waiting for {what}; last sample: {last}")


def holder(sample: dict[str, Any], component: str) -> dict[str, Any] | None:
    return next((h for h in sample["holders"] if h["component"] == component), None)


def state_name(value: Any) -> str:
    return str(getattr(value, "name", value))


def test_contested_robot_holders_refusals_authority_and_clock(
        domain_id: int, partition: str) -> None:
    relay_ip, peer_ip = "127.0.0.141", "127.0.0.142"
    robot = ContestedRobot(JausAddress(60, 1, 1), foreign_authority=120, clock_offset=5.0)
    profile = relay_profile(relay_ip, [peer_ip], domain_id, partition,
                            control={"authority_from_operator": True},
                            time={"set_on_discovery": True, "set_threshold": 1.0,
                                  "query_period": 1.0})

    async def main() -> None:
        loop = asyncio.get_running_loop()
        peer = UdpPeer(robot)
        await loop.create_datagram_endpoint(lambda: peer, local_addr=(peer_ip, 3794))
        runtime = Runtime(profile)
        await runtime.start()
        operator = dds.DdsBridge(domain_id, (partition,))
        try:
            operator.open_writers(["ControlRequest", "ManagementCommand"])
            control = Latest(operator, "ControlStatus")
            clocks = Latest(operator, "VehicleClock")
            vid = "Contested-60"

            # Another client holds the robot: ControlStatus names it, not the relay.
            status = await control.until(vid, lambda s: bool(
                (h := holder(s, "60.1.1")) and h["controller"] == str(FOREIGN)),
                "the foreign holder")
            assert holder(status, "60.1.1") == {
                "component": "60.1.1", "controller": "9.1.5", "authority": 120,
                "current_authority": 120, "is_relay": False}

            # The clock is 5 s off; SetTime needs control, which the foreign client's
            # higher authority keeps from the relay: read, noted, not set.
            clock = await clocks.until(vid, lambda s: "refused" in s["note"], "SetTime note")
            assert clock["offset_ms"] == pytest.approx(5000, abs=300)
            assert clock["set_time_sent"] == 0 and clock["component"] == "60.1.1"
            assert not robot.names("SetTime")

            # An operator holds the vehicle through the relay, but the robot refuses the
            # relay's authority: a management command is not sent, and says why.
            def request(authority: int) -> None:
                operator.publish("ControlRequest", {"vehicle_id": vid, "operator_id": "op1",
                                                    "authority": authority,
                                                    "action": "request"})

            request(90)
            await control.until(vid, lambda s: state_name(s["state"]) == "REJECTED",
                                "the robot refusing the relay")
            assert robot.names("RequestControl")[-1]["authority_code"] == 90  # the operator's
            operator.publish("ManagementCommand", {"vehicle_id": vid, "operator_id": "op1",
                                                   "command": "STANDBY"})
            status = await control.until(vid, lambda s: "Standby" in s["last_rejection"],
                                         "the Standby refusal")
            assert "held by 9.1.5 (authority 120)" in status["last_rejection"]
            assert status["rejected_commands"] >= 1
            assert not robot.names("Standby")

            # The other client lets go: the relay gets control, and ControlStatus says so.
            robot.foreign_release()
            status = await control.until(vid, lambda s: bool(
                (h := holder(s, "60.1.1")) and h["is_relay"]), "the relay as holder")
            assert holder(status, "60.1.1")["controller"] == "200.1.1"
            assert holder(status, "60.1.1")["authority"] == 90
            assert not robot.names("SetTime")  # decided on discovery, not later

            # The operator lowers its authority: SetAuthority, then it shows.
            request(60)
            status = await control.until(vid, lambda s: (
                h := holder(s, "60.1.1")) is not None and h["current_authority"] == 60,
                "the lowered authority")
            assert [f["authority_code"] for f in robot.names("SetAuthority")] == [60]
            assert robot.authority == 60
            # Raising it goes out as RequestControl (SetAuthority cannot raise it).
            request(95)
            await control.until(vid, lambda s: (h := holder(s, "60.1.1")) is not None
                                and h["current_authority"] == 95, "the raised authority")
            assert robot.names("RequestControl")[-1]["authority_code"] == 95
            assert len(robot.names("SetAuthority")) == 1

            # With control the management commands are obeyed.
            await wait(lambda: robot.status == READY, "READY (the relay's Resume)")
            for command, expected in (("STANDBY", STANDBY), ("RESUME", READY),
                                      ("SHUTDOWN", SHUTDOWN)):
                operator.publish("ManagementCommand", {"vehicle_id": vid,
                                                       "operator_id": "op1",
                                                       "command": command})
                await wait(lambda e=expected: robot.status == e, command)
            assert robot.controller is None  # Shutdown ends control
        finally:
            operator.close()
            await runtime.stop()
            peer.close()

    asyncio.run(main())


async def wait(check: Callable[[], bool], what: str, timeout: float = 8.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.02)


def test_sim_management_commands_and_clock_setting(domain_id: int, partition: str) -> None:
    from edge_vis.tools.sim.profile import VehicleSpec
    from edge_vis.tools.sim.runner import UdpVehicle

    relay_ip, ip_a, ip_b = "127.0.0.145", "127.0.0.146", "127.0.0.147"
    profile = relay_profile(relay_ip, [ip_a, ip_b], domain_id, partition,
                            time={"set_on_discovery": True, "set_threshold": 1.0,
                                  "query_period": 1.0})

    async def main() -> None:
        far = UdpVehicle(VehicleSpec("ugv-far", 151, f"udp://{ip_a}:3794", init_time=0.1,
                                     clock_offset=3.0))
        near = UdpVehicle(VehicleSpec("ugv-near", 152, f"udp://{ip_b}:3794", init_time=0.1,
                                      clock_offset=0.3))
        await far.start()
        await near.start()
        runtime = Runtime(profile)
        await runtime.start()
        operator = dds.DdsBridge(domain_id, (partition,))
        try:
            operator.open_writers(["ControlRequest", "ManagementCommand", "WrenchEffortCommand"])
            control = Latest(operator, "ControlStatus")
            clocks = Latest(operator, "VehicleClock")
            statuses = Latest(operator, "VehicleStatus")
            sim_far, sim_near = far.vehicle, near.vehicle
            assert sim_far is not None and sim_near is not None

            # Clocks: the far one is set once (above the threshold), the near one is not.
            clock = await clocks.until("ugv-far-151", lambda s: s["set_time_sent"] == 1
                                       and abs(s["offset_ms"]) < 250, "the far clock set")
            assert sim_far.counters["set_time"] == 1
            clock = await clocks.until("ugv-near-152", lambda s: True, "the near clock")
            assert clock["offset_ms"] == pytest.approx(300, abs=150)
            assert clock["set_time_sent"] == 0
            await asyncio.sleep(1.5)  # more readings, still no SetTime
            assert sim_near.counters["set_time"] == 0 and sim_far.counters["set_time"] == 1
            # the relay let go of the far vehicle's Time component after setting it
            assert all(c.controller is None for c in sim_far.components.values())

            vid = "ugv-far-151"
            platform = sim_far.component(2)

            def manage(command: str) -> None:
                operator.publish("ManagementCommand", {"vehicle_id": vid,
                                                       "operator_id": "op1",
                                                       "command": command})

            # Without control: refused, with the reason, and nothing reaches the vehicle.
            manage("STANDBY")
            status = await control.until(vid, lambda s: "Standby" in s["last_rejection"],
                                         "the refusal")
            assert status["last_rejection"] == (
                "Standby from op1 refused: control held by nobody")
            assert sim_far.counters["commands_ignored"] == 0

            operator.publish("ControlRequest", {"vehicle_id": vid, "operator_id": "op1",
                                                "authority": 50, "action": "request"})
            await statuses.until(vid, lambda s: state_name(s["state"]) == "READY", "READY")
            status = await control.until(vid, lambda s: bool(
                (h := holder(s, "151.1.2")) and h["is_relay"]), "the relay holding")
            assert holder(status, "151.1.2")["authority"] == 100  # the relay's own

            manage("STANDBY")
            await statuses.until(vid, lambda s: state_name(s["state"]) == "STANDBY",
                                 "STANDBY")
            await asyncio.sleep(1.5)  # the relay does not Resume behind the operator's back
            assert platform.state == 2 and platform.controller == RELAY
            operator.publish("WrenchEffortCommand", {"vehicle_id": vid, "operator_id": "op1",
                                                     "propulsive_linear_x": 30.0})
            status = await control.until(vid, lambda s: "SetWrenchEffort" in s[
                "last_rejection"], "the motion refusal in STANDBY")
            assert status["last_rejection"] == (
                "SetWrenchEffort refused: 151.1.2 in STANDBY at the operator's request "
                "(send Resume)")
            manage("RESUME")
            await statuses.until(vid, lambda s: state_name(s["state"]) == "READY",
                                 "READY after Resume")
            manage("RESET")
            await wait(lambda: sim_far.counters["obeyed_reset"] == 1, "Reset")
            # after the reset the relay takes control again and brings it back to READY
            await statuses.until(vid, lambda s: state_name(s["state"]) == "READY",
                                 "READY after Reset", timeout=15)
            manage("SHUTDOWN")
            await statuses.until(vid, lambda s: state_name(s["state"]) == "SHUTDOWN",
                                 "SHUTDOWN")
            assert platform.controller is None
            assert sim_far.counters["commands_ignored"] == 0  # every command was the holder's
        finally:
            operator.close()
            await runtime.stop()
            await far.stop()
            await near.stop()

    asyncio.run(main())
