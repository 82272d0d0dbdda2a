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
import struct
from pathlib import Path
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

from .battery_rig import identified_and_reporting, prepare, relay_and_operator

pytestmark = pytest.mark.dds

pytest.importorskip("edge_vis.dds")

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


def test_battery_pack_from_jsidl_to_dds(domain_id: int, partition: str,
                                        tmp_path: Path) -> None:
    relay_toml, registry = prepare(tmp_path, domain_id, partition, RELAY_IP, PACK_IP)

    async def run() -> None:
        loop = asyncio.get_running_loop()
        peer = BatteryPackPeer()
        await loop.create_datagram_endpoint(lambda: peer, local_addr=(PACK_IP, 3794))
        try:
            async with relay_and_operator(relay_toml, domain_id, partition,
                                          registry) as operator:
                report = await identified_and_reporting(operator)
                assert report["state_of_charge_pct"] == pytest.approx(81.0, abs=0.4)
                assert report.get("temperature_c") is None  # not sent
                # found without JAUS discovery and asked for its report by polling: the
                # pack lists no Events service
                assert peer.asked(0xE0C1) and not peer.asked(0x01F0)  # CreateEvent
                assert not peer.asked(0x2B03) and not peer.asked(0x2B01)  # Query{Services,..}
        finally:
            peer.close()

    asyncio.run(run())
