"""The emergency stop end to end: a real Cyclone DDS operator publishes EmergencyCommand, the
relay runs in-process over real UDP on loopback, and a JAUS vehicle written in the tests
(:mod:`emergency_peer`, from the Management JSIDL) says what reached it in which state."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable
from typing import Any

import pytest
from emergency_peer import EMERGENCY, READY, STANDBY, ManagedRobot, ManagedRobotUdp

from edge_vis.config import from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet
from edge_vis.shell.relay import Runtime

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY_ID = JausAddress(42, 1, 1)
SET_EMERGENCY, CLEAR_EMERGENCY = 0x0006, 0x0007
_IPS = iter(range(40, 90, 2))


async def wait_for(check: Callable[[], bool], timeout: float, what: str) -> float:
    start = time.monotonic()
    while not check():
        if time.monotonic() - start > timeout:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        await asyncio.sleep(0.01)
    return time.monotonic() - start


class Station:
    """The operator station: a DDS participant of its own."""

    def __init__(self, domain: int, partition: str) -> None:
        self.bridge = dds.DdsBridge(domain, (partition,))
        self.bridge.open_writers(["ControlRequest", "EmergencyCommand", "WrenchEffortCommand"])
        self.status = self.bridge.reader("VehicleStatus")
        self.control = self.bridge.reader("ControlStatus")
        self.vehicle_id = ""
        self.latest: dict[str, dict[str, Any]] = {}

    def poll(self) -> None:
        for topic, reader in (("VehicleStatus", self.status), ("ControlStatus", self.control)):
            for sample in reader.take(0.0, 256):
                self.latest[topic] = sample
                self.vehicle_id = self.vehicle_id or sample["vehicle_id"]

    def emergency(self, action: str, operator: str, authority: int, reason: str = "") -> None:
        self.bridge.publish("EmergencyCommand", {
            "vehicle_id": self.vehicle_id, "operator_id": operator, "action": action,
            "authority": authority, "reason": reason})

    def request(self, operator: str, authority: int) -> None:
        self.bridge.publish("ControlRequest", {"vehicle_id": self.vehicle_id,
                                               "operator_id": operator,
                                               "authority": authority, "action": "request"})

    def drive(self, operator: str, effort: float = 30.0) -> None:
        self.bridge.publish("WrenchEffortCommand", {
            "vehicle_id": self.vehicle_id, "operator_id": operator,
            "propulsive_linear_x": effort})


Body = Callable[[Runtime, ManagedRobot, ManagedRobotUdp, Station], Awaitable[None]]


async def with_rig(domain: int, partition: str, body: Body, *, pop_to: int | None = None,
                   bandwidth: int | None = None, **sections: Any) -> None:
    loop = asyncio.get_running_loop()
    octet = next(_IPS)
    relay_ip, peer_ip = f"127.0.19.{octet}", f"127.0.19.{octet + 1}"
    robot = ManagedRobot(pop_to=pop_to)
    udp = ManagedRobotUdp(robot)
    await loop.create_datagram_endpoint(lambda: udp, local_addr=(peer_ip, 3794))
    url = f"udp://{relay_ip}:3794?peers={peer_ip}:3794"
    if bandwidth:
        url += f"&bandwidth={bandwidth}"
    data: dict[str, Any] = {
        "relay": {"jaus_id": str(RELAY_ID), "authority": 150},
        "links": {"lan": {"url": url}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "emergency", "mobility"]},
        "operators": [{"id": "op1", "max_authority": 100}, {"id": "op2", "max_authority": 200},
                      {"id": "op3", "max_authority": 50}],
        "discovery": {"period": 0.3, "liveness_period": 0.2, "lost_after": 3,
                      "response_timeout": 0.5},
        "control": {"renewal_period": 1.0, "response_timeout": 0.3, "retry_period": 0.5},
        "commands": {"rate": 10.0, "lifespan": 0.5, "deadman_timeout": 5.0},
        "emergency": {"retry_period": 0.2},
    }
    data.update(sections)
    runtime = Runtime(from_mapping(data, file="emergency-e2e.toml"))
    station = Station(domain, partition)
    await runtime.start()
    try:
        await wait_for(lambda: (station.poll(), bool(station.vehicle_id))[1], 10,
                       "the vehicle on DDS")
        await wait_for(lambda: (station.poll(), station.latest.get("VehicleStatus", {})
                                .get("state") == "STANDBY")[1], 10, "its status")
        await body(runtime, robot, udp, station)
    finally:
        await runtime.stop()
        station.bridge.close()
        udp.close()


def states(robot: ManagedRobot) -> list[int]:
    return [c.state for c in robot.components.values()]


def test_set_reaches_every_management_component_without_control_and_only_allowed_clear(
        domain_id: int, partition: str) -> None:
    async def body(runtime: Runtime, robot: ManagedRobot, udp: ManagedRobotUdp,
                   station: Station) -> None:
        station.emergency("SET", "op1", 60, "person in the way")
        await wait_for(lambda: states(robot) == [EMERGENCY, EMERGENCY], 2,
                       "both components in EMERGENCY")
        assert not robot.arrivals("RequestControl"), "an emergency needs no control"
        assert {c.controller for c in robot.components.values()} == {None}
        for component in (1, 2):
            assert robot.components[component].emergency_ids == {RELAY_ID}
        await wait_for(lambda: (station.poll(), station.latest["VehicleStatus"]
                                .get("emergency") is True)[1], 3, "VehicleStatus.emergency")
        status = station.latest["VehicleStatus"]
        assert status["emergency_operator"] == "op1"
        assert status["emergency_reason"] == "person in the way"
        assert status["state"] == "EMERGENCY"
        # confirmed by ReportStatus: the relay stops sending it again
        await asyncio.sleep(0.6)
        sent = len(robot.arrivals("SetEmergency"))
        await asyncio.sleep(0.6)
        assert len(robot.arrivals("SetEmergency")) == sent

        # op3 (authority 50) may not clear what op1 set with 60: refused, with the reason
        station.emergency("CLEAR", "op3", 50)
        await wait_for(lambda: (station.poll(), "below the setter" in station.latest.get(
            "ControlStatus", {}).get("last_rejection", ""))[1], 3, "the refusal")
        rejection = station.latest["ControlStatus"]["last_rejection"]
        assert "op3" in rejection and "authority 50" in rejection, rejection
        assert station.latest["ControlStatus"]["emergency"] is True
        assert not robot.arrivals("ClearEmergency")
        # an operator not listed at all is refused too
        station.emergency("CLEAR", "intruder", 255)
        await wait_for(lambda: (station.poll(), "intruder" in station.latest.get(
            "ControlStatus", {}).get("last_rejection", ""))[1], 3, "the second refusal")
        assert states(robot) == [EMERGENCY, EMERGENCY]

        # op2 (authority 150 >= 60) may: both components leave EMERGENCY
        station.emergency("CLEAR", "op2", 150)
        await wait_for(lambda: states(robot) == [STANDBY, STANDBY], 2, "the clear")
        await wait_for(lambda: (station.poll(), station.latest["VehicleStatus"]
                                .get("emergency") is False)[1], 3, "emergency over on DDS")
        assert all(a.source == RELAY_ID for a in robot.arrivals("ClearEmergency"))

    asyncio.run(with_rig(domain_id, partition, body))


def test_no_motion_in_emergency_and_motion_resumes_only_after_ready(
        domain_id: int, partition: str) -> None:
    async def body(runtime: Runtime, robot: ManagedRobot, udp: ManagedRobotUdp,
                   station: Station) -> None:
        driver = robot.components[1]
        station.request("op1", 80)
        done = False

        async def drive() -> None:
            while not done:
                station.drive("op1")
                await asyncio.sleep(0.05)

        task = asyncio.get_running_loop().create_task(drive())
        try:
            await wait_for(lambda: len(driver.obeyed) >= 3, 5, "driving")
            set_at = time.monotonic()
            station.emergency("SET", "op1", 80)
            await wait_for(lambda: states(robot) == [EMERGENCY, EMERGENCY], 2, "EMERGENCY")
            obeyed = len(driver.obeyed)
            await asyncio.sleep(1.0)  # the operator keeps pushing the stick
            assert len(driver.obeyed) == obeyed
            motion = robot.arrivals("SetWrenchEffort")
            assert not [a for a in motion if a.state == EMERGENCY], \
                "a motion command reached the vehicle in EMERGENCY"
            assert [a for a in motion if a.at > set_at + 0.3] == []
            # control survives the emergency (NOT_AVAILABLE answers to renewals)
            assert driver.controller == RELAY_ID
            station.poll()
            assert station.latest["ControlStatus"]["state"] == "CONTROLLED"

            cleared_at = time.monotonic()
            station.emergency("CLEAR", "op1", 80)
            # this vehicle comes back in STANDBY: the relay must Resume before commanding
            await wait_for(lambda: len(driver.obeyed) > obeyed, 3, "motion after the clear")
        finally:
            done = True
            await task
        resume = [a for a in robot.arrivals("Resume", 1) if a.at >= cleared_at]
        assert resume, "no Resume after the clear"
        after = [a for a in robot.arrivals("SetWrenchEffort") if a.at >= cleared_at]
        assert after and after[0].at >= resume[0].at
        assert {a.state for a in after} == {READY}, "motion sent before READY"
        assert not [a for a in robot.arrivals("SetWrenchEffort") if a.state != READY]

    asyncio.run(with_rig(domain_id, partition, body, pop_to=STANDBY))


def test_set_jumps_a_full_paced_link_queue(domain_id: int, partition: str) -> None:
    """4,800 bit/s, 45 kB of telemetry queued in 1.5 kB packets (over the 32 kB limit: the
    oldest are dropped), each one 2.5 s on the link: the SET leaves at once, ahead of what
    waits, without waiting for the budget the last packet used."""
    async def body(runtime: Runtime, robot: ManagedRobot, udp: ManagedRobotUdp,
                   station: Station) -> None:
        loop = asyncio.get_running_loop()
        nobody = JausAddress(robot.subsystem, 1, 9)  # no such component: ignored
        payload = bytes((0x02, 0x22)) + bytes(1500)  # QueryHeartbeatPulse + padding
        now = loop.time()
        for _ in range(30):
            runtime._carry_router(runtime.router.send(
                Packet(nobody, RELAY_ID, payload, priority=0), now), now)
        queue = runtime.router.stats().links["lan"]
        assert queue.queued_bytes > 30_000 and queue.drops, "the queue is not full"
        await asyncio.sleep(0.2)  # a filler packet left: the budget is spent
        station.emergency("SET", "op2", 150)
        took = await wait_for(lambda: any(c == SET_EMERGENCY for _, c in udp.packets), 2,
                              "SetEmergency on the wire")
        assert took < 0.5, f"SetEmergency took {took:.2f} s"
        first = next(i for i, (_, c) in enumerate(udp.packets) if c == SET_EMERGENCY)
        assert len([c for _, c in udp.packets[:first] if c == 0x2202]) <= 2
        assert runtime.router.stats().links["lan"].depth >= 15, "the queue drained first"
        await wait_for(lambda: states(robot) == [EMERGENCY, EMERGENCY], 5, "EMERGENCY")
        assert runtime.router.stats().counters["sent urgently"] >= 2

    asyncio.run(with_rig(domain_id, partition, body, bandwidth=4800))


def test_set_for_an_offline_vehicle_goes_out_when_it_is_found(
        domain_id: int, partition: str) -> None:
    async def body(runtime: Runtime, robot: ManagedRobot, udp: ManagedRobotUdp,
                   station: Station) -> None:
        robot.silent = True
        await wait_for(lambda: (station.poll(), station.latest["VehicleStatus"]
                                .get("online") is False)[1], 5, "the vehicle lost")
        station.emergency("SET", "op1", 60)
        await wait_for(lambda: (station.poll(), station.latest["VehicleStatus"]
                                .get("emergency") is True)[1], 3, "the SET taken")
        await asyncio.sleep(1.0)
        assert not [c for _, c in udp.packets if c == SET_EMERGENCY], \
            "sent to a vehicle known to be offline"
        back = time.monotonic()
        robot.silent = False
        await wait_for(lambda: states(robot) == [EMERGENCY, EMERGENCY], 5,
                       "the SET delivered once found")
        first = min(a.at for a in robot.arrivals("SetEmergency"))
        assert first >= back

    asyncio.run(with_rig(domain_id, partition, body))
