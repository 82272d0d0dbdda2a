"""The fault-matrix rig: a simulated vehicle, an impairing wire, the relay, an operator.

Everything is real: the sim vehicle's JUDP socket or pseudo-terminal, the relay's
:class:`~edge_vis.shell.relay.Runtime` with its UDP or serial link, and Cyclone DDS (loopback
only) between the relay and an operator station in this process. Between vehicle and
relay sits an impairing wire that works on whole datagrams (UDP) or whole frames (serial,
deframed and framed again), so each fault hits complete JAUS packets:

* ``loss`` / ``duplicate`` / ``corrupt``: probabilities per unit and direction (seeded);
* ``reorder``: probability that a unit is held back and sent after the next one;
* ``down``: drop everything (a radio fade or a cable pulled);
* ``inject(data)``: put raw bytes on the wire towards the relay (malformed floods).

Timers are shortened (liveness 0.25 s, lost after 3 = 0.75 s of silence, discovery every
0.5 s) so a test that spans "a link down for 30 s" runs as a 3 s outage: every relay and
vehicle timer involved (silence timeout, vehicle control timeout of 1 s) is shorter than
the outage, as the real ones (3 s, 5 s) are shorter than 30 s.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import random
import time
import tty
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from edge_vis.config import from_mapping
from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime
from edge_vis.tools.sim.profile import FaultSpec, VehicleSpec
from edge_vis.tools.sim.runner import VehicleEndpoint, endpoint_for

RELAY_ID = JausAddress(200, 1, 1)
SUBSYSTEM = 121
OPERATOR = "op-faults"

_ips = itertools.cycle(range(150, 190))  # 190-199: tests/test_limits.py, test_security.py


def next_ip() -> str:
    """A loopback address of the fault suite's own range (127.0.0.150-189), reused only
    after every other one (each rig closes its sockets when its test ends)."""
    return f"127.0.0.{next(_ips)}"


@dataclass
class Impairment:
    """What the wire does to each unit going one way."""

    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    corrupt: float = 0.0


@dataclass
class Wire:
    """Impairment state shared by both directions; counters of what was done."""

    up: Impairment = field(default_factory=Impairment)      # vehicle -> relay
    down_: Impairment = field(default_factory=Impairment)   # relay -> vehicle
    down: bool = False
    counters: Counter[str] = field(default_factory=Counter)
    rng: random.Random = field(default_factory=lambda: random.Random(7))

    def both(self, **kwargs: float) -> None:
        """Set the same impairment both ways (no arguments: clear)."""
        self.up = Impairment(**kwargs)
        self.down_ = Impairment(**kwargs)

    def shape(self, units: list[bytes], toward_relay: bool,
              corrupt: Callable[[bytes], bytes], held: list[bytes]) -> list[bytes]:
        """The units to send now for ``units`` received (``held``: reorder buffer)."""
        if self.down:
            self.counters["dropped: link down"] += len(units)
            return []
        imp = self.up if toward_relay else self.down_
        out: list[bytes] = []
        rng = self.rng
        for unit in units:
            if rng.random() < imp.loss:
                self.counters["lost"] += 1
                continue
            if rng.random() < imp.corrupt:
                self.counters["corrupted"] += 1
                self.counters["corrupted toward " + ("relay" if toward_relay else "vehicle")] += 1
                unit = corrupt(unit)
            copies = 2 if rng.random() < imp.duplicate else 1
            self.counters["duplicated"] += copies - 1
            if not held and rng.random() < imp.reorder:
                held.append(unit)
                self.counters["reordered"] += 1
                continue
            out += [unit] * copies
            if held:
                out += held
                held.clear()
        return out


def _flip(data: bytes, rng: random.Random, start: int) -> bytes:
    if len(data) <= start:
        return data
    i = rng.randrange(start, len(data))
    return data[:i] + bytes((data[i] ^ (1 << rng.randrange(8)),)) + data[i + 1:]


class UdpWire(asyncio.DatagramProtocol):
    """A UDP relay between the relay (``front``) and the vehicle (``back``), impaired."""

    def __init__(self, wire: Wire, ip: str, vehicle: tuple[str, int]) -> None:
        self.wire = wire
        self.ip = ip
        self.vehicle = vehicle
        self.relay_addr: tuple[str, int] | None = None
        self.front: asyncio.DatagramTransport | None = None
        self.back: asyncio.DatagramTransport | None = None
        self._held = ([], [])  # type: tuple[list[bytes], list[bytes]]

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        wire = self

        class Back(asyncio.DatagramProtocol):
            def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
                wire._from_vehicle(data)

        self.front, _ = await loop.create_datagram_endpoint(lambda: self,
                                                           local_addr=(self.ip, 3794))
        self.back, _ = await loop.create_datagram_endpoint(Back, local_addr=(self.ip, 3795))

    @property
    def address(self) -> str:
        return f"{self.ip}:3794"

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:  # from relay
        self.relay_addr = addr
        for unit in self.wire.shape([data], False, self._corrupt, self._held[1]):
            assert self.back is not None
            self.back.sendto(unit, self.vehicle)

    def _from_vehicle(self, data: bytes) -> None:
        if self.relay_addr is None or self.front is None:
            return
        for unit in self.wire.shape([data], True, self._corrupt, self._held[0]):
            self.front.sendto(unit, self.relay_addr)

    def _corrupt(self, data: bytes) -> bytes:
        return _flip(data, self.wire.rng, 1)

    def inject(self, data: bytes) -> None:
        """Raw bytes to the relay, as if from the vehicle's side of the radio."""
        if self.relay_addr is not None and self.front is not None:
            self.front.sendto(data, self.relay_addr)

    def close(self) -> None:
        for t in (self.front, self.back):
            if t is not None:
                t.close()


class SerialWire:
    """Two pseudo-terminals joined frame by frame: the sim's pty and one the relay opens."""

    def __init__(self, wire: Wire, vehicle_pty: str) -> None:
        self.wire = wire
        self.vehicle_fd = os.open(vehicle_pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(self.master, False)
        self._deframers = (jserial.SerialDeframer(), jserial.SerialDeframer())
        self._held = ([], [])  # type: tuple[list[bytes], list[bytes]]
        self._inject: list[bytes] = []
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._carry())

    def inject(self, data: bytes) -> None:
        self._inject.append(data)

    def _corrupt(self, data: bytes) -> bytes:
        return _flip(data, self.wire.rng, 2)

    def _pass(self, src: int, dst: int, toward_relay: bool, deframer: Any,
              held: list[bytes]) -> None:
        try:
            data = os.read(src, 65536)
        except (BlockingIOError, OSError):
            return
        now = time.monotonic()
        frames = [jserial.frame(item.packet) for item in deframer.feed(data, now)
                  if isinstance(item, jserial.SerialFrame)]
        out = self.wire.shape(frames, toward_relay, self._corrupt, held)
        if toward_relay and self._inject:
            out = [*self._inject, *out]
            self._inject.clear()
        for unit in out:
            _write_all(dst, unit)

    async def _carry(self) -> None:
        while True:
            await asyncio.sleep(0.003)
            self._pass(self.vehicle_fd, self.master, True, self._deframers[0], self._held[0])
            self._pass(self.master, self.vehicle_fd, False, self._deframers[1], self._held[1])
            if self._inject:
                for unit in self._inject:
                    _write_all(self.master, unit)
                self._inject.clear()

    async def stop(self) -> None:
        await _cancel(self._task)
        os.close(self.master)
        os.close(self.vehicle_fd)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    for _ in range(1000):
        if not view:
            return
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            time.sleep(0.001)


def relay_profile(link_url: str, domain: int, partition: str, **overrides: Any) -> Any:
    """The relay's profile with shortened timers (see the module docstring)."""
    data: dict[str, Any] = {
        "relay": {"jaus_id": str(RELAY_ID), "authority": 150},
        "links": {"radio": {"url": link_url}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "emergency", "mobility"]},
        "operators": [{"id": OPERATOR, "max_authority": 200},
                      {"id": "op-late", "max_authority": 250}],
        "discovery": {"period": 0.5, "liveness_period": 0.25, "lost_after": 3,
                      "response_timeout": 0.5},
        "control": {"renewal_period": 0.4, "response_timeout": 0.4, "retry_period": 0.5},
        "events": {"response_timeout": 0.5, "attempts": 2},
        "commands": {"rate": 10.0, "lifespan": 0.5, "deadman_timeout": 0.5},
        "report_rates": {"ReportGlobalPose": 10.0},
    }
    data.update(overrides)
    return from_mapping(data, file="faults.toml")


class Rig:
    """One vehicle behind an impairing wire, the relay and an operator station."""

    def __init__(self, medium: str, domain: int, partition: str, *,
                 control_timeout: int = 5, faults: FaultSpec | None = None) -> None:
        self.medium = medium
        self.domain = domain
        self.partition = partition
        self.wire = Wire()
        ip = next_ip()
        self.vehicle_ip = next_ip() if medium == "udp" else ""
        self.relay_ip = ip
        spec = VehicleSpec(
            name="ugv-fault", subsystem=SUBSYSTEM,
            link=f"udp://{self.vehicle_ip}:3794" if medium == "udp" else "pty",
            baud=115200, control_timeout=control_timeout, event_timeout=1,
            init_time=0.2, faults=faults or FaultSpec(), seed=3)
        self.endpoint: VehicleEndpoint = endpoint_for(spec)
        self.udp: UdpWire | None = None
        self.serial: SerialWire | None = None
        self.runtime: Runtime | None = None
        self.operator: Any = None
        self.poses: list[tuple[float, dict[str, Any]]] = []
        self.control_states: list[tuple[float, str, str]] = []
        self._readers: dict[str, Any] = {}
        self._poller: asyncio.Task[None] | None = None
        self._driver: asyncio.Task[None] | None = None
        self.vehicle_id = ""
        self.profile_overrides: dict[str, Any] = {}

    # -- set-up ------------------------------------------------------------------------
    async def start(self, *, operator: bool = True) -> None:
        await self.endpoint.start()
        if self.medium == "udp":
            self.udp = UdpWire(self.wire, next_ip(), self.endpoint.spec.udp_address)
            await self.udp.open()
            self.link_url = f"udp://{self.relay_ip}:3794?peers={self.udp.address}"
        else:
            self.serial = SerialWire(self.wire, self.endpoint.slave_path)  # type: ignore
            self.serial.start()
            self.link_url = f"serial://{self.serial.path}?baud=115200"
        await self.start_relay()
        if operator:
            self.open_operator()

    async def start_relay(self) -> None:
        self.runtime = Runtime(relay_profile(self.link_url, self.domain, self.partition,
                                             **self.profile_overrides))
        await self.runtime.start()

    def open_operator(self) -> None:
        from edge_vis.dds import DdsBridge

        self.operator = DdsBridge(self.domain, (self.partition,))
        self.operator.open_writers(["ControlRequest", "WrenchEffortCommand", "EmergencyCommand"])
        for topic in ("GlobalPose", "ControlStatus", "VehicleStatus", "VehicleIdentification"):
            self._readers[topic] = self.operator.reader(topic)
        self._poller = asyncio.get_running_loop().create_task(self._poll())

    async def _poll(self) -> None:
        while True:
            await asyncio.sleep(0.02)
            now = time.monotonic()
            for sample in self._readers["GlobalPose"].take(0.0, 256):
                self.poses.append((now, sample))
                self.vehicle_id = self.vehicle_id or sample["vehicle_id"]
            for sample in self._readers["ControlStatus"].take(0.0, 256):
                self.control_states.append((now, str(sample["state"]), sample["operator_id"]))

    async def stop(self) -> None:
        await _cancel(self._driver)
        await _cancel(self._poller)
        if self.runtime is not None:
            await self.runtime.stop()
        if self.operator is not None:
            self.operator.close()
        if self.udp is not None:
            self.udp.close()
        if self.serial is not None:
            await self.serial.stop()
        await self.endpoint.stop()

    async def close_operator_abruptly(self) -> None:
        """The station's process dies: its participant goes away without a release."""
        await _cancel(self._poller)
        self._poller = None
        self.operator.close()
        self.operator = None

    async def crash_relay(self) -> None:
        """Stop the relay as a power cut would: no goodbyes, sockets simply close."""
        runtime = self.runtime
        assert runtime is not None
        for name in ("_status_task", "_timer"):
            handle = getattr(runtime, name)
            if handle is not None:
                handle.cancel()
        for link in runtime.links.values():
            await link.close()
        if runtime.publisher is not None:
            runtime.publisher.close()
        self.runtime = None

    # -- the operator --------------------------------------------------------------------
    def request(self, operator: str = OPERATOR, authority: int = 100,
                action: str = "request", bridge: Any = None) -> None:
        (bridge or self.operator).publish("ControlRequest", {
            "vehicle_id": self.vehicle_id, "operator_id": operator, "authority": authority,
            "action": action})

    def drive(self, effort: float = 40.0, operator: str = OPERATOR, bridge: Any = None) -> None:
        (bridge or self.operator).publish("WrenchEffortCommand", {
            "vehicle_id": self.vehicle_id, "operator_id": operator,
            "propulsive_linear_x": effort})

    def emergency(self, action: str, operator: str = OPERATOR, authority: int = 100,
                  bridge: Any = None) -> None:
        (bridge or self.operator).publish("EmergencyCommand", {
            "vehicle_id": self.vehicle_id, "operator_id": operator, "action": action,
            "authority": authority, "reason": ""})

    def in_emergency(self) -> bool:
        """Every Management component of the sim is in EMERGENCY."""
        states = [c.state for c in self.sim.components.values() if c.state is not None]
        return bool(states) and all(s == 5 for s in states)

    def start_driving(self, period: float = 0.1) -> None:
        """Drive at 10 Hz and re-request control every second (a well-behaved station)."""
        async def loop() -> None:
            n = 0
            while True:
                if n % 10 == 0:
                    self.request()
                self.drive()
                n += 1
                await asyncio.sleep(period)

        self._driver = asyncio.get_running_loop().create_task(loop())

    async def stop_driving(self) -> None:
        await _cancel(self._driver)
        self._driver = None

    # -- what the vehicle and the relay say --------------------------------------------
    @property
    def sim(self) -> Any:
        return self.endpoint.vehicle

    def vehicle_controlled(self) -> bool:
        """The sim's commanded component has the relay as its controller."""
        comps = [c for c in self.sim.components.values() if c.controller is not None]
        return bool(comps) and all(c.controller == RELAY_ID for c in comps)

    def vehicle_events(self) -> int:
        """Events the relay holds on the vehicle (the vehicle's own event tables)."""
        return len(self.relay_events_on_vehicle())

    def relay_events_on_vehicle(self) -> list[Any]:
        """The vehicle's own event records held for the relay (new objects after a reboot)."""
        return [s for c in self.sim.components.values() if c.events is not None
                for s in c.events if s.subscriber == RELAY_ID]

    def relay_view(self) -> Any:
        assert self.runtime is not None and self.runtime.engine is not None
        for v in self.runtime.engine.snapshot().vehicles:
            if v.view.subsystem == SUBSYSTEM:
                return v
        return None

    def relay_online(self) -> bool:
        v = self.runtime and self.runtime.engine and self.relay_view()
        return bool(v) and v.view.online

    def relay_events_active(self) -> bool:
        v = self.relay_view() if self.runtime else None
        return bool(v) and any(s.report == "ReportGlobalPose" and s.state == "active"
                               for s in v.subscriptions)

    def relay_controlled(self) -> bool:
        v = self.relay_view() if self.runtime else None
        return bool(v) and v.view.jaus_control == "controlled"

    def driving(self) -> bool:
        """The vehicle's last wrench effort asks it to move."""
        # a scaled zero decodes as 0.0015 %: anything under 1 % is a stop
        return abs(self.sim.effort.get("propulsive_linear_effort_x", 0.0)) > 1.0

    def poses_since(self, t: float) -> int:
        return sum(1 for at, _ in self.poses if at >= t)

    @property
    def commands_obeyed(self) -> int:
        return self.sim.counters["commands_obeyed"]

    @property
    def commands_ignored(self) -> int:
        """Commands the vehicle got from a sender that did not hold control: must stay 0."""
        return self.sim.counters["commands_ignored"]

    def healthy(self, since: float) -> bool:
        """Rediscovered, events on both sides, control on both sides, poses flowing,
        commands obeyed."""
        return (self.relay_online() and self.relay_events_active() and self.vehicle_events() > 0
                and self.relay_controlled() and self.vehicle_controlled()
                and self.poses_since(since) >= 3)


async def _cancel(task: asyncio.Task[None] | None) -> None:
    """Cancel ``task`` (if any) and wait until it has ended."""
    if task is not None:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def until(check: Callable[[], bool], timeout: float, what: str) -> float:
    """Wait until ``check()`` holds; return the seconds it took (AssertionError on timeout)."""
    start = time.monotonic()
    while not check():
        if time.monotonic() - start > timeout:
            raise AssertionError(f"timed out after {timeout:.1f} s waiting for {what}")
        await asyncio.sleep(0.02)
    return time.monotonic() - start
