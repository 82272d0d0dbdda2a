"""A UDP link with a receive ``cycle``: read on a timer while traffic flows, real sockets
on loopback and a real pty for the serial side."""

from __future__ import annotations

import asyncio
import socket

import pytest
from linkkit import Pty, free_port, msg, run, until

from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import SerialDeframer, SerialFrame
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.routing.link import Peer, check_link_url, create_link
from edge_vis.routing.router import Router
from edge_vis.tools.testing import RouterNode
from links.udp import UdpLink

RELAY = JausAddress(200, 1, 1)
OPERATOR = JausAddress(42, 1, 1)
VEHICLE = JausAddress(126, 1, 199)
HOST, SENDER = "127.0.0.2", "127.0.0.3"


def telemetry(seq: int) -> Packet:
    return msg(OPERATOR, VEHICLE, seq.to_bytes(4, "little"), code=0x4402, sequence=seq)


def sender() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((SENDER, 0))
    return sock


class Recorder:
    """The link's receiving side as the runtime sees it: every deliver call."""

    def __init__(self) -> None:
        self.calls: list[list[Packet]] = []

    def __call__(self, link: str, peer: Peer, packets: list[Packet]) -> None:
        self.calls.append(list(packets))

    @property
    def packets(self) -> list[Packet]:
        return [p for call in self.calls for p in call]


def test_cycle_is_validated_like_every_option() -> None:
    assert check_link_url("udp://127.0.0.1:3794?cycle=0.002").cycle == 0.002  # type: ignore[attr-defined]
    assert create_link("udp://127.0.0.1:3794").cycle == 0  # type: ignore[attr-defined]
    for bad, reason in (("0.5", "must be"), ("-1", "must be"), ("soon", "not a number")):
        with pytest.raises(ConfigError) as info:
            check_link_url(f"udp://127.0.0.1:3794?cycle={bad}")
        assert reason in str(info.value) and "cycle" in str(info.value)


def test_cycle_link_delivers_everything_in_order_in_few_wake_ups() -> None:
    async def scenario() -> None:
        port = free_port()
        link = UdpLink(f"udp://{HOST}:{port}?cycle=0.02", name="in")
        got = Recorder()
        await link.open(got)
        tx = sender()
        try:
            # a steady stream, one datagram at a time: several per cycle
            for seq in range(1, 201):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
                await asyncio.sleep(0.002)
            await until(lambda: len(got.packets) == 200)
            assert [p.sequence for p in got.packets] == list(range(1, 201))
            # the point of the cycle: one read (and one router pass) per cycle, not one
            # per datagram
            assert len(got.calls) < 100, len(got.calls)
            # quiet again: the link waits on its socket, and a lone datagram is read at once
            await asyncio.sleep(0.1)
            calls = len(got.calls)
            tx.sendto(pack_datagram([telemetry(500)]), (HOST, port))
            await until(lambda: len(got.calls) == calls + 1)
            assert got.calls[-1][0].sequence == 500
            assert link.stats().messages_in == 201
        finally:
            tx.close()
            await link.close()

    run(scenario())


def test_send_never_waits_for_the_cycle() -> None:
    async def scenario() -> None:
        port = free_port()
        link = UdpLink(f"udp://{HOST}:{port}?cycle=0.1&multicast=off", name="in")
        await link.open(Recorder())
        tx = sender()
        tx.setblocking(False)
        try:
            tx.sendto(pack_datagram([telemetry(1)]), (HOST, port))
            await until(lambda: link.stats().messages_in == 1)  # now reading on the cycle
            stop = msg(OPERATOR, VEHICLE, b"\x01", code=0x0006, priority=3)
            link.send_urgent([stop], tx.getsockname())
            link.send([telemetry(2)], tx.getsockname())
            # both are on the peer's socket when the calls return: no loop turn, no cycle
            first = unpack_datagram(tx.recv(65535))[0]
            second = unpack_datagram(tx.recv(65535))[0]
            assert (first.message_code, second.sequence) == (0x0006, 2)
        finally:
            tx.close()
            await link.close()

    run(scenario())


def test_emergency_read_in_a_cycle_leaves_first_on_a_paced_radio() -> None:
    """Telemetry and an emergency stop read in one cycle are relayed to a 9,600 baud
    serial radio: the stop is written first, the telemetry in arrival order behind it."""

    async def scenario() -> None:
        port = free_port()
        pty = Pty()
        node = RouterNode(Router([RELAY]), [
            create_link(f"udp://{HOST}:{port}?cycle=0.05&multicast=off", name="lan"),
            create_link(f"serial://{pty.path}?baud=9600", name="radio"),
        ])
        await node.start()
        node.router.set_relay("lan", "radio")
        node.router.add_route(VEHICLE, "radio", pty.path)
        tx = sender()
        deframer = SerialDeframer()
        frames: list[Packet] = []

        def read() -> None:
            frames.extend(f.packet for f in deframer.feed(pty.read())
                          if isinstance(f, SerialFrame))

        try:
            tx.sendto(pack_datagram([telemetry(1)]), (HOST, port))  # starts the cycle
            await until(lambda: (read(), len(frames))[1] == 1)
            stop = msg(OPERATOR, VEHICLE, b"\x01", code=0x0006, priority=3, sequence=99)
            for seq in range(2, 22):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
            tx.sendto(pack_datagram([stop]), (HOST, port))
            await until(lambda: (read(), len(frames))[1] == 22, timeout=5.0)
            assert frames[1].message_code == 0x0006
            assert [f.sequence for f in frames[2:]] == list(range(2, 22))
        finally:
            tx.close()
            await node.stop()
            pty.close()

    run(scenario())


def test_duplicates_within_and_across_cycles_are_dropped() -> None:
    async def scenario() -> None:
        port = free_port()
        node = RouterNode(Router([RELAY]), [
            create_link(f"udp://{HOST}:{port}?cycle=0.05&multicast=off", name="lan")])
        await node.start()
        tx = sender()
        try:
            to_us = msg(OPERATOR, RELAY, b"\x07", code=0x4402, sequence=7)
            tx.sendto(pack_datagram([msg(OPERATOR, RELAY, code=0x4402, sequence=1)]),
                      (HOST, port))
            await until(lambda: node.delivered.qsize() == 1)  # the link reads on its cycle now
            for _ in range(3):  # one cycle: the original and two copies (radio retries)
                tx.sendto(pack_datagram([to_us]), (HOST, port))
            await asyncio.sleep(0.08)
            tx.sendto(pack_datagram([to_us]), (HOST, port))  # a later cycle
            await until(lambda: node.router.counters["dropped: duplicate"] == 3)
            await asyncio.sleep(0.1)
            assert node.delivered.qsize() == 2
        finally:
            tx.close()
            await node.stop()

    run(scenario())
