"""Several relay processes on one DDS domain, one simulated vehicle they all reach.

Each relay is a real ``edge-vis run`` process with its own JAUS id and loopback address
and nothing else configured for sharing; the vehicle is the simulator's UDP vehicle in
this process; between each relay and the vehicle sits its own impairing wire
(:class:`~.harness.UdpWire`), so one relay's radio path can fail while the others' work.
An operator station (a :class:`~edge_vis.dds.DdsBridge`) requests control and drives at
10 Hz, and a *plain* reader - a Cyclone DataReader with default QoS, as
``cyclonedds subscribe`` or a station that never heard of edge-vis would use - records
which DDS writer each GlobalPose came from. Timers are scaled down as in ``harness``.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from edge_vis.jaus.address import JausAddress
from edge_vis.tools.sim.profile import VehicleSpec
from edge_vis.tools.sim.runner import VehicleEndpoint, endpoint_for

from .harness import UdpWire, Wire, _cancel

SUBSYSTEM = 131
OPERATOR = "op-relays"
EDGE_VIS = str(Path(sys.executable).with_name("edge-vis"))
#: one /24 of loopback per rig: 127.44.<pid-based>.<rig> (other suites use 127.0.*)
_rigs = itertools.count(1)
_BLOCK = 10 + os.getpid() % 200

PROFILE = """\
[relay]
jaus_id = "{jaus_id}"
authority = 150

[links.radio]
url = "udp://{ip}:3794?peers={peers}"

[dds]
domain = {domain}
partitions = ["{partition}"]

[translators]
enabled = ["core", "emergency", "mobility"]

[access]
any_operator = true

[discovery]
period = 0.5
liveness_period = 0.25
lost_after = 3
response_timeout = 0.5

[control]
renewal_period = 0.4
response_timeout = 0.4
retry_period = 0.3

[events]
response_timeout = 0.5
attempts = 2

[commands]
rate = 10.0
lifespan = 0.5
deadman_timeout = 0.5

[report_rates]
ReportGlobalPose = 10.0
"""


def relay_id(index: int) -> JausAddress:
    return JausAddress(201 + index, 1, 1)


class RelayGroup:
    """``count`` relay processes, one vehicle, one operator station, one plain reader."""

    def __init__(self, tmp: Path, domain: int, partition: str, count: int = 2, *,
                 control_timeout: int = 2) -> None:
        self.tmp = tmp
        self.domain = domain
        self.partition = partition
        self.count = count
        rig = next(_rigs) % 20
        self.net = f"127.44.{_BLOCK}"
        self.vehicle_ip = f"{self.net}.{rig * 12 + 1}"
        self.relay_ips = [f"{self.net}.{rig * 12 + 2 + i}" for i in range(count)]
        self.wire_ips = [f"{self.net}.{rig * 12 + 6 + i}" for i in range(count)]
        spec = VehicleSpec(name="ugv-shared", subsystem=SUBSYSTEM,
                           link=f"udp://{self.vehicle_ip}:3794",
                           control_timeout=control_timeout, event_timeout=1, init_time=0.2,
                           seed=5)
        self.endpoint: VehicleEndpoint = endpoint_for(spec)
        self.wires = [Wire() for _ in range(count)]
        self.udp: list[UdpWire] = []
        self.procs: list[subprocess.Popen[bytes] | None] = [None] * count
        self.logs = [tmp / f"relay-{i}.log" for i in range(count)]
        self.operator: Any = None
        self.vehicle_id = ""
        #: (arrival, publication handle) of each GlobalPose the plain reader got
        self.poses: list[tuple[float, int]] = []
        #: (arrival, relay) of each VehicleStatus
        self.statuses: list[tuple[float, str]] = []
        self._plain: Any = None
        self._readers: dict[str, Any] = {}
        self._tasks: list[asyncio.Task[None]] = []
        self.driving = False

    # -- set-up ------------------------------------------------------------------------------
    async def start(self) -> None:
        await self.endpoint.start()
        for i in range(self.count):
            udp = UdpWire(self.wires[i], self.wire_ips[i], (self.vehicle_ip, 3794))
            await udp.open()
            self.udp.append(udp)
        self.open_operator()
        for i in range(self.count):  # at the same instant, as far as a test can
            self.start_relay(i)
        loop = asyncio.get_running_loop()
        self._tasks.append(loop.create_task(self._poll()))

    def profile_text(self, i: int) -> str:
        return PROFILE.format(jaus_id=relay_id(i), ip=self.relay_ips[i],
                              peers=f"{self.wire_ips[i]}:3794", domain=self.domain,
                              partition=self.partition)

    def start_relay(self, i: int) -> None:
        path = self.tmp / f"relay-{i}.toml"
        path.write_text(self.profile_text(i))
        with open(self.logs[i], "ab") as log:
            self.procs[i] = subprocess.Popen(
                [EDGE_VIS, "run", "--profile", str(path)], stdout=log,
                stderr=subprocess.STDOUT, env=os.environ.copy())

    def open_operator(self) -> None:
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.qos import Policy, Qos
        from cyclonedds.sub import DataReader, Subscriber
        from cyclonedds.topic import Topic

        from edge_vis.dds import DdsBridge
        from edge_vis.dds.model import GlobalPose

        self.operator = DdsBridge(self.domain, (self.partition,))
        self.operator.open_writers(["ControlRequest", "WrenchEffortCommand",
                                    "EmergencyCommand"])
        for topic in ("VehicleStatus", "ControlStatus", "LinkStatus", "RelayStatus"):
            self._readers[topic] = self.operator.reader(topic)
        # the plain reader: default QoS, only the partition set
        participant = DomainParticipant(self.domain)
        subscriber = Subscriber(participant, qos=Qos(Policy.Partition([self.partition])))
        self._plain = (participant,
                       DataReader(subscriber, Topic(participant, "GlobalPose", GlobalPose)))

    async def _poll(self) -> None:
        reader = self._plain[1]
        while True:
            await asyncio.sleep(0.02)
            now = time.monotonic()
            for sample in reader.take(256):
                if sample.sample_info.valid_data:
                    self.vehicle_id = self.vehicle_id or sample.vehicle_id
                    self.poses.append((now, int(sample.sample_info.publication_handle)))
            for sample in self._readers["VehicleStatus"].take(0.0, 256):
                self.statuses.append((now, sample.get("relay", "")))

    async def stop(self) -> None:
        self.driving = False
        for task in self._tasks:
            await _cancel(task)
        for i in range(self.count):
            self.signal(i, signal.SIGTERM)
        for proc in self.procs:
            if proc is not None:
                try:
                    await asyncio.to_thread(proc.wait, 10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        if self.operator is not None:
            self.operator.close()
        self._plain = None
        for udp in self.udp:
            udp.close()
        await self.endpoint.stop()

    def signal(self, i: int, sig: int) -> None:
        proc = self.procs[i]
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(sig)

    def log_tail(self) -> str:
        return "\n".join(f"--- relay {i}\n" + "\n".join(
            p.read_text(errors="replace").splitlines()[-25:]) for i, p in enumerate(self.logs)
            if p.exists())

    # -- the operator ---------------------------------------------------------------------------
    def request(self, action: str = "request") -> None:
        self.operator.publish("ControlRequest", {
            "vehicle_id": self.vehicle_id, "operator_id": OPERATOR, "authority": 100,
            "action": action})

    def emergency(self, action: str = "SET") -> None:
        self.operator.publish("EmergencyCommand", {
            "vehicle_id": self.vehicle_id, "operator_id": OPERATOR, "authority": 100,
            "action": action, "reason": "relay-group test"})

    def start_driving(self) -> None:
        async def loop() -> None:
            while True:
                if self.driving:
                    self.operator.publish("WrenchEffortCommand", {
                        "vehicle_id": self.vehicle_id, "operator_id": OPERATOR,
                        "propulsive_linear_x": 40.0, "propulsive_rotational_z": 0.0})
                await asyncio.sleep(0.1)

        self.driving = True
        self._tasks.append(asyncio.get_running_loop().create_task(loop()))

    # -- what the vehicle and the data model say -------------------------------------------------
    @property
    def sim(self) -> Any:
        return self.endpoint.vehicle

    def controllers(self) -> set[JausAddress]:
        """The JAUS clients controlling the vehicle's components."""
        return {c.controller for c in self.sim.components.values() if c.controller is not None}

    def event_subscribers(self) -> set[JausAddress]:
        """The JAUS clients holding events on the vehicle."""
        return {s.subscriber for c in self.sim.components.values() if c.events is not None
                for s in c.events}

    def serving(self) -> str:
        """The relay the latest VehicleStatus names."""
        return self.statuses[-1][1] if self.statuses else ""

    def writers_since(self, since: float) -> set[int]:
        return {h for at, h in self.poses if at >= since}

    def poses_since(self, since: float) -> int:
        return sum(1 for at, _ in self.poses if at >= since)

    @property
    def commands_obeyed(self) -> int:
        return int(self.sim.counters["commands_obeyed"])

    @property
    def commands_ignored(self) -> int:
        """Commands from a sender that did not hold control: must stay 0."""
        return int(self.sim.counters["commands_ignored"])

    def latest(self, topic: str) -> list[dict[str, Any]]:
        """The newest sample of every instance of a state topic (transient-local)."""
        return self._readers[topic].read(1024)

    def index_of(self, relay: str) -> int:
        return [str(relay_id(i)) for i in range(self.count)].index(relay)
