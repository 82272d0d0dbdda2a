"""A relay between a UDP network and a serial radio, with a JAUS node on each side.

The radio is two pseudo-terminals joined by a wire that carries 57600 baud (5760 bytes/s),
so the router's pacing and the ACK timers meet a real radio's pace.
"""

from __future__ import annotations

import asyncio
import random
import socket

import pytest
from linkkit import ThrottledWire, collect, free_port, msg, run, until

from edge_vis.errors import DecodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import frame
from edge_vis.jaus.transport import AckNak, pack_datagram, unpack_datagram
from edge_vis.routing.link import create_link
from edge_vis.routing.router import Router
from edge_vis.tools.testing import RouterNode

pytestmark = pytest.mark.serial

RELAY = JausAddress(200, 1, 1)
OCU = JausAddress(42, 1, 1)  # on UDP, 127.0.0.3
ROBOT = JausAddress(126, 1, 199)  # on the radio
BAUD = 57600


class Network:
    """relay (udp 127.0.0.2 + radio end 0), ocu (udp 127.0.0.3), robot (radio end 1)."""

    def __init__(self) -> None:
        self.port = free_port(("127.0.0.2", "127.0.0.3"))
        self.wire = ThrottledWire(BAUD)
        relay_udp = create_link(f"udp://127.0.0.2:{self.port}?peers=127.0.0.3:{self.port}",
                                name="udp")
        relay_radio = create_link(f"serial://{self.wire.paths[0]}?baud={BAUD}", name="radio")
        self.relay = RouterNode(Router([RELAY]), [relay_udp, relay_radio])
        self.relay.router.set_relay("udp", "radio")
        self.ocu = RouterNode(Router([OCU]), [create_link(
            f"udp://127.0.0.3:{self.port}?peers=127.0.0.2:{self.port}", name="udp")])
        self.robot = RouterNode(Router([ROBOT]), [create_link(
            f"serial://{self.wire.paths[1]}?baud={BAUD}", name="radio")])

    async def __aenter__(self) -> Network:
        self.wire.start()
        for node in (self.relay, self.ocu, self.robot):
            await node.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        for node in (self.relay, self.ocu, self.robot):
            await node.stop()
        await self.wire.stop()


def test_udp_node_and_radio_node_talk_through_the_relay() -> None:
    async def scenario() -> None:
        async with Network() as net:
            # the OCU has never heard of the robot: JTS-style ACKed broadcast finds it
            net.ocu.send(msg(OCU, ROBOT, b"\x02", code=0x2B00))
            (query,) = await collect(net.robot.delivered, 1)
            assert query.packet.source == OCU and query.packet.ack_nak == AckNak.REQUEST
            await until(lambda: net.ocu.router.stats().pending_acks == 0)
            route = net.ocu.router.lookup(ROBOT)
            assert route is not None and route.peer == ("127.0.0.2", net.port)
            # the robot answers; the reply crosses the radio and the relay to the OCU
            net.robot.send(msg(ROBOT, OCU, b"\x02\x11\x27\x05Robot", code=0x4B00))
            (reply,) = await collect(net.ocu.delivered, 1)
            assert reply.packet.message_code == 0x4B00
            assert reply.peer == ("127.0.0.2", net.port)
            # a stream of commands arrives complete and in order at radio pace
            for i in range(20):
                net.ocu.send(msg(OCU, ROBOT, bytes([i]), code=0x0405))
            got = await collect(net.robot.delivered, 20)
            assert [d.packet.payload[2] for d in got] == list(range(20))
            assert net.ocu.failures == []
            # the relay's health counters saw it all
            radio = net.relay.links["radio"].stats()
            assert radio.messages_out >= 21 and radio.messages_in >= 2
            assert net.relay.router.stats().counters["forwarded"] >= 22
            assert net.relay.delivered.empty()  # nothing was for the relay itself

    run(scenario(), timeout=20)


def test_fuzz_both_links_while_valid_traffic_flows() -> None:
    async def scenario() -> None:
        rng = random.Random(5710)
        async with Network() as net:
            net.ocu.send(msg(OCU, ROBOT, code=0x2B00))  # make the routes known
            await collect(net.robot.delivered, 1)
            await until(lambda: net.ocu.router.stats().pending_acks == 0)
            jammer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            jammer.bind(("127.0.0.4", 0))
            bad_udp = 0
            try:
                for i in range(40):
                    net.ocu.send(msg(OCU, ROBOT, i.to_bytes(2, "little"), code=0x0405))
                    net.robot.send(msg(ROBOT, OCU, i.to_bytes(2, "little"), code=0x4402))
                    junk = rng.choice((
                        rng.randbytes(rng.randrange(1, 60)),
                        b"\x02" + rng.randbytes(rng.randrange(1, 40)),
                        pack_datagram([msg(OCU, ROBOT)])[:-3],
                    ))
                    try:
                        unpack_datagram(junk)
                    except DecodeError:
                        bad_udp += 1
                    jammer.sendto(junk, ("127.0.0.2", net.port))
                    broken = bytearray(frame(msg(ROBOT, OCU, b"\x99", code=0x4402)))
                    broken[rng.randrange(2, len(broken))] ^= 0x40
                    for end in (0, 1):
                        net.wire.inject(end, rng.randbytes(rng.randrange(1, 30)))
                        net.wire.inject(end, bytes(broken[: rng.randrange(3, len(broken))]))
                        net.wire.inject(end, bytes(broken))
                    await asyncio.sleep(0.005)
                at_robot = [d for d in await collect(net.robot.delivered, 40, timeout=8)]
                assert [int.from_bytes(d.packet.payload[2:4], "little") for d in at_robot] == (
                    list(range(40)))
                at_ocu = await collect(net.ocu.delivered, 40, timeout=8)
                assert [int.from_bytes(d.packet.payload[2:4], "little") for d in at_ocu] == (
                    list(range(40)))
                await until(lambda: net.relay.links["udp"].stats().malformed == bad_udp)
                assert net.relay.links["radio"].stats().malformed > 0
                assert net.robot.links["radio"].stats().malformed > 0
            finally:
                jammer.close()

    run(scenario(), timeout=30)
