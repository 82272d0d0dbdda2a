"""The plan on the vehicle read back, path segments, and the Mission Spooler, end to end.

Real UDP on loopback between the relay (in-process) and a simulated UGV, a real Cyclone DDS
participant as the operator station: send a plan and read back what the vehicle holds;
spool a mission, run, pause, resume and abort it and watch its state.
"""

from __future__ import annotations

import asyncio
import json
import math
import time
from collections.abc import Callable
from typing import Any

import pytest

from edge_vis.config import from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY = JausAddress(200, 1, 1)
READY = 1


def profile(relay_ip: str, sim_ip: str, domain: int, partition: str) -> Any:
    return from_mapping({
        "relay": {"jaus_id": str(RELAY), "authority": 100},
        "links": {"lan": {"url": f"udp://{relay_ip}:3794?peers={sim_ip}:3794"}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "mobility", "mission_spooler"]},
        "discovery": {"period": 0.5, "liveness_period": 0.5},
        "control": {"retry_period": 0.5, "response_timeout": 0.5},
        "commands": {"rate": 10.0, "lifespan": 2.0, "deadman_timeout": 30.0},
    }, file="plans-e2e.toml")


class Latest:
    """Samples of one topic, read in the background of the test."""

    def __init__(self, operator: Any, topic: str) -> None:
        self.reader = operator.reader(topic)
        self.last: dict[str, Any] | None = None

    async def until(self, check: Callable[[dict[str, Any]], bool], what: str,
                    timeout: float = 10.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for sample in await asyncio.to_thread(self.reader.take, 0.1):
                self.last = sample
                if check(sample):
                    return sample
        raise AssertionError(f"timed out waiting for {what}; last sample: {self.last}")


async def until(check: Callable[[], bool], what: str, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.02)


def name(value: Any) -> str:
    return str(getattr(value, "name", value))


async def run_with_sim(octet: int, domain: int, partition: str,
                       body: Callable[[Any, Any, str], Any]) -> None:
    from edge_vis.tools.sim.profile import VehicleSpec
    from edge_vis.tools.sim.runner import UdpVehicle

    relay_ip, sim_ip = f"127.0.0.{octet}", f"127.0.0.{octet + 1}"
    sim = UdpVehicle(VehicleSpec("ugv-plan", 161, f"udp://{sim_ip}:3794", init_time=0.1))
    await sim.start()
    runtime = Runtime(profile(relay_ip, sim_ip, domain, partition))
    await runtime.start()
    operator = dds.DdsBridge(domain, (partition,))
    try:
        vid = "ugv-plan-161"
        vehicle = sim.vehicle
        assert vehicle is not None
        request = {"vehicle_id": vid, "operator_id": "op1", "authority": 50,
                   "action": "request"}
        platform = vehicle.component(2)
        deadline = time.monotonic() + 10
        while not (platform.controller == RELAY and platform.state == READY):
            assert time.monotonic() < deadline, "the relay never took and readied control"
            operator.publish("ControlRequest", request)
            await asyncio.sleep(0.1)
        await body(operator, vehicle, vid)
    finally:
        await runtime.stop()
        operator.close()
        await sim.stop()


def test_a_plan_sent_is_read_back_from_the_vehicle(domain_id: int, partition: str) -> None:
    async def body(operator: Any, vehicle: Any, vid: str) -> None:
        origin = vehicle.spec.origin
        plans = Latest(operator, "VehiclePlan")
        points = [origin.to_geodetic(x, y) for x, y in ((30.0, 0.0), (30.0, 30.0),
                                                        (0.0, 30.0))]
        assert operator.wait_for_subscribers("WaypointPlan", 1, 5.0)
        operator.publish("WaypointPlan", {
            "vehicle_id": vid, "operator_id": "op1", "plan_id": "survey", "frame": "GLOBAL",
            "speed": 1.0, "waypoints": [{"latitude": lat, "longitude": lon, "tolerance": 2.0}
                                        for lat, lon in points]})
        held = await plans.until(lambda s: s["complete"] and len(s["elements"]) == 3,
                                 "the three waypoints read back")
        assert held["component"] == "161.1.2" and held["element_count"] == 3
        assert [e["uid"] for e in held["elements"]] == [1, 2, 3]
        for element, (lat, lon) in zip(held["elements"], points, strict=True):
            assert element["message"] == "SetGlobalWaypoint"
            assert element["latitude"] == pytest.approx(lat, abs=1e-6)
            assert element["longitude"] == pytest.approx(lon, abs=1e-6)
            assert element["tolerance"] == pytest.approx(2.0, abs=0.01)
        assert [(e["previous_uid"], e["next_uid"]) for e in held["elements"]] == [
            (0, 2), (1, 3), (2, 0)]
        # what the vehicle holds is what it reports, not what was sent: change it behind
        # the relay's back and the plan shown follows
        vehicle.waypoints.elements[2].waypoint["latitude"] += 1e-4
        vehicle.waypoints.delete([3])
        held = await plans.until(lambda s: s["complete"] and len(s["elements"]) == 2,
                                 "the shorter list")
        assert [e["uid"] for e in held["elements"]] == [1, 2]

        # path segments: the list on the vehicle is replaced, the segment driven is shown
        (lat1, lon1), (lat2, lon2) = points[0], points[1]
        operator.publish("PathSegmentPlan", {
            "vehicle_id": vid, "operator_id": "op1", "plan_id": "bend", "frame": "GLOBAL",
            "speed": 1.0, "segments": [
                {"latitude": lat1, "longitude": lon1, "control_latitude": lat1,
                 "control_longitude": lon1, "weighting_factor": 0.0, "tolerance": 2.0},
                {"latitude": lat2, "longitude": lon2, "control_latitude": lat1,
                 "control_longitude": lon2, "weighting_factor": 1.0}]})
        held = await plans.until(
            lambda s: s["complete"] and len(s["elements"]) == 2
            and all(e["message"] == "SetGlobalPathSegment" for e in s["elements"])
            and s["current"]["message"] == "SetGlobalPathSegment", "the segments read back")
        second = held["elements"][1]
        assert (second["latitude"], second["control_longitude"]) == (
            pytest.approx(lat2, abs=1e-6), pytest.approx(lon2, abs=1e-6))
        assert second["weighting_factor"] == pytest.approx(1.0, abs=0.01)
        assert held["current"]["latitude"] == pytest.approx(lat1, abs=1e-6)
        assert math.isnan(held["current"]["x"])
        status = await Latest(operator, "MissionStatus").until(
            lambda s: s["plan_id"] == "bend" and name(s["state"]) == "MISSION_EXECUTING"
            and s["active_waypoint"] >= 0, "the segments executing")
        assert status["active_waypoint"] in (0, 1)

        # on demand (the holder): the whole plan is read again
        reads = vehicle.counters["received"]
        operator.publish("PlanQuery", {"vehicle_id": vid, "operator_id": "op1"})
        await plans.until(lambda s: s["complete"] and len(s["elements"]) == 2,
                          "the plan read again")
        assert vehicle.counters["received"] > reads

    asyncio.run(run_with_sim(221, domain_id, partition, body))


def order(vid: str, action: str, **extra: Any) -> dict[str, Any]:
    return {"vehicle_id": vid, "operator_id": "op1", "action": action, "mission_id": 7,
            **extra}


def test_a_mission_is_spooled_run_paused_resumed_and_aborted(domain_id: int,
                                                             partition: str) -> None:
    async def body(operator: Any, vehicle: Any, vid: str) -> None:
        statuses = Latest(operator, "SpoolerStatus")
        missions = Latest(operator, "SpoolerMissions")
        speed = {"message": "SetTravelSpeed", "destination": "161.1.2"}
        tasks = [{"task_id": 1, "child_tasks": [1], "messages": [
                     {**speed, "uid": u, "fields_json": json.dumps({"speed": float(u)}),
                      "blocking": u == 2} for u in (1, 2, 3)]},
                 {"task_id": 2, "messages": [
                     {**speed, "uid": 9, "fields_json": json.dumps({"speed": 0.5})}]}]
        assert operator.wait_for_subscribers("MissionSpoolCommand", 1, 5.0)
        operator.publish("MissionSpoolCommand", order(vid, "SPOOL", tasks=tasks))
        held = await missions.until(lambda s: [m["mission_id"] for m in s["missions"]] == [7]
                                    and s["plan_mission_id"] == 7, "the mission and its plan")
        assert held["missions"][0]["creator"] == str(RELAY)
        assert held["preference"] == 1.0  # ReportSpoolingPreferences, kept by the merge
        (root,) = held["plan"]  # the sim reports its mission's first task
        assert root["task_id"] == 1 and root["child_tasks"] == [1]
        assert [(m["uid"], m["message"], m["blocking"]) for m in root["messages"]] == [
            (1, "SetTravelSpeed", False), (2, "SetTravelSpeed", True),
            (3, "SetTravelSpeed", False)]
        third = json.loads(root["messages"][2]["fields_json"])
        assert third["speed"] == pytest.approx(3.0, abs=0.01)

        operator.publish("MissionSpoolCommand", order(vid, "RUN"))
        await statuses.until(lambda s: s["scope"] == "MISSION" and s["id"] == 7
                             and s["status"] == "RUNNING", "RUNNING")
        # the protocol: RESUME is for a paused mission; refused here with the reason
        operator.publish("MissionSpoolCommand", order(vid, "RESUME"))
        refusal = await statuses.until(lambda s: s["scope"] == "COMMAND", "the refusal")
        assert refusal["status"] == "REFUSED" and "RUNNING" in refusal["detail"]
        await until(lambda: vehicle.spooler.executed == [(7, 1, 1)], "the first message run")
        operator.publish("MissionSpoolCommand", order(vid, "PAUSE"))
        await statuses.until(lambda s: s["scope"] == "MISSION" and s["status"] == "PAUSED",
                             "PAUSED")
        done = len(vehicle.spooler.executed)
        await asyncio.sleep(2.5)
        assert len(vehicle.spooler.executed) == done  # nothing runs while paused
        # while paused the mission can be changed: the last message of task 1 goes
        operator.publish("MissionSpoolCommand", order(vid, "REMOVE_MESSAGES", task_id=1,
                                                      uids=[3]))
        await asyncio.sleep(0.5)
        operator.publish("MissionSpoolCommand", order(vid, "RESUME"))
        await statuses.until(lambda s: s["scope"] == "MISSION" and s["status"] == "RUNNING",
                             "RUNNING again")
        await until(lambda: len(vehicle.spooler.executed) == 2, "the next message run")
        operator.publish("MissionSpoolCommand", order(vid, "ABORT"))
        await statuses.until(lambda s: s["scope"] == "MISSION" and s["status"] == "ABORTED",
                             "ABORTED")
        await missions.until(lambda s: s["missions"] == [], "no mission held")
        await asyncio.sleep(1.5)
        assert vehicle.spooler.executed == [(7, 1, 1), (7, 1, 2)]  # 3 removed, 9 aborted

        # a mission that runs to its end
        operator.publish("MissionSpoolCommand", order(vid, "SPOOL", mission_id=8,
                                                      tasks=tasks[1:]))
        await missions.until(lambda s: [m["mission_id"] for m in s["missions"]] == [8],
                             "mission 8 held")
        operator.publish("MissionSpoolCommand", order(vid, "RUN", mission_id=8))
        await statuses.until(lambda s: s["scope"] == "MISSION" and s["id"] == 8
                             and s["status"] == "FINISHED", "FINISHED")
        assert vehicle.spooler.executed[-1] == (8, 2, 9)

    asyncio.run(run_with_sim(223, domain_id, partition, body))
