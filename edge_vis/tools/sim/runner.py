"""The asyncio adapter that puts simulated vehicles on the wire. Does I/O.

Each vehicle gets its own endpoint: a UDP socket bound to its loopback address (JUDP,
one packet per datagram as the JAUS Toolset sends) or a pseudo-terminal speaking JAUS
serial framing at the profile's baud rate. The endpoint does what a robot's node manager
does: decodes packets, answers ACK requests, reassembles large data sets, numbers and
fragments what it sends, learns where each client lives - and hands decoded messages to
the sans-I/O :class:`~edge_vis.tools.sim.subsystem.SimVehicle`. Malformed frames requested by the
vehicle's fault profile are made here, because only the adapter knows the bytes.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
import tty
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.errors import DecodeError, EncodeError
from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import Reassembler, fragment
from edge_vis.jaus.transport import (
    JTS_MAX_PAYLOAD,
    AckNak,
    Broadcast,
    Packet,
    pack_datagram,
    unpack_datagram,
)
from edge_vis.tools.sim.image_serving import start_image_server
from edge_vis.tools.sim.outputs import Action, Restarted, Send
from edge_vis.tools.sim.profile import SimProfile, VehicleSpec
from edge_vis.tools.sim.scripted import vehicle_catalogue
from edge_vis.tools.sim.subsystem import SimVehicle

log = logging.getLogger(__name__)

#: seconds between the counter lines each vehicle logs
STATS_PERIOD = 30.0
#: bytes queued for a pseudo-terminal before further messages are dropped
MAX_SERIAL_BACKLOG = 64 * 1024


class VehicleEndpoint:
    """Transport-level glue shared by UDP and serial vehicles."""

    #: how a medium is named in logs
    medium = "?"

    def __init__(self, spec: VehicleSpec, catalogue: Catalogue | None = None,
                 *, mtu: int = JTS_MAX_PAYLOAD) -> None:
        self.spec = spec
        self.catalogue = catalogue if catalogue is not None else default_catalogue()
        self.mtu = mtu
        self.vehicle: SimVehicle | None = None
        self.counters: Counter[str] = Counter()
        self._sequences: dict[JausAddress, int] = {}
        self._reassembler = Reassembler()
        self._wake = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def where(self) -> str:
        """Where the vehicle is on the air, as a link URL (for messages and scripts)."""
        raise NotImplementedError

    # -- life cycle -----------------------------------------------------------------------

    async def start(self) -> None:
        """Open the medium and start the vehicle's clock."""
        self._loop = asyncio.get_running_loop()
        now = self._loop.time()
        self.vehicle = SimVehicle(self.spec, self.catalogue, start=now,
                                  wall_offset=time.time() - now)
        await self._open()
        self._task = asyncio.create_task(self._timer_loop(), name=f"sim-{self.name}")

    async def stop(self) -> None:
        """Stop the clock and close the medium (idempotent)."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        await self._close()

    async def _open(self) -> None:
        raise NotImplementedError

    async def _close(self) -> None:
        raise NotImplementedError

    def _now(self) -> float:
        assert self._loop is not None
        return self._loop.time()

    async def _timer_loop(self) -> None:
        assert self.vehicle is not None
        next_stats = self._now() + STATS_PERIOD
        while True:
            deadline = self.vehicle.next_deadline()
            frag_deadline = self._reassembler.next_deadline()
            targets = [t for t in (deadline, frag_deadline, next_stats) if t is not None]
            delay = max(0.0, min(targets) - self._now())
            self._wake.clear()
            # asyncio.timeout, not wait_for: 3.11's wait_for can swallow a cancellation
            # that races with the event being set, and stop() would then wait forever
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(delay):
                    await self._wake.wait()
            now = self._now()
            self._reassembler.expire(now)
            try:
                self._perform(self.vehicle.on_timer(now))
            except Exception:  # one bad tick must not stop the vehicle
                log.exception("%s: timer failed", self.name)
            if now >= next_stats:
                next_stats = now + STATS_PERIOD
                self._log_stats()

    def _log_stats(self) -> None:
        assert self.vehicle is not None
        both = self.counters + self.vehicle.counters
        text = ", ".join(f"{k} {v}" for k, v in sorted(both.items()))
        log.info("%s: %s", self.name, text or "no traffic yet")

    # -- receiving ------------------------------------------------------------------------

    def _packets_in(self, packets: Iterable[Packet], peer: Any) -> None:
        """Handle decoded transport packets from ``peer``."""
        vehicle = self.vehicle
        if vehicle is None:
            return
        now = self._now()
        for packet in packets:
            if vehicle.down:
                self.counters["ignored_while_down"] += 1
                continue
            if not any(packet.destination.matches(a) for a in vehicle.components):
                self.counters["not_for_us"] += 1
                continue
            if packet.ack_nak in (AckNak.ACK, AckNak.NAK):
                continue
            self._learn(packet.source, peer)
            if packet.ack_nak == AckNak.REQUEST and not packet.destination.is_broadcast:
                self._write([Packet(packet.source, packet.destination, b"",
                                    sequence=packet.sequence, priority=packet.priority,
                                    ack_nak=AckNak.ACK)], peer)
            whole = self._reassembler.feed(packet, now)
            if whole is None:
                continue
            try:
                message = self.catalogue.decode(whole.payload, vehicle.dialects)
            except DecodeError as exc:
                self.counters["undecodable"] += 1
                log.warning("%s: undecodable message from %s: %s", self.name, whole.source, exc)
                continue
            self.counters["messages_in"] += 1
            try:
                actions = vehicle.receive(whole.source, whole.destination, message, now)
            except Exception:  # a logic bug must not kill the endpoint
                log.exception("%s: failed to handle %s", self.name, message.name)
                continue
            self._perform(actions)
        self._wake.set()

    def _learn(self, source: JausAddress, peer: Any) -> None:
        raise NotImplementedError

    # -- sending --------------------------------------------------------------------------

    def _perform(self, actions: Iterable[Action]) -> None:
        for action in actions:
            if isinstance(action, Restarted):
                self._sequences.clear()
                self._reassembler = Reassembler()
                self.counters["reboots"] += 1
                log.warning("%s: rebooted (sequence numbers restart)", self.name)
            elif isinstance(action, Send):
                self._send(action)

    def _next_sequence(self, source: JausAddress, count: int) -> int:
        seq = self._sequences.get(source, 1)
        self._sequences[source] = (seq + count) & 0xFFFF
        return seq

    @property
    def _dialects(self) -> tuple[str, ...]:
        return self.vehicle.dialects if self.vehicle is not None else ()

    def _send(self, send: Send) -> None:
        if send.name == "ReportAtrImageAvailable" and self.spec.atr_dir:
            self._write_atr_image(int(send.fields["image_id"]))
        try:
            payload = self.catalogue.encode(send.name, send.fields, self._dialects)
        except EncodeError as exc:
            self.counters["encode_errors"] += 1
            log.error("%s: cannot encode %s: %s", self.name, send.name, exc)
            return
        broadcast = send.destination.is_broadcast
        if send.corrupt == "bad_body":
            payload = payload[:2] + b"\x01"  # a code this vehicle knows, a body far too short
        packet = Packet(send.destination, send.source, payload,
                        broadcast=Broadcast.GLOBAL if broadcast else Broadcast.NONE)
        try:
            pieces = fragment(packet, self.mtu)
        except EncodeError as exc:
            self.counters["encode_errors"] += 1
            log.error("%s: cannot send %s: %s", self.name, send.name, exc)
            return
        first = self._next_sequence(send.source, len(pieces))
        pieces = [p.with_sequence(first + i) for i, p in enumerate(pieces)]
        self.counters["messages_out"] += 1
        if len(pieces) > 1:
            self.counters["large_data_sets_out"] += 1
        self._route(pieces, send.destination, send.corrupt)

    def _write_atr_image(self, image_id: int) -> None:
        """Put the announced image where a bulk sender can pick it up (write, then rename)."""
        assert self.vehicle is not None
        folder = Path(self.spec.atr_dir)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            part = folder / f".atr-{image_id}.png.part"
            part.write_bytes(self.vehicle.atr_image(image_id))
            part.replace(folder / f"atr-{image_id}.png")
        except OSError as exc:
            self.counters["atr_write_errors"] += 1
            log.error("%s: cannot write ATR image %d to %s: %s", self.name, image_id, folder,
                      exc)

    def _route(self, packets: list[Packet], destination: JausAddress, corrupt: str) -> None:
        raise NotImplementedError

    def _write(self, packets: list[Packet], peer: Any, corrupt: str = "") -> None:
        raise NotImplementedError


class UdpVehicle(VehicleEndpoint, asyncio.DatagramProtocol):
    """A vehicle on its own loopback address speaking JUDP."""

    medium = "udp"

    def __init__(self, spec: VehicleSpec, catalogue: Catalogue | None = None) -> None:
        super().__init__(spec, catalogue)
        self._transport: asyncio.DatagramTransport | None = None
        self._routes: dict[JausAddress, tuple[str, int]] = {}

    @property
    def address(self) -> tuple[str, int]:
        """The bound (ip, port)."""
        if self._transport is None:
            return self.spec.udp_address
        return self._transport.get_extra_info("sockname")[:2]

    @property
    def where(self) -> str:
        return "udp://{}:{}".format(*self.address)

    async def _open(self) -> None:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: self, local_addr=self.spec.udp_address)
        self._transport = transport
        log.info("%s: JAUS subsystem %d on udp://%s:%d", self.name, self.spec.subsystem,
                 *self.address)

    async def _close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        try:
            packets = unpack_datagram(data)
        except DecodeError as exc:
            self.counters["malformed_in"] += 1
            log.warning("%s: malformed datagram from %s:%d: %s", self.name, *addr[:2], exc)
            return
        self._packets_in(packets, addr[:2])

    def error_received(self, exc: Exception) -> None:
        self.counters["socket_errors"] += 1
        log.debug("%s: socket error %s", self.name, exc)

    def _learn(self, source: JausAddress, peer: Any) -> None:
        if self._routes.get(source) != peer:
            if source not in self._routes:
                log.info("%s: client %s at %s:%d", self.name, source, *peer)
            self._routes[source] = peer

    def _route(self, packets: list[Packet], destination: JausAddress, corrupt: str) -> None:
        if destination.is_broadcast:
            peers = {peer for addr, peer in self._routes.items() if destination.matches(addr)}
        else:
            peer = self._routes.get(destination)
            peers = {peer} if peer is not None else set()
        if not peers:
            self.counters["no_route"] += 1
            return
        for peer in peers:
            self._write(packets, peer, corrupt)

    def _write(self, packets: list[Packet], peer: Any, corrupt: str = "") -> None:
        if self._transport is None:
            return
        for packet in packets:
            data = corrupt_datagram(pack_datagram([packet]), corrupt)
            self._transport.sendto(data, peer)
            self.counters["datagrams_out"] += 1


def corrupt_datagram(data: bytes, how: str) -> bytes:
    """``data`` with the defect ``how`` (see :data:`~edge_vis.tools.sim.subsystem.CORRUPTIONS`)."""
    if how == "truncated":
        return data[: max(3, len(data) // 2)]
    if how == "bad_size":
        return data[:2] + b"\x05" + data[3:]  # data size below the 14-byte minimum
    if how == "bad_version":
        return b"\x07" + data[1:]
    return data


def corrupt_frame(data: bytes, how: str) -> bytes:
    """A serial frame with the defect ``how``: cut short, bad CRC or bad header CRC."""
    if how == "truncated":
        return data[: len(data) // 2]
    if how == "bad_size":  # flip a byte of the message: packet CRC mismatch
        middle = len(data) - 4
        flipped = data[middle] ^ 0x5A
        if flipped == jserial.DLE or data[middle] == jserial.DLE:
            flipped = data[middle] ^ 0x01
        return data[:middle] + bytes((flipped,)) + data[middle + 1 :]
    if how == "bad_version":
        return data[:2] + bytes((data[2] ^ 0x04,)) + data[3:]
    return data


class PtyVehicle(VehicleEndpoint):
    """A vehicle behind a serial line, simulated with a pseudo-terminal pair.

    The simulator keeps the master side; the slave path (``/dev/pts/N``) is what a relay
    opens as its serial port. The path is logged, written to ``pty_path_file`` and linked
    from ``pty_link`` when the profile names them. Output is paced to the profile's baud
    rate (10 bits per byte) like a real UART.
    """

    medium = "serial"

    def __init__(self, spec: VehicleSpec, catalogue: Catalogue | None = None) -> None:
        super().__init__(spec, catalogue)
        self._master = -1
        self._slave = -1
        self.slave_path = ""
        self._deframer = jserial.SerialDeframer()
        self._backlog = bytearray()
        self._writer: asyncio.Task[None] | None = None
        self._routes: set[JausAddress] = set()

    @property
    def where(self) -> str:
        where = f"serial://{self.slave_path}" if self.slave_path else "a pseudo-terminal"
        return where + (f" (link {self.spec.pty_link})" if self.spec.pty_link else "")

    async def _open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self.slave_path = os.ttyname(slave)
        if self.spec.pty_path_file:
            path = Path(self.spec.pty_path_file)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(self.slave_path + "\n", encoding="utf-8")
        if self.spec.pty_link:
            link = Path(self.spec.pty_link)
            link.parent.mkdir(parents=True, exist_ok=True)
            if link.is_symlink():
                link.unlink()
            elif link.exists():
                raise FileExistsError(f"{link} exists and is not a symbolic link")
            link.symlink_to(self.slave_path)
        loop = asyncio.get_running_loop()
        loop.add_reader(master, self._readable)
        self._writer = asyncio.create_task(self._write_loop(), name=f"pty-{self.name}")
        where = f" (link {self.spec.pty_link})" if self.spec.pty_link else ""
        log.info("%s: JAUS subsystem %d on serial pty %s%s at %d baud", self.name,
                 self.spec.subsystem, self.slave_path, where, self.spec.baud)

    async def _close(self) -> None:
        if self._writer is not None:
            self._writer.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._writer
            self._writer = None
        if self._master >= 0:
            asyncio.get_running_loop().remove_reader(self._master)
            os.close(self._master)
            os.close(self._slave)
            self._master = self._slave = -1
        # remove the link and path file only while they still name this run's pty: another
        # simulator started since may have taken them over
        if self.spec.pty_link:
            link = Path(self.spec.pty_link)
            with contextlib.suppress(OSError):
                if link.is_symlink() and os.readlink(link) == self.slave_path:
                    link.unlink()
        if self.spec.pty_path_file:
            path = Path(self.spec.pty_path_file)
            with contextlib.suppress(OSError):
                if path.read_text(encoding="utf-8").strip() == self.slave_path:
                    path.unlink()

    def _readable(self) -> None:
        try:
            data = os.read(self._master, 65536)
        except BlockingIOError:
            return
        except OSError as exc:  # EIO when no slave is open: nothing to read
            self.counters["pty_errors"] += 1
            log.debug("%s: pty read: %s", self.name, exc)
            return
        packets = []
        for item in self._deframer.feed(data, self._now()):
            if isinstance(item, jserial.SerialFrame):
                packets.append(item.packet)
            else:
                self.counters["malformed_in"] += 1
                log.warning("%s: serial %s (%d bytes)", self.name, item.reason, len(item.data))
        if packets:
            self._packets_in(packets, self.slave_path)

    def _learn(self, source: JausAddress, peer: Any) -> None:
        if source not in self._routes:
            log.info("%s: client %s on %s", self.name, source, self.slave_path)
            self._routes.add(source)

    def _route(self, packets: list[Packet], destination: JausAddress, corrupt: str) -> None:
        self._write(packets, self.slave_path, corrupt)  # one line: everything goes on it

    def _write(self, packets: list[Packet], peer: Any, corrupt: str = "") -> None:
        data = b"".join(corrupt_frame(jserial.frame(p), corrupt) for p in packets)
        if len(self._backlog) + len(data) > MAX_SERIAL_BACKLOG:
            self.counters["serial_overflow_drops"] += 1
            return
        self._backlog += data
        self.counters["frames_out"] += len(packets)

    async def _write_loop(self) -> None:
        tick = 0.02
        budget = max(1, int(self.spec.baud / 10 * tick))
        while True:
            await asyncio.sleep(tick)
            if not self._backlog or self._master < 0:
                continue
            chunk = bytes(self._backlog[:budget])
            try:
                written = os.write(self._master, chunk)
            except BlockingIOError:
                continue
            except OSError as exc:
                self.counters["pty_errors"] += 1
                log.debug("%s: pty write: %s", self.name, exc)
                continue
            del self._backlog[:written]


def endpoint_for(spec: VehicleSpec, catalogue: Catalogue | None = None) -> VehicleEndpoint:
    """The endpoint that puts ``spec`` on its medium."""
    return PtyVehicle(spec, catalogue) if spec.is_pty else UdpVehicle(spec, catalogue)


class VehicleLinkError(OSError):
    """A vehicle's medium could not be opened; the message names the vehicle and where."""

    def __init__(self, endpoint: VehicleEndpoint, cause: OSError) -> None:
        reason = cause.strerror or str(cause)
        super().__init__(f"{endpoint.name}: cannot open {endpoint.where}: {reason}")
        self.errno = cause.errno
        self.vehicle = endpoint.name


class Simulation:
    """Every vehicle of a profile, started and stopped together."""

    def __init__(self, profile: SimProfile, catalogue: Catalogue | None = None) -> None:
        self.profile = profile
        self.catalogue = catalogue if catalogue is not None else default_catalogue()
        #: a vehicle with JSIDL of its own speaks the shared catalogue plus its messages
        self.endpoints = [endpoint_for(v, vehicle_catalogue(v.jsidl, self.catalogue))
                          for v in profile.vehicles]
        #: vehicle name -> its running image server (``image_server`` in the profile)
        self.image_servers: dict[str, Any] = {}

    async def start(self) -> None:
        """Open every vehicle's medium; on failure close the ones already open.

        Raises :class:`VehicleLinkError` naming the vehicle whose medium failed.
        """
        started: list[VehicleEndpoint] = []
        try:
            for ep in self.endpoints:
                try:
                    await ep.start()
                except OSError as exc:
                    await ep.stop()
                    raise VehicleLinkError(ep, exc) from exc
                started.append(ep)
            for ep in self.endpoints:
                if ep.spec.image_server:
                    self.image_servers[ep.name] = start_image_server(ep.spec)
        except BaseException:
            for ep in started:
                await ep.stop()
            self._stop_image_servers()
            raise

    def _stop_image_servers(self) -> None:
        for server in self.image_servers.values():
            server.stop()
        self.image_servers.clear()

    async def stop(self) -> None:
        """Close everything."""
        self._stop_image_servers()
        for ep in self.endpoints:
            await ep.stop()

    def endpoint(self, name: str) -> VehicleEndpoint:
        """The endpoint of vehicle ``name`` (KeyError if none)."""
        for ep in self.endpoints:
            if ep.name == name:
                return ep
        raise KeyError(name)


__all__ = [
    "PtyVehicle",
    "Simulation",
    "UdpVehicle",
    "VehicleEndpoint",
    "VehicleLinkError",
    "corrupt_datagram",
    "corrupt_frame",
    "endpoint_for",
]
