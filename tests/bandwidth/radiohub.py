"""An emulated shared serial radio between one relay and several simulated vehicles.

Used by the bandwidth end-to-end test and ``bench/bandwidth.py``. Performs I/O (ptys).

The relay opens ``hub.relay_path`` (a real pseudo-terminal) as its serial link; each
simulated vehicle (:class:`edge_vis.tools.sim.runner.PtyVehicle`) has its own pty, which the
hub opens as the radio would. Every JAUS serial frame, from either side, joins ONE FIFO
(the air time of a half-duplex radio shared by everyone) drained at ``baud / 10`` bytes
per second: frames from the relay go to every vehicle (a radio broadcasts), frames from a
vehicle go to the relay. Frames are never split or interleaved, as on a packet radio.

Instrumentation: bytes carried, the backlog waiting for air time, the age of every pose
(ReportGlobalPose in an Event) when it reaches the relay, and when every command frame
reaches the vehicles.
"""

from __future__ import annotations

import asyncio
import os
import tty
from collections import Counter, deque
from dataclasses import dataclass, field

from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.transport import Packet

EVENT = 0x41F1
POSE = 0x4402
TICK = 0.005


@dataclass
class Frame:
    raw: bytes
    packet: Packet
    to_relay: bool
    source: int  # vehicle index for uplink, -1 for the relay
    queued: float


@dataclass
class HubStats:
    carried: int = 0
    uplink: int = 0
    downlink: int = 0
    max_backlog: int = 0
    backlog_samples: list[tuple[float, int]] = field(default_factory=list)
    #: (subsystem, time the relay got it, time the vehicle sent it)
    poses: list[tuple[int, float, float]] = field(default_factory=list)
    #: (message code, payload, time delivered to the vehicles, time the relay wrote it)
    commands: list[tuple[int, bytes, float, float]] = field(default_factory=list)
    #: bytes on the air by (direction, message code, inner report code of an Event)
    by_code: Counter[tuple[str, int, int]] = field(default_factory=Counter)


class RadioHub:
    """See the module docstring. ``command_codes``: downlink messages to time."""

    def __init__(self, baud: int, command_codes: frozenset[int] = frozenset()) -> None:
        self.rate = baud / 10
        self.command_codes = command_codes
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._relay_master = master
        self._relay_slave = slave  # kept open so the pty survives the relay reopening it
        self.relay_path = os.ttyname(slave)
        self._vehicles: list[int] = []
        self._deframers: list[jserial.SerialDeframer] = []
        self._relay_deframer = jserial.SerialDeframer()
        self.queue: deque[Frame] = deque()
        self.backlog = 0
        self.stats = HubStats()
        self._task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    def add_vehicle(self, path: str) -> None:
        """Join a vehicle's pty (its slave path) to the radio."""
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd)
        index = len(self._vehicles)
        self._vehicles.append(fd)
        self._deframers.append(jserial.SerialDeframer())
        if self._loop is not None:
            self._loop.add_reader(fd, self._read_vehicle, index)

    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(self._relay_master, self._read_relay)
        for index, fd in enumerate(self._vehicles):
            self._loop.add_reader(fd, self._read_vehicle, index)
        self._task = self._loop.create_task(self._air())

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
        assert self._loop is not None
        for fd in [self._relay_master, *self._vehicles]:
            self._loop.remove_reader(fd)
        for fd in [self._relay_master, self._relay_slave, *self._vehicles]:
            os.close(fd)

    def _enqueue(self, frames: list[Frame]) -> None:
        for frame in frames:
            self.queue.append(frame)
            self.backlog += len(frame.raw)
        self.stats.max_backlog = max(self.stats.max_backlog, self.backlog)

    def _read_vehicle(self, index: int) -> None:
        try:
            data = os.read(self._vehicles[index], 65536)
        except OSError:
            return
        now = asyncio.get_running_loop().time()
        self._enqueue([Frame(item.raw, item.packet, True, index, now)
                       for item in self._deframers[index].feed(data, now)
                       if isinstance(item, jserial.SerialFrame)])

    def _read_relay(self) -> None:
        try:
            data = os.read(self._relay_master, 65536)
        except OSError:
            return
        now = asyncio.get_running_loop().time()
        self._enqueue([Frame(item.raw, item.packet, False, -1, now)
                       for item in self._relay_deframer.feed(data, now)
                       if isinstance(item, jserial.SerialFrame)])

    async def _air(self) -> None:
        loop = asyncio.get_running_loop()
        budget = 0.0
        last = loop.time()
        sample_at = last
        while True:
            await asyncio.sleep(TICK)
            now = loop.time()
            budget = min(budget + (now - last) * self.rate, self.rate * 0.05 + 300)
            last = now
            while self.queue and budget > 0:
                frame = self.queue.popleft()
                size = len(frame.raw)
                budget -= size
                self.backlog -= size
                self.stats.carried += size
                code = frame.packet.message_code or 0
                inner = (int.from_bytes(frame.packet.payload[8:10], "little")
                         if code == EVENT and len(frame.packet.payload) >= 10 else 0)
                self.stats.by_code["up" if frame.to_relay else "down", code, inner] += size
                done = now  # the frame has been on the air for its size / rate
                if frame.to_relay:
                    self.stats.uplink += size
                    _write(self._relay_master, frame.raw)
                    self._note_pose(frame, done)
                else:
                    self.stats.downlink += size
                    for fd in self._vehicles:
                        _write(fd, frame.raw)
                    code = frame.packet.message_code
                    if code in self.command_codes:
                        self.stats.commands.append((code, frame.packet.payload, done,
                                                    frame.queued))
            if now - sample_at >= 0.25:
                sample_at = now
                self.stats.backlog_samples.append((now, self.backlog))

    def _note_pose(self, frame: Frame, now: float) -> None:
        payload = frame.packet.payload
        code = frame.packet.message_code
        if code == POSE or (code == EVENT and len(payload) >= 10
                            and int.from_bytes(payload[8:10], "little") == POSE):
            self.stats.poses.append((frame.packet.source.subsystem, now, frame.queued))


def _write(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        try:
            n = os.write(fd, view)
        except BlockingIOError:
            continue
        except OSError:
            return
        view = view[n:]
