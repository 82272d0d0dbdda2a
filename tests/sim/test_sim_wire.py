"""Simulated vehicles on real sockets and pseudo-terminals, talked to by a hand-written client.

The client here is deliberately not the relay: a bare asyncio socket, the transport codec,
the catalogue and the reassembler - so these tests check the simulator on its own.
"""

from __future__ import annotations

import asyncio
import hashlib
import os
import socket
import subprocess
import sys
import tty
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from conftest import spec

from edge_vis.catalogue import default_catalogue
from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.fragments import Reassembler
from edge_vis.jaus.transport import AckNak, DataFlags, Packet, pack_datagram, unpack_datagram
from edge_vis.tools.sim.images import camera_frame
from edge_vis.tools.sim.profile import SimProfile
from edge_vis.tools.sim.runner import PtyVehicle, Simulation, UdpVehicle

ME = JausAddress(200, 1, 1)
CAT = default_catalogue()


class Client(asyncio.DatagramProtocol):
    """A minimal JAUS client on UDP: sends messages, collects and reassembles packets."""

    def __init__(self) -> None:
        self.packets: list[Packet] = []
        self.messages: asyncio.Queue[tuple[Packet, Any]] = asyncio.Queue()
        self.reassembler = Reassembler()
        self.transport: asyncio.DatagramTransport | None = None
        self.sequence = 1

    def datagram_received(self, data: bytes, addr: Any) -> None:
        loop = asyncio.get_running_loop()
        for packet in unpack_datagram(data):
            self.packets.append(packet)
            if packet.ack_nak == AckNak.ACK:
                continue
            whole = self.reassembler.feed(packet, loop.time())
            if whole is not None:
                self.messages.put_nowait((whole, CAT.decode(whole.payload)))

    def send(self, peer: tuple[str, int], to: JausAddress, name: str,
             fields: dict | None = None, **flags: Any) -> None:
        packet = Packet(to, ME, CAT.encode(name, fields or {}), sequence=self.sequence, **flags)
        self.sequence += 1
        assert self.transport is not None
        self.transport.sendto(pack_datagram([packet]), peer)

    async def expect(self, name: str, timeout: float = 2.0) -> tuple[Packet, Any]:
        async with asyncio.timeout(timeout):
            while True:
                packet, message = await self.messages.get()
                if message.name == name:
                    return packet, message


async def _with_ugv(body: Any) -> None:
    vehicle = replace(spec(name="ugv-udp", link="udp://127.0.0.71:0"), seed=5)
    sim = Simulation(SimProfile((vehicle,)))
    await sim.start()
    loop = asyncio.get_running_loop()
    client = Client()
    transport, _ = await loop.create_datagram_endpoint(lambda: client,
                                                       local_addr=("127.0.0.1", 0))
    client.transport = transport
    try:
        endpoint = sim.endpoints[0]
        assert isinstance(endpoint, UdpVehicle)
        await body(client, endpoint)
    finally:
        transport.close()
        await sim.stop()


def test_discover_control_events_and_fragmented_image_over_udp() -> None:
    async def body(client: Client, endpoint: UdpVehicle) -> None:
        peer = endpoint.address
        client.send(peer, BROADCAST, "QueryIdentification", {"query_type": 2},
                    broadcast=2)
        packet, ident = await client.expect("ReportIdentification")
        assert ident.fields["identification"] == "ugv-udp"
        node_manager = packet.source
        client.send(peer, node_manager, "QueryServices", {"node_list": []})
        _, services = await client.expect("ReportServices")
        by_uri = {s["uri"]: c["component_rec"]["component_id"]
                  for c in services.fields["node_list"][0]["component_list"]
                  for s in c["service_list"]}
        platform = JausAddress(101, 1, by_uri["urn:jaus:jss:mobility:PrimitiveDriver"])
        camera = JausAddress(101, 1, by_uri["urn:jaus:jss:environmentSensing:StillImage"])

        await asyncio.sleep(0.6)  # past INITIALIZE
        client.send(peer, platform, "RequestControl", {"authority_code": 100})
        _, confirm = await client.expect("ConfirmControl")
        assert confirm.fields["response_code"] == 0

        client.send(peer, platform, "CreateEvent", {
            "request_id": 1, "event_type": 0, "requested_periodic_rate": 10.0,
            "query_message": CAT.encode("QueryGlobalPose", {"presence_vector": 3})})
        _, confirmed = await client.expect("ConfirmEventRequest")
        event_id = confirmed.fields["event_id"]
        loop = asyncio.get_running_loop()
        start = loop.time()
        events = []
        while loop.time() - start < 2.0:
            _, event = await client.expect("Event")
            events.append(event)
        assert 17 <= len(events) <= 23  # 10 Hz for 2 s
        assert {e.fields["event_id"] for e in events} == {event_id}
        seqs = [e.fields["sequence_number"] for e in events]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
        assert CAT.unwrap_event(events[-1]).name == "ReportGlobalPose"

        vehicle = endpoint.vehicle
        assert vehicle is not None
        before = int(vehicle._physics_time)
        client.packets.clear()
        client.send(peer, camera, "QueryStillImageData", {"query_still_image_data_list": [
            {"sensor_id": 1, "report_coordinate_system": 0, "query_presence_vector": 0}]})
        _, report = await client.expect("ReportStillImageData")
        after = int(vehicle._physics_time)
        flags = [p.data_flags for p in client.packets if p.source == camera]
        assert flags[0] == DataFlags.FIRST and flags[-1] == DataFlags.LAST
        assert len(flags) >= 3 and set(flags[1:-1]) <= {DataFlags.MIDDLE}
        assert max(len(p.payload) for p in client.packets) <= 4079
        frame = report.fields["still_image_data_list"][0]["image_frame"]
        candidates = {camera_frame(160, 120, 5, n) for n in range(before, after + 1)}
        assert frame["format"] == 2 and frame["data"] in candidates

    asyncio.run(_with_ugv(body))


def test_acks_and_malformed_input_over_udp() -> None:
    async def body(client: Client, endpoint: UdpVehicle) -> None:
        peer = endpoint.address
        platform = JausAddress(101, 1, 2)
        client.packets.clear()
        client.send(peer, platform, "QueryHeartbeatPulse", ack_nak=AckNak.REQUEST)
        await client.expect("ReportHeartbeatPulse")
        acks = [p for p in client.packets if p.ack_nak == AckNak.ACK]
        assert len(acks) == 1 and acks[0].payload == b"" and acks[0].source == platform
        assert client.transport is not None
        client.transport.sendto(b"\x02\x00\x05\x00garbage", peer)
        client.transport.sendto(b"\x09rubbish", peer)
        client.send(peer, platform, "QueryStatus")
        await client.expect("ReportStatus")
        assert endpoint.counters["malformed_in"] == 2

    asyncio.run(_with_ugv(body))


def test_reboot_restarts_transport_sequence_numbers() -> None:
    vehicle = spec(name="ugv-reboot", link="udp://127.0.0.73:0",
                   faults={"dropout_every": 100.0, "dropout_first": 0.6,
                           "dropout_duration": 0.6, "dropout_reboot": True})

    async def main() -> None:
        sim = Simulation(SimProfile((vehicle,)))
        await sim.start()
        loop = asyncio.get_running_loop()
        client = Client()
        transport, _ = await loop.create_datagram_endpoint(lambda: client,
                                                           local_addr=("127.0.0.1", 0))
        client.transport = transport
        endpoint = sim.endpoints[0]
        assert isinstance(endpoint, UdpVehicle)
        platform = JausAddress(101, 1, 2)
        try:
            seqs = []
            for _ in range(3):
                client.send(endpoint.address, platform, "QueryStatus")
                packet, _ = await client.expect("ReportStatus")
                seqs.append(packet.sequence)
            assert seqs == [seqs[0], seqs[0] + 1, seqs[0] + 2]
            await asyncio.sleep(0.8)  # inside the drop-out (0.6 .. 1.2 s)
            client.send(endpoint.address, platform, "QueryStatus")
            with pytest.raises(TimeoutError):
                await client.expect("ReportStatus", timeout=0.3)
            await asyncio.sleep(0.4)  # back, rebooted
            client.send(endpoint.address, platform, "QueryStatus")
            packet, _ = await client.expect("ReportStatus")
            assert packet.sequence == 1
            assert endpoint.counters["reboots"] == 1
        finally:
            transport.close()
            await sim.stop()

    asyncio.run(main())


@pytest.mark.serial
def test_uuv_on_a_pseudo_terminal(tmp_path: Path) -> None:
    link, path_file = tmp_path / "uuv", tmp_path / "uuv.path"
    vehicle = spec(name="uuv-pty", kind="uuv", subsystem=300, link="pty",
                   pty_link=str(link), pty_path_file=str(path_file), hello_period=0.3,
                   environment_period=0.0, atr_period=0.5, baud=115200,
                   atr_dir=str(tmp_path / "atr"))

    async def main() -> None:
        sim = Simulation(SimProfile((vehicle,)))
        await sim.start()
        endpoint = sim.endpoints[0]
        assert isinstance(endpoint, PtyVehicle)
        fd = os.open(link, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd)
        deframer = jserial.SerialDeframer()
        loop = asyncio.get_running_loop()
        got: asyncio.Queue[Any] = asyncio.Queue()

        def readable() -> None:
            for item in deframer.feed(os.read(fd, 4096), loop.time()):
                if isinstance(item, jserial.SerialFrame):
                    got.put_nowait(CAT.decode(item.packet.payload))

        loop.add_reader(fd, readable)
        try:
            assert path_file.read_text().strip() == os.path.realpath(link)
            async with asyncio.timeout(3.0):
                hello = await got.get()
                assert hello.name == "VendorHello" and hello.fields["vehicle_name"] == "uuv-pty"
                os.write(fd, jserial.frame(Packet(JausAddress(300, 1, 1), ME,
                                                  CAT.encode("QueryHeartbeatPulse", {}))))
                while (await got.get()).name != "ReportHeartbeatPulse":
                    pass
                while (notice := await got.get()).name != "ReportAtrImageAvailable":
                    pass
        finally:
            loop.remove_reader(fd)
            os.close(fd)
            await sim.stop()
        assert not link.exists() and not path_file.exists()
        image = (tmp_path / "atr" / f"atr-{notice.fields['image_id']}.png").read_bytes()
        assert hashlib.sha256(image).digest() == notice.fields["sha256"]
        assert len(image) == notice.fields["size_bytes"]

    asyncio.run(main())


def test_sim_command_prints_where_each_vehicle_is(tmp_path: Path) -> None:
    profile = tmp_path / "one.toml"
    profile.write_text('seed = 1\n[[vehicles]]\nname = "cli-ugv"\nsubsystem = 150\n'
                       'link = "udp://127.0.0.72:0"\n')
    done = subprocess.run([sys.executable, "-m", "edge_vis", "sim", "--profile", str(profile),
                           "--duration", "0.5"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("cli-ugv ugv 150 udp://127.0.0.72:")
    bad = tmp_path / "bad.toml"
    bad.write_text('[[vehicles]]\nname = "x"\nlink = "tcp://1.2.3.4:5"\nspeed = 3\n')
    done = subprocess.run([sys.executable, "-m", "edge_vis", "sim", "--profile", str(bad)],
                          capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    for needle in ("subsystem", "link", "speed: unknown key"):
        assert needle in done.stderr


def test_sim_reports_a_taken_address_on_stderr_naming_the_vehicle(tmp_path: Path) -> None:
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.73", 0))
    port = holder.getsockname()[1]
    profile = tmp_path / "taken.toml"
    profile.write_text('[[vehicles]]\nname = "first"\nsubsystem = 151\n'
                       'link = "udp://127.0.0.74:0"\n'
                       '[[vehicles]]\nname = "blocked"\nsubsystem = 152\n'
                       f'link = "udp://127.0.0.73:{port}"\n')
    try:
        done = subprocess.run([sys.executable, "-m", "edge_vis", "sim", "--profile",
                               str(profile), "--duration", "5"],
                              capture_output=True, text=True, timeout=30)
    finally:
        holder.close()
    assert done.returncode == 2
    assert done.stdout == ""  # stdout is for "vehicle on the air" lines only
    assert f"edge-vis sim: blocked: cannot open udp://127.0.0.73:{port}: " in done.stderr
    assert "Address already in use" in done.stderr and "already running?" in done.stderr
