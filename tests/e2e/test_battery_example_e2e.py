"""The README's battery example, end to end from its shipped files, no Python of its own.

``edge-vis run`` runs in a process of its own on a copy of ``profiles/examples/battery/``
(relay.toml with only its link and DDS domain moved to the test's, the JSIDL it loads and
the discovery profile it takes, unchanged). The pack is a peer written here from
BatteryPack.xml, byte by byte as its firmware would be: it says ReportBatteryHello and
answers QueryBatteryPack over real UDP, and knows nothing else of JAUS. An operator's
Cyclone DDS participant in this process must see the pack identified by its hello and its
report on the BatteryPack topic.
"""

from __future__ import annotations

import asyncio
import shutil
import struct
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"
RELAY_IP, PACK_IP = "127.0.0.87", "127.0.0.88"
PACK = JausAddress(77, 1, 3)
RELAY = JausAddress(200, 1, 1)
BATTERY_PACK = "urn:example:battery:BatteryPack"


def text(value: str) -> bytes:
    """A variable_length_string with an unsigned byte count."""
    data = value.encode()
    return bytes([len(data)]) + data


def scaled(value: float, lower: float, upper: float, bits: int) -> int:
    """A JSIDL scale_range: round((value - lower) / ((upper - lower) / (2**bits - 1)))."""
    return round((value - lower) * (2 ** bits - 1) / (upper - lower))


class BatteryPackPeer(asyncio.DatagramProtocol):
    """The pack's firmware: a hello every ``period`` and ReportBatteryPack when asked."""

    def __init__(self, period: float = 0.3) -> None:
        self.period = period
        self.transport: Any = None
        self.received: list[tuple[JausAddress, JausAddress, int]] = []
        self.sequence = 0
        self.task: asyncio.Task[None] | None = None

    def connection_made(self, transport: Any) -> None:
        self.transport = transport
        self.task = asyncio.get_running_loop().create_task(self._hello())

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        for packet in unpack_datagram(data):
            code = struct.unpack_from("<H", packet.payload)[0]
            self.received.append((packet.source, packet.destination, code))
            if code == 0xE0C1 and packet.destination == PACK:  # QueryBatteryPack
                self.send(packet.source, self.report())

    def send(self, to: JausAddress, payload: bytes) -> None:
        self.sequence += 1
        self.transport.sendto(pack_datagram([Packet(to, PACK, payload,
                                                    sequence=self.sequence)]),
                              (RELAY_IP, 3794))

    @staticmethod
    def hello() -> bytes:
        return (struct.pack("<H", 0xF0C0) + text("BP-0042") + text("Aft pack")
                + bytes([1])                                  # chemistry LIFEPO4
                + bytes([1]) + text(BATTERY_PACK))            # one service

    @staticmethod
    def report() -> bytes:
        return struct.pack("<HBHHBB", 0xF0C1, 0b10,          # pack_state present
                           scaled(48.2, 0, 100, 16), scaled(-12.5, -200, 200, 16),
                           scaled(81.0, 0, 100, 8), 2)       # DISCHARGING

    async def _hello(self) -> None:
        while True:
            self.send(RELAY, self.hello())
            await asyncio.sleep(self.period)

    def asked(self, code: int) -> list[JausAddress]:
        """Sources of the messages of ``code`` sent to the pack itself."""
        return [src for src, dst, c in self.received if c == code and dst == PACK]

    def close(self) -> None:
        if self.task is not None:
            self.task.cancel()
        self.transport.close()


async def collect(operator: Any, topic: str, vehicle_id: str,
                  timeout: float = 10.0) -> dict[str, Any]:
    reader = operator.reader(topic)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in await asyncio.to_thread(reader.take, 0.2):
            if sample["vehicle_id"] == vehicle_id:
                return dict(sample)
    raise AssertionError(f"no {topic} sample of {vehicle_id} within {timeout} s")


def test_battery_pack_from_jsidl_to_dds(domain_id: int, partition: str,
                                        tmp_path: Path) -> None:
    from edge_vis.catalogue.jsidl import profile_catalogue
    from edge_vis.dds.topics import TopicRegistry
    from translators.generic import GenericTranslator

    for name in ("BatteryPack.xml", "battery-pack.toml", "relay.toml"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    relay_toml = tmp_path / "relay.toml"
    text = relay_toml.read_text()
    for old, new in (('url = "udp://127.0.0.1:3794"',
                      f'url = "udp://{RELAY_IP}:3794?peers={PACK_IP}:3794"'),
                     ("[dds]\ndomain = 0\n",
                      f'[dds]\ndomain = {domain_id}\npartitions = ["{partition}"]\n')):
        assert old in text
        text = text.replace(old, new)
    relay_toml.write_text(text)
    # the operator's side: the topic the mapping publishes, typed from the JSIDL
    generic = GenericTranslator()
    generic.configure(tomllib.loads(text)["translators"]["generic"])
    generic.verify(profile_catalogue([EXAMPLE / "BatteryPack.xml"]))
    registry = TopicRegistry.standard()
    registry.register_all(generic.topic_types, owner="station")

    async def run() -> None:
        loop = asyncio.get_running_loop()
        peer = BatteryPackPeer()
        await loop.create_datagram_endpoint(lambda: peer, local_addr=(PACK_IP, 3794))
        relay = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "edge_vis", "run", "--profile", str(relay_toml),
            "--duration", "60", stdout=asyncio.subprocess.DEVNULL,
            stderr=asyncio.subprocess.PIPE)
        operator = dds.DdsBridge(domain_id, (partition,), registry)
        try:
            ident = await collect(operator, "VehicleIdentification", "BP-0042", 20.0)
            assert (ident["name"], ident["vehicle_type"]) == ("Aft pack", "LIFEPO4")
            assert ident["jaus_address"] == "77.1.3"
            report = await collect(operator, "BatteryPack", "BP-0042")
            assert report["voltage_v"] == pytest.approx(48.2, abs=0.01)
            assert report["current_a"] == pytest.approx(-12.5, abs=0.01)
            assert report["state_of_charge_pct"] == pytest.approx(81.0, abs=0.4)
            assert report["state"] == 2 and report.get("temperature_c") is None  # not sent
            # found without JAUS discovery and asked for its report by polling: the pack
            # lists no Events service
            assert peer.asked(0xE0C1) and not peer.asked(0x01F0)  # CreateEvent
            assert not peer.asked(0x2B03) and not peer.asked(0x2B01)  # Query{Services,Config}
        finally:
            if relay.returncode is None:
                relay.terminate()
            _, err = await relay.communicate()
            operator.close()
            peer.close()
        assert relay.returncode in (0, -15), err.decode()[-2000:]

    asyncio.run(run())
