"""Shared pieces for the link tests (imported as ``linkkit``): ports, pty radios, runner."""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import tty
from collections.abc import Awaitable, Callable
from typing import TypeVar

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet
from edge_vis.routing.router import Deliver

T = TypeVar("T")


def run(coro: Awaitable[T], timeout: float = 10.0) -> T:
    """Run a test coroutine on a fresh loop, with a hard timeout."""

    async def guarded() -> T:
        return await asyncio.wait_for(coro, timeout)

    return asyncio.run(guarded())


def free_port(hosts: tuple[str, ...] = ("127.0.0.2", "127.0.0.3", "127.0.0.4")) -> int:
    """A UDP port that is free on every one of ``hosts`` right now."""
    for _ in range(50):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind((hosts[0], 0))
            port = probe.getsockname()[1]
            ok = True
            for host in hosts[1:]:
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
                    try:
                        other.bind((host, port))
                    except OSError:
                        ok = False
            if ok:
                return port
    raise RuntimeError("no common free port")


class Pty:
    """A pseudo-terminal pair; the link opens ``path`` (the slave), the test holds ``master``."""

    def __init__(self) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)  # no echo or line editing before the link configures it
        self.path = os.ttyname(slave)
        os.close(slave)  # the link reopens it by path; the pty lives while master is open
        os.set_blocking(self.master, False)

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.master, view)
            except BlockingIOError:
                continue
            view = view[n:]

    def read(self) -> bytes:
        try:
            return os.read(self.master, 65536)
        except (BlockingIOError, OSError):
            return b""

    def close(self) -> None:
        if self.master >= 0:
            os.close(self.master)
            self.master = -1


def msg(src: JausAddress, dst: JausAddress, body: bytes = b"\x02", code: int = 0x2B00,
        **kw: int) -> Packet:
    """A packet carrying message ``code`` with ``body``."""
    return Packet(destination=dst, source=src, payload=code.to_bytes(2, "little") + body, **kw)


async def collect(queue: asyncio.Queue[Deliver], count: int, timeout: float = 3.0
                  ) -> list[Deliver]:
    """The next ``count`` deliveries (fails the test on timeout)."""
    out = []
    for _ in range(count):
        out.append(await asyncio.wait_for(queue.get(), timeout))
    return out


async def until(predicate: Callable[[], bool], timeout: float = 3.0) -> None:
    """Poll ``predicate`` on the loop until it holds (fails on timeout)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not predicate():
        if loop.time() > end:
            raise AssertionError("condition not reached in time")
        await asyncio.sleep(0.01)


class ThrottledWire:
    """Two ptys joined master to master, carrying at most ``baud / 10`` bytes/s each way.

    Each end's ``path`` is opened by a serial link, so two links talk at a real radio's
    pace (an 8N1 byte costs ten bit times). ``inject(end, data)`` adds bytes as if the
    radio had received them from the air (noise, broken frames).
    """

    def __init__(self, baud: int) -> None:
        self.ends = (Pty(), Pty())
        self.rate = baud / 10
        self.carried = [0, 0]
        self._noise: tuple[list[bytes], list[bytes]] = ([], [])
        self._tasks: list[asyncio.Task[None]] = []

    @property
    def paths(self) -> tuple[str, str]:
        return self.ends[0].path, self.ends[1].path

    def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._tasks = [loop.create_task(self._carry(0, 1)), loop.create_task(self._carry(1, 0))]

    def inject(self, end: int, data: bytes) -> None:
        """Put ``data`` on the air towards the link at ``end`` (0 or 1), between frames."""
        self._noise[end].append(data)

    @staticmethod
    def _frame_start(buf: bytearray, written_dles: int) -> int:
        """Index of a real DLE SOH in ``buf`` (not a stuffed DLE followed by 01), or -1.

        ``written_dles``: DLE bytes that ended what was already sent.
        """
        pos = buf.find(b"\x10\x01")
        while pos >= 0:
            run = 0
            while pos - run - 1 >= 0 and buf[pos - run - 1] == 0x10:
                run += 1
            if pos - run == 0:
                run += written_dles
            if run % 2 == 0:
                return pos
            pos = buf.find(b"\x10\x01", pos + 1)
        return -1

    async def _carry(self, src: int, dst: int) -> None:
        loop = asyncio.get_running_loop()
        pending = bytearray()
        budget = 0.0
        last = loop.time()
        written_dles = 0
        while True:
            await asyncio.sleep(0.002)
            pending += self.ends[src].read()
            noise = self._noise[dst]
            if noise:
                at = self._frame_start(pending, written_dles)
                if at >= 0:
                    pending[at:at] = b"".join(noise)
                    noise.clear()
            now = loop.time()
            budget = min(budget + (now - last) * self.rate, max(self.rate * 0.01, 16.0))
            last = now
            n = min(len(pending), int(budget))
            if n:
                chunk = bytes(pending[:n])
                self.ends[dst].write(chunk)
                stripped = chunk.rstrip(b"\x10")
                tail = len(chunk) - len(stripped)
                written_dles = written_dles + tail if not stripped else tail
                del pending[:n]
                budget -= n
                self.carried[src] += n

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        for end in self.ends:
            end.close()
