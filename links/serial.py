"""JAUS over a serial line (radio modems, USB serial). I/O: a pyserial port on the asyncio loop.

URL::

    serial:///dev/ttyUSB0?baud=57600&rtscts=0&reopen=0.25&pace=1&frame_timeout=1.0

* ``baud`` (default 19200, the JAUS Toolset default) sets the port and the pacing:
  writes leave at most ``baud / 10`` bytes per second (8N1), so a radio's buffer is not
  overrun and the router, not the modem, decides what waits. ``pace=0`` writes as fast
  as the port accepts. The advertised ``bandwidth_bps`` is ``baud * 8 / 10`` unless the
  ``bandwidth`` option says otherwise.
* ``rtscts=1`` enables hardware flow control.
* ``reopen`` (seconds, default 0.25): when the device disappears (USB radio unplugged,
  read/write error, hang-up), the link goes ``down`` and retries opening the same path at
  this interval; it comes back ``open`` without a restart. Packets sent while down are
  dropped and counted (stale commands to a robot are worse than none).
* ``frame_timeout`` (seconds): a partial frame older than this is discarded.

The port is opened exclusively (``flock``): a second process asking for the same radio
gets a clear error instead of silently splitting its bytes with the relay.

The framing is :mod:`edge_vis.jaus.serial_framing` (sans-I/O). This module opens the port with
pyserial (which sets the line discipline and speed) and then reads and writes its file
descriptor from the asyncio loop with ``add_reader``/``add_writer``: no threads of its own.
A link forwarding on its own thread (``udp://...?thread=1``) may hand it packets from that
thread (holding the relay's lock, see :mod:`edge_vis.shell.sharedloop`): they are written
at once as usual, and whatever must wait (pacing, a full port) is left to the loop. The
peer address of every received packet is the device path (a serial line is point to point).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import os
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import serial  # pyserial

from edge_vis.errors import LinkError
from edge_vis.jaus.serial_framing import (
    FRAME_OVERHEAD,
    FRAME_PARTS,
    SerialDeframer,
    SerialError,
    frame,
    frame_parts,
)
from edge_vis.jaus.transport import Packet
from edge_vis.routing.link import Link, LinkOptions, LinkUrl, Peer
from edge_vis.schema import setting
from edge_vis.shell.sharedloop import on_loop_thread

log = logging.getLogger(__name__)

#: bytes held for writing before further sends are dropped
MAX_WRITE_BUFFER = 64 * 1024
_READ_SIZE = 65536


@dataclass(frozen=True, slots=True)
class SerialOptions(LinkOptions):
    """The query options of a ``serial://`` URL (see the module docstring)."""

    baud: int = setting(19200, ge=50, le=20_000_000)
    rtscts: bool = False
    reopen: float = setting(0.25, gt=0, unit="s")
    pace: bool = True
    frame_timeout: float = setting(1.0, gt=0, unit="s")


class SerialLink(Link):
    """JAUS serial framing over a serial device, paced to the baud rate, self-reopening."""

    scheme: ClassVar[str] = "serial"
    options_type: ClassVar[type[LinkOptions]] = SerialOptions
    overhead: ClassVar[int] = FRAME_OVERHEAD + 3  # framing plus typical DLE stuffing
    config: SerialOptions

    @classmethod
    def url_problems(cls, url: LinkUrl, options: Any) -> list[tuple[str, str]]:
        """A serial URL must name its device."""
        if url.path or url.host:
            return []
        return [("url", "no device path (serial:///dev/...)")]

    def __init__(self, url: str | LinkUrl, *, name: str | None = None) -> None:
        super().__init__(url, name=name)
        self.path = self.url.path or self.url.host
        self.baud = self.config.baud
        self.rtscts = self.config.rtscts
        self.pace = self.config.pace
        self.reopen_interval = self.config.reopen
        self.frame_timeout = self.config.frame_timeout
        # reused for every read (see links.udp: a fresh 64 KiB per read fragments the heap)
        self._buffer = memoryview(bytearray(_READ_SIZE))
        if self.bandwidth_bps is None:
            self.bandwidth_bps = self.baud * 8 / 10
        self.bytes_per_second = self.baud / 10
        self._port: serial.Serial | None = None
        self._fd: int | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._deframer = SerialDeframer(timeout=self.frame_timeout)
        self._out = bytearray()  # framed bytes not yet written
        #: length of each frame in ``_out``, and how much of the first is written: an
        #: urgent frame goes in at the first frame boundary, never inside a frame
        self._frames: deque[int] = deque()
        self._head_sent = 0
        #: leading bytes of ``_out`` written regardless of pacing (urgent frames and the
        #: rest of the frame they waited for)
        self._urgent_bytes = 0
        self._budget = 0.0
        self._budget_time = 0.0
        self._pump_handle: asyncio.Handle | None = None
        self._writer_armed = False
        self._reopen_task: asyncio.Task[None] | None = None
        self.reopened = 0

    # -- life cycle ------------------------------------------------------------------
    async def _open(self) -> None:
        self._loop = asyncio.get_running_loop()
        try:
            self._attach()
        except (OSError, serial.SerialException) as exc:
            raise LinkError(f"{self.name}: cannot open {self.path}: {exc}") from exc

    def _attach(self) -> None:
        port = serial.Serial(
            port=self.path, baudrate=self.baud, timeout=0, write_timeout=0,
            rtscts=self.rtscts, exclusive=True,  # a second process must not steal bytes
        )
        self._port = port
        self._fd = port.fileno()
        os.set_blocking(self._fd, False)
        assert self._loop is not None
        self._loop.add_reader(self._fd, self._readable)
        self._deframer = SerialDeframer(timeout=self.frame_timeout)
        self._budget = 0.0
        self._budget_time = self._loop.time()

    def _detach(self) -> None:
        if self._fd is not None and self._loop is not None:
            self._loop.remove_reader(self._fd)
            if self._writer_armed:
                self._loop.remove_writer(self._fd)
        self._writer_armed = False
        if self._pump_handle is not None:
            self._pump_handle.cancel()
            self._pump_handle = None
        if self._port is not None:
            with contextlib.suppress(OSError, serial.SerialException):
                self._port.close()
        self._port = None
        self._fd = None
        if self._out:
            self.counters.dropped("link down (bytes unsent)", len(self._out))
        self._out.clear()
        self._frames.clear()
        self._head_sent = self._urgent_bytes = 0

    async def _close(self) -> None:
        if self._reopen_task is not None:
            self._reopen_task.cancel()
            self._reopen_task = None
        self._detach()

    def _lost(self, reason: str) -> None:
        """The device failed: go down and start trying to reopen it."""
        self._detach()
        self._set_state("down", reason)
        if self._reopen_task is None and self.state != "closed" and self._loop is not None:
            self._reopen_task = self._loop.create_task(self._reopen())

    async def _reopen(self) -> None:
        try:
            while self.state == "down":
                await asyncio.sleep(self.reopen_interval)
                try:
                    self._attach()
                except (OSError, serial.SerialException) as exc:
                    self.counters.last_error = f"reopen {self.path}: {exc}"
                    continue
                self.reopened += 1
                self._set_state("open", f"{self.path} reopened")
        finally:
            self._reopen_task = None

    @property
    def queue_depth(self) -> int:
        return len(self._out)

    # -- receiving -------------------------------------------------------------------
    def _readable(self) -> None:
        fd = self._fd
        if fd is None:
            return
        try:
            size = os.readv(fd, [self._buffer])
        except BlockingIOError:
            return
        except OSError as exc:
            self._lost(f"read {self.path}: {exc.strerror or exc}")
            return
        if not size:
            self._lost(f"{self.path}: end of file (device gone)")
            return
        assert self._loop is not None
        self._consume(self._buffer[:size].tobytes(), self._loop.time())

    def _consume(self, data: bytes, now: float) -> None:
        path = self.path
        for item in self._deframer.feed(data, now):
            if isinstance(item, SerialError):
                self._malformed(path, item.reason, item.data)
            else:
                self._received(path, [item.packet], len(item.raw))

    # -- sending ---------------------------------------------------------------------
    def _send(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        if self._fd is None:
            self.counters.dropped("link down", len(packets))
            return
        if packets:
            self._write(list(map(frame, packets)))

    def _send_wires(self, wires: Sequence[bytes], peer: Peer | None) -> None:
        """Frames of forwarded messages: written at once in one system call when nothing
        waits and the link is not paced (the usual case of a fast port), else as
        :meth:`_send` does."""
        fd = self._fd
        if fd is None:
            self.counters.dropped("link down", len(wires))
            return
        if not wires:
            return
        parts = frame_parts(wires)
        if self._out or self.pace or self._pump_handle is not None or self._writer_armed:
            self._write([b"".join(parts[i:i + FRAME_PARTS])
                         for i in range(0, len(parts), FRAME_PARTS)])
            return
        data = b"".join(parts)
        try:
            written = os.write(fd, data)
        except OSError:  # _pump meets it again below and says what it means
            written = 0
        self.counters.sent(self.path, len(data), len(wires))
        if written == len(data):
            return
        # the port took part of it: the rest waits in the buffer, frame by frame
        self._out += data
        self._frames.extend(sum(map(len, parts[i:i + FRAME_PARTS]))
                            for i in range(0, len(parts), FRAME_PARTS))
        if written:
            del self._out[:written]
            self._written(written)
        self._pump()

    def _write(self, framed: list[bytes]) -> None:
        """Buffer whole frames (up to the buffer's bound) and write what pacing allows."""
        out, frames = self._out, self._frames
        before = len(out)
        lengths = list(map(len, framed))
        if before + sum(lengths) - lengths[-1] <= MAX_WRITE_BUFFER:  # all fit (usual)
            out += b"".join(framed)
            frames.extend(lengths)
            sent = len(framed)
        else:
            sent = 0
            for data in framed:
                if len(out) > MAX_WRITE_BUFFER:
                    self.counters.dropped("send buffer full", len(framed) - sent)
                    break
                out += data
                frames.append(len(data))
                sent += 1
        if sent:
            self.counters.sent(self.path, len(out) - before, sent)
        # the frames of one call share one system call (the router hands over everything
        # a burst of input produced at once); written now when nothing waits, else the
        # pending pump or writer callback takes them along
        if self._pump_handle is None and not self._writer_armed:
            self._pump()

    def _send_urgent(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        """Frames ahead of every buffered one (after the frame being written, and after
        earlier urgent ones), written at once whatever the pacing budget; never dropped
        for a full buffer."""
        if self._fd is None:
            self.counters.dropped("link down", len(packets))
            return
        out, frames = self._out, self._frames
        # where the urgent prefix ends: the rest of the frame in progress, earlier urgent
        # frames; always a frame boundary
        position, index = 0, 0
        if self._head_sent and frames:
            position, index = frames[0] - self._head_sent, 1
        while position < self._urgent_bytes and index < len(frames):
            position += frames[index]
            index += 1
        for packet in packets:
            data = frame(packet)
            out[position:position] = data
            frames.insert(index, len(data))
            position += len(data)
            index += 1
            self.counters.sent(self.path, len(data), 1)
        self._urgent_bytes = position
        if self._pump_handle is not None:
            self._pump_handle.cancel()
            self._pump_handle = None
        if not self._writer_armed:
            self._pump()

    def _pump(self) -> None:
        """Write what the pacing budget allows; schedule the rest."""
        self._pump_handle = None
        fd = self._fd
        loop = self._loop
        out = self._out
        if fd is None or loop is None or self._writer_armed or not out:
            return
        if self.pace:
            now = loop.time()
            burst = max(64.0, self.bytes_per_second * 0.01)
            self._budget = min(burst, self._budget + (now - self._budget_time)
                               * self.bytes_per_second)
            self._budget_time = now
            allowed = min(len(out), max(int(self._budget), self._urgent_bytes))
        else:
            allowed = len(out)
        if allowed > 0:
            try:
                written = os.write(fd, out[:allowed])
            except BlockingIOError:
                written = 0
            except OSError as exc:
                if exc.errno not in (errno.EAGAIN, errno.EWOULDBLOCK):
                    if not on_loop_thread(loop):  # the loop retries, and goes down
                        self._pump_handle = loop.call_soon_threadsafe(self._pump)
                        return
                    self._lost(f"write {self.path}: {exc.strerror or exc}")
                    return
                written = 0
            if written == 0:  # the port is full: wait until it drains
                if not on_loop_thread(loop):
                    self._pump_handle = loop.call_soon_threadsafe(self._pump)
                    return
                loop.add_writer(fd, self._writable)
                self._writer_armed = True
                return
            del out[:written]
            self._written(written)
            if self.pace:
                self._budget -= written
        if out:
            if not on_loop_thread(loop):  # the loop paces the rest
                self._pump_handle = loop.call_soon_threadsafe(self._pump)
                return
            wait = (1.0 - self._budget) / self.bytes_per_second if self.pace else 0.0
            self._pump_handle = loop.call_later(max(wait, 0.0005), self._pump)

    def _written(self, count: int) -> None:
        """``count`` bytes left the buffer: advance the frame bookkeeping."""
        frames = self._frames
        if not self._out:  # all written (the usual case): no frame left to track
            frames.clear()
            self._head_sent = self._urgent_bytes = 0
            return
        self._urgent_bytes = max(0, self._urgent_bytes - count)
        count += self._head_sent
        while frames and count >= frames[0]:
            count -= frames.popleft()
        self._head_sent = count

    def _writable(self) -> None:
        if self._fd is not None and self._loop is not None:
            self._loop.remove_writer(self._fd)
        self._writer_armed = False
        self._pump()

