"""JUDP over real UDP sockets: three JAUS nodes on 127.0.0.2, .3 and .4."""

from __future__ import annotations

import asyncio
import random
import socket

from linkkit import collect, free_port, msg, run, until

from edge_vis.errors import DecodeError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.transport import AckNak, pack_datagram, unpack_datagram
from edge_vis.routing.link import create_link
from edge_vis.routing.router import Router
from edge_vis.tools.testing import RouterNode
from links.udp import UdpLink

A = JausAddress(200, 1, 1)
B = JausAddress(201, 1, 1)
C = JausAddress(202, 1, 1)
HOSTS = {A: "127.0.0.2", B: "127.0.0.3", C: "127.0.0.4"}


def node(me: JausAddress, port: int, options: str = "") -> RouterNode:
    peers = ",".join(f"{h}:{port}" for a, h in HOSTS.items() if a != me)
    link = create_link(f"udp://{HOSTS[me]}:{port}?peers={peers}{options}", name="udp")
    return RouterNode(Router([me]), [link])


def test_url_selects_udp_plugin_with_defaults() -> None:
    link = create_link("udp://0.0.0.0:3794")
    assert isinstance(link, UdpLink)
    assert link.multicast == "239.255.0.1" and link.ttl == 16
    assert link.broadcast_to == ["multicast", "peers"]
    assert create_link("udp://127.0.0.2:4000").multicast == ""  # cannot join on one address


def test_three_nodes_broadcast_reply_then_unicast() -> None:
    async def scenario() -> None:
        port = free_port()
        a, b, c = node(A, port), node(B, port), node(C, port)
        for n in (a, b, c):
            await n.start()
        try:
            a.send(msg(A, BROADCAST, code=0x2B00))  # QueryIdentification to everyone
            (db,) = await collect(b.delivered, 1)
            (dc,) = await collect(c.delivered, 1)
            assert db.peer == ("127.0.0.2", port) and dc.packet.source == A
            b.send(msg(B, A, b"\x02Bravo", code=0x4B00))  # replies go unicast
            c.send(msg(C, A, b"\x02Charlie", code=0x4B00))
            replies = await collect(a.delivered, 2)
            assert {d.peer for d in replies} == {("127.0.0.3", port), ("127.0.0.4", port)}
            # A learned where C lives: a unicast reaches C only
            a.send(msg(A, C, b"\x01", code=0x000D))
            (only,) = await collect(c.delivered, 1)
            assert only.packet.message_code == 0x000D
            await asyncio.sleep(0.05)
            assert b.delivered.empty()
            stats = a.links["udp"].stats()
            assert stats.messages_out == 3  # broadcast to 2 peers + 1 unicast
            assert stats.peers[f"127.0.0.4:{port}"].messages_in == 1
        finally:
            for n in (a, b, c):
                await n.stop()

    run(scenario())


def test_unknown_destination_found_by_acked_broadcast() -> None:
    async def scenario() -> None:
        port = free_port()
        a, b, c = node(A, port), node(B, port), node(C, port)
        for n in (a, b, c):
            await n.start()
        try:
            a.send(msg(A, C, code=0x2002))  # A has never heard of C
            (got,) = await collect(c.delivered, 1)
            assert got.packet.ack_nak == AckNak.REQUEST
            await until(lambda: a.router.stats().pending_acks == 0)
            route = a.router.lookup(C)
            assert route is not None and route.peer == ("127.0.0.4", port)
            assert a.failures == [] and b.delivered.empty()
        finally:
            for n in (a, b, c):
                await n.stop()

    run(scenario())


def test_packed_datagrams_carry_several_messages() -> None:
    async def scenario() -> None:
        port = free_port()
        a = node(A, port, "&pack=1")
        b = node(B, port)
        await a.start()
        await b.start()
        try:
            link = a.links["udp"]
            link.send([msg(A, B, bytes([i])) for i in range(20)], ("127.0.0.3", port))
            got = await collect(b.delivered, 20)
            assert [d.packet.payload[-1] for d in got] == list(range(20))
            assert link.stats().peers[f"127.0.0.3:{port}"].messages_out == 20
            assert b.links["udp"].counters.bytes_in < 20 * 18  # one version byte, not 20
        finally:
            await a.stop()
            await b.stop()

    run(scenario())


def test_malformed_datagrams_counted_while_valid_traffic_flows() -> None:
    async def scenario() -> None:
        port = free_port()
        a, b = node(A, port), node(B, port)
        await a.start()
        await b.start()
        rng = random.Random(3794)
        noise = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        noise.bind(("127.0.0.4", 0))
        bad = 0
        try:
            for i in range(200):
                b.send(msg(B, A, i.to_bytes(2, "little")))
                junk = rng.choice((
                    rng.randbytes(rng.randrange(0, 40)),
                    b"\x02" + rng.randbytes(rng.randrange(1, 30)),
                    pack_datagram([msg(C, A)])[:-1],  # truncated
                    b"\x01" + bytes(20),  # AS5669 v1 header
                ))
                try:
                    unpack_datagram(junk)
                except DecodeError:
                    bad += 1
                noise.sendto(junk, ("127.0.0.2", port))
                if i % 20 == 0:
                    await asyncio.sleep(0)
            got = []
            while len(got) < 200:
                d = await asyncio.wait_for(a.delivered.get(), 3)
                if d.packet.source == B:
                    got.append(int.from_bytes(d.packet.payload[2:4], "little"))
            assert got == list(range(200))
            await until(lambda: a.links["udp"].stats().malformed == bad)
            assert bad > 100
        finally:
            noise.close()
            await a.stop()
            await b.stop()

    run(scenario())


def test_close_is_idempotent_and_send_after_close_is_counted() -> None:
    async def scenario() -> None:
        port = free_port()
        link = create_link(f"udp://127.0.0.2:{port}")
        await link.open(lambda *_: None)
        await link.close()
        await link.close()
        link.send([msg(A, B)], ("127.0.0.3", port))
        assert link.stats().drops == {"link closed": 1}
        assert link.stats().state == "closed"

    run(scenario())
