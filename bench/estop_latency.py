"""Emergency stop latency: from the DDS sample to the SetEmergency on the wire.

An operator participant (real Cyclone DDS, its own participant in this process) publishes
``EmergencyCommand`` SET samples; the relay (the real runtime, DDS bridge included) turns
each into SetEmergency. Two set-ups:

* ``loopback`` - UDP on loopback to a JAUS vehicle (``tests/emergency_peer.py``); the time
  is taken when the datagram arrives at the vehicle's socket.
* ``radio``    - the emulated half-duplex 19,200 bit/s serial radio of
  ``bench/bandwidth.py`` (``tests/bandwidth/radiohub.py``, real ptys), three simulated
  UGVs whose pose and velocity events fill the relay's 80 % budget, an operator driving
  each at 2 Hz. Two times: when the relay wrote the SetEmergency frame to its serial
  port, and when the radio put it on the air to the vehicles (after the frame the radio
  was carrying, and whatever vehicles queued before it, since the radio has one FIFO).

Target: p99 below one frame on the air (MTU 256 + 32 bytes: 0.150 s at 19,200 bit/s)
+ 50 ms. ::

    .venv/bin/python bench/estop_latency.py [--samples 200] [--only loopback|radio]
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
import time
import uuid
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "bandwidth"))
sys.path.insert(0, str(ROOT / "bench"))

from bandwidth import BAUD, VEHICLES, sim_profile  # noqa: E402
from emergency_peer import ManagedRobot, ManagedRobotUdp  # noqa: E402
from radiohub import RadioHub  # noqa: E402

from edge_vis.catalogue import default_catalogue  # noqa: E402
from edge_vis.config import from_mapping  # noqa: E402
from edge_vis.shell.relay import Runtime  # noqa: E402
from edge_vis.tools.sim.runner import Simulation  # noqa: E402

SET_EMERGENCY = 0x0006
#: one MTU frame on the air: 256 bytes of payload + 14 of header + 18 of serial framing
FRAME_S = (256 + 14 + 18) / (BAUD / 10)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def operator_bridge(domain: int, partition: str) -> Any:
    from edge_vis.dds import DdsBridge

    bridge = DdsBridge(domain, (partition,))
    bridge.open_writers(["EmergencyCommand", "ControlRequest", "WrenchEffortCommand"])
    return bridge


def estop(bridge: Any, vehicle_id: str) -> None:
    bridge.publish("EmergencyCommand", {"vehicle_id": vehicle_id, "operator_id": "op",
                                        "action": "SET", "authority": 200, "reason": "bench"})


async def wait_matched(bridge: Any, runtime: Runtime) -> None:
    for _ in range(200):
        if bridge.matched_subscribers("EmergencyCommand"):
            return
        await asyncio.sleep(0.05)
    raise SystemExit("the relay's EmergencyCommand reader never matched")


async def loopback(samples: int, domain: int) -> list[float]:
    loop = asyncio.get_running_loop()
    partition = f"estop-bench-{uuid.uuid4().hex[:8]}"
    robot = ManagedRobot()
    udp = ManagedRobotUdp(robot)
    await loop.create_datagram_endpoint(lambda: udp, local_addr=("127.0.23.2", 3794))
    runtime = Runtime(from_mapping({
        "relay": {"jaus_id": "42.1.1", "authority": 150},
        "links": {"lan": {"url": "udp://127.0.23.1:3794?peers=127.0.23.2:3794"}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "emergency"]},
        "discovery": {"period": 0.3, "liveness_period": 0.5},
        "emergency": {"retry_period": 60.0},
    }))
    await runtime.start()
    bridge = operator_bridge(domain, partition)
    latencies: list[float] = []
    try:
        vehicle = "ManagedBot-88"
        while runtime.engine is None or runtime.engine.vehicle(vehicle) is None \
                or not runtime.engine.vehicle(vehicle).services_known:  # type: ignore
            await asyncio.sleep(0.05)
        await wait_matched(bridge, runtime)
        for _ in range(samples):
            seen = len(udp.packets)
            sent = time.monotonic()
            estop(bridge, vehicle)
            while not any(c == SET_EMERGENCY for _, c in udp.packets[seen:]):
                await asyncio.sleep(0.0005)
                if time.monotonic() - sent > 5:
                    raise SystemExit("a SET never reached the vehicle")
            at = next(t for t, c in udp.packets[seen:] if c == SET_EMERGENCY)
            latencies.append(at - sent)
            await asyncio.sleep(0.02)
    finally:
        await runtime.stop()
        bridge.close()
        udp.close()
    return latencies


async def radio(samples: int, domain: int) -> tuple[list[float], list[float], float]:
    loop = asyncio.get_running_loop()
    partition = f"estop-bench-{uuid.uuid4().hex[:8]}"
    hub = RadioHub(BAUD, command_codes=frozenset({SET_EMERGENCY}))
    sim = Simulation(sim_profile(False), default_catalogue())
    await sim.start()
    for endpoint in sim.endpoints:
        hub.add_vehicle(endpoint.slave_path)  # type: ignore[attr-defined]
    hub.start()
    runtime = Runtime(from_mapping({
        "relay": {"jaus_id": "200.1.1", "authority": 200},
        "links": {"radio": {"url": f"serial://{hub.relay_path}?baud={BAUD}", "bit_rate": BAUD,
                            "bits_per_byte": 10, "half_duplex": True, "budget": 0.8,
                            "mtu": 256, "overhead": 18, "latency": 0.0}},
        "dds": {"domain": domain, "partitions": [partition]},
        "discovery": {"period": 10.0, "liveness_period": 1.0, "lost_after": 10,
                      "response_timeout": 6.0},
        "events": {"response_timeout": 6.0},
        "translators": {"enabled": ["core", "emergency", "mobility"]},
        "emergency": {"retry_period": 60.0},
        "report_rates": {
            "ReportGlobalPose": {"desired": 10.0, "minimum": 2.0, "priority": 7},
            "ReportVelocityState": {"desired": 10.0, "minimum": 1.0, "priority": 5},
        },
        "vehicles": [{"vehicle_id": f"ugv-{i + 1}", "subsystem": 101 + i, "link": "radio"}
                     for i in range(VEHICLES)],
    }))
    await runtime.start()
    bridge = operator_bridge(domain, partition)
    written: list[float] = []
    on_air: list[float] = []
    start = loop.time()
    try:
        await wait_matched(bridge, runtime)
        for i in range(VEHICLES):
            bridge.publish("ControlRequest", {"vehicle_id": f"ugv-{i + 1}", "operator_id": "op",
                                              "action": "REQUEST", "authority": 200})
        await asyncio.sleep(12.0)  # warm-up: discovery, events, control, the plan settles
        carried = hub.stats.carried
        measured_from = loop.time()
        for n in range(samples):
            vehicle = f"ugv-{n % VEHICLES + 1}"
            for i in range(VEHICLES):  # the operator keeps driving (refused in EMERGENCY)
                bridge.publish("WrenchEffortCommand", {
                    "vehicle_id": f"ugv-{i + 1}", "operator_id": "op",
                    "propulsive_linear_x": 20.0})
            seen = len(hub.stats.commands)
            sent = loop.time()
            estop(bridge, vehicle)
            while len(hub.stats.commands) == seen:
                await asyncio.sleep(0.002)
                if loop.time() - sent > 10:
                    raise SystemExit("a SET never went on the air")
            _code, _payload, done, queued = hub.stats.commands[seen]
            written.append(queued - sent)
            on_air.append(done - sent)
            await asyncio.sleep(0.5)
        load = (hub.stats.carried - carried) / (loop.time() - measured_from) / (BAUD / 10)
    finally:
        await runtime.stop()
        bridge.close()
        await hub.close()
        await sim.stop()
    del start
    return written, on_air, load


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--only", choices=("loopback", "radio"), default=None)
    parser.add_argument("--domain", type=int, default=100 + os.getpid() % 100)
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    from edge_vis.dds import loopback_config

    os.environ.setdefault("CYCLONEDDS_URI", loopback_config())
    target = FRAME_S + 0.050
    print(f"DDS EmergencyCommand sample -> SetEmergency, {args.samples} samples per run; "
          f"target p99 < one frame on air ({FRAME_S * 1000:.0f} ms) + 50 ms = "
          f"{target * 1000:.0f} ms")
    head = f"{'path':<52} {'p50':>9} {'p99':>9} {'max':>9}"
    print(head)
    print("-" * len(head))

    def row(label: str, values: list[float]) -> None:
        print(f"{label:<52} {percentile(values, 0.5) * 1000:7.2f}ms "
              f"{percentile(values, 0.99) * 1000:7.2f}ms {max(values) * 1000:7.2f}ms")

    if args.only in (None, "loopback"):
        row("loopback UDP, datagram at the vehicle", asyncio.run(loopback(args.samples,
                                                                         args.domain)))
    if args.only in (None, "radio"):
        written, on_air, load = asyncio.run(radio(args.samples, args.domain + 1))
        row("19.2 kbit/s radio, frame written by the relay", written)
        row("19.2 kbit/s radio, frame on the air to the vehicles", on_air)
        print(f"radio load while measuring: {load:.0%} of its capacity")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
