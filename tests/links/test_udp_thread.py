"""A UDP link with ``thread=1``: it reads, routes and forwards on a thread of its own,
sharing the relay's lock with the event loop. Real sockets on loopback, real ptys."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Awaitable
from typing import TypeVar

import pytest
from linkkit import Pty, free_port, msg, until

from edge_vis.errors import ConfigError, LinkError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import SerialDeframer, SerialError, SerialFrame
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.routing.link import check_link_url, create_link
from edge_vis.routing.router import Router
from edge_vis.shell import sharedloop
from edge_vis.tools.testing import RouterNode
from links.udp import UdpLink

RELAY = JausAddress(200, 1, 1)
OPERATOR = JausAddress(42, 1, 1)
VEHICLE = JausAddress(126, 1, 199)
HOST, SENDER, SINK = "127.0.0.2", "127.0.0.3", "127.0.0.4"
T = TypeVar("T")


def run(coro: Awaitable[T], timeout: float = 15.0) -> T:
    """Run a test coroutine on the relay's event loop (the one link threads need)."""

    async def guarded() -> T:
        return await asyncio.wait_for(coro, timeout)

    return sharedloop.run(guarded())


def telemetry(seq: int) -> Packet:
    return msg(OPERATOR, VEHICLE, seq.to_bytes(4, "little"), code=0x4402, sequence=seq)


def udp(host: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    sock.setblocking(False)
    return sock


def link_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("edge-vis link")]


class Serial:
    """The vehicle's end of a pty radio: the frames the relay wrote, in order."""

    def __init__(self, pty: Pty) -> None:
        self.pty = pty
        self.deframer = SerialDeframer()
        self.frames: list[Packet] = []
        self.errors: list[SerialError] = []

    def read(self) -> int:
        for item in self.deframer.feed(self.pty.read()):
            if isinstance(item, SerialFrame):
                self.frames.append(item.packet)
            else:
                self.errors.append(item)
        return len(self.frames)


def test_thread_is_validated_like_every_option() -> None:
    assert check_link_url("udp://127.0.0.1:3794?thread=1&cycle=0.01").thread  # type: ignore[attr-defined]
    assert not create_link("udp://127.0.0.1:3794").threaded  # type: ignore[attr-defined]
    with pytest.raises(ConfigError) as info:
        check_link_url("udp://127.0.0.1:3794?thread=sometimes")
    assert "thread" in str(info.value)


def test_a_plain_asyncio_loop_is_refused_with_a_clear_error() -> None:
    async def scenario() -> None:
        link = UdpLink(f"udp://{HOST}:{free_port()}?thread=1", name="lan")
        with pytest.raises(LinkError, match="thread=1 needs the relay's event loop"):
            await link.open(lambda *_: None)

    asyncio.run(scenario())
    assert not link_threads()


async def relay_to_radio(cycle: float, baud: int = 20_000_000, pace: int = 0
                         ) -> tuple[RouterNode, int, Serial]:
    port = free_port()
    pty = Pty()
    node = RouterNode(Router([RELAY]), [
        create_link(f"udp://{HOST}:{port}?cycle={cycle}&thread=1&multicast=off", name="lan"),
        create_link(f"serial://{pty.path}?baud={baud}&pace={pace}", name="radio"),
    ])
    await node.start()
    node.router.set_relay("lan", "radio")
    node.router.add_route(VEHICLE, "radio", pty.path)
    return node, port, Serial(pty)


def test_forwards_a_stream_in_order_nothing_lost_from_its_own_thread() -> None:
    async def scenario() -> None:
        node, port, radio = await relay_to_radio(cycle=0.1)
        loop_thread = threading.get_ident()
        callers: set[int] = set()
        send = node.links["radio"].send

        def watched(packets: object, peer: object = None) -> None:
            callers.add(threading.get_ident())
            send(packets, peer)  # type: ignore[arg-type]

        node.links["radio"].send = watched  # type: ignore[method-assign]
        tx = udp(SENDER)
        try:
            for seq in range(1, 301):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
                if seq % 10 == 0:
                    await asyncio.sleep(0.003)
            await until(lambda: radio.read() == 300, timeout=5.0)
            assert [p.sequence for p in radio.frames] == list(range(1, 301))
            assert [p.payload for p in radio.frames] == [telemetry(s).payload
                                                         for s in range(1, 301)]
            assert callers and loop_thread not in callers  # forwarded by the link thread
            assert node.router.counters["forwarded"] == 300
            assert node.links["lan"].stats().messages_in == 300
            assert node.links["radio"].stats().messages_out == 300
            # quiet, then a lone datagram: read at once, not a cycle (0.1 s) later
            await asyncio.sleep(0.25)
            start = time.monotonic()
            tx.sendto(pack_datagram([telemetry(1000)]), (HOST, port))
            while radio.read() < 301 and time.monotonic() - start < 1.0:
                await asyncio.sleep(0.001)
            assert time.monotonic() - start < 0.05
        finally:
            tx.close()
            await node.stop()
            radio.pty.close()

    run(scenario())
    assert not link_threads()


def test_duplicates_are_dropped_and_traffic_for_the_relay_reaches_the_loop() -> None:
    async def scenario() -> None:
        port, sink = free_port(), udp(SINK)
        node = RouterNode(Router([RELAY]), [
            create_link(f"udp://{HOST}:{port}?cycle=0.03&thread=1&multicast=off", name="lan"),
            create_link(f"udp://{HOST}:0?multicast=off", name="out"),
        ])
        await node.start()
        node.router.set_relay("lan", "out")
        node.router.add_route(VEHICLE, "out", sink.getsockname())
        tx = udp(SENDER)
        try:
            tx.sendto(pack_datagram([telemetry(1)]), (HOST, port))  # starts the cycle
            copy = pack_datagram([telemetry(2)])
            for _ in range(3):  # the original and two copies in one cycle
                tx.sendto(copy, (HOST, port))
            await asyncio.sleep(0.05)
            tx.sendto(copy, (HOST, port))  # and one a cycle later
            tx.sendto(pack_datagram([msg(OPERATOR, RELAY, b"\x07", code=0x4402,
                                         sequence=9)]), (HOST, port))
            delivered = await asyncio.wait_for(node.delivered.get(), 2.0)
            assert delivered.packet.sequence == 9 and delivered.link == "lan"
            await until(lambda: node.router.counters["dropped: duplicate"] == 3)
            await asyncio.sleep(0.05)
            got = []
            while True:
                try:
                    got += unpack_datagram(sink.recv(65535))
                except BlockingIOError:
                    break
            assert [p.sequence for p in got] == [1, 2]
        finally:
            tx.close()
            sink.close()
            await node.stop()

    run(scenario())


def test_an_emergency_stop_leaves_first_on_a_paced_radio() -> None:
    """The link thread fills a 9,600 baud radio's queue with telemetry; an emergency stop
    the relay sends meanwhile (on the loop) is written before every queued frame, and the
    telemetry follows in order, none lost. A stop from the network read in a cycle with
    telemetry also goes ahead of it (priority 3 leaves the router's queues first)."""

    async def scenario() -> None:
        node, port, radio = await relay_to_radio(cycle=0.05, baud=9600, pace=1)
        tx = udp(SENDER)
        try:
            tx.sendto(pack_datagram([telemetry(1)]), (HOST, port))
            await until(lambda: radio.read() == 1)
            for seq in range(2, 42):  # 40 telemetry frames: seconds of a 9,600 baud radio
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
            await until(lambda: node.links["lan"].stats().messages_in == 41)
            stop = msg(RELAY, VEHICLE, b"\x01", code=0x0006, priority=3)
            handed = node.links["radio"].stats().messages_out  # the rest waits in queues
            assert handed < 30
            node.send(stop, urgent=True)
            remote = msg(OPERATOR, VEHICLE, b"\x01", code=0x0006, priority=3, sequence=99)
            for seq in range(42, 47):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
            tx.sendto(pack_datagram([remote]), (HOST, port))
            await until(lambda: radio.read() == 48, timeout=8.0)
            codes = [p.message_code for p in radio.frames]
            first_stop = codes.index(0x0006)
            # behind at most what the radio link had taken before it (one frame may be
            # half written), ahead of everything still queued
            assert first_stop <= handed, (codes, handed)
            assert radio.frames[first_stop].source == RELAY
            second = codes.index(0x0006, first_stop + 1)
            assert radio.frames[second].sequence == 99
            # the stop from the network overtook telemetry queued long before it came
            telemetry_at = {p.sequence: i for i, p in enumerate(radio.frames)
                            if p.message_code == 0x4402}
            assert second < telemetry_at[41], codes
            telemetry_seqs = [p.sequence for p in radio.frames if p.message_code == 0x4402]
            assert telemetry_seqs == list(range(1, 47))
            assert node.router.counters["sent urgently"] == 1
        finally:
            tx.close()
            await node.stop()
            radio.pty.close()

    run(scenario(), timeout=20.0)


def test_the_loop_and_the_link_thread_write_one_radio_at_once_without_damage() -> None:
    """The relay sends its own messages (on the loop) to the radio while the link thread
    forwards a stream to it: every frame arrives whole (CRCs good, nothing malformed),
    each stream in its order, none lost."""

    async def scenario() -> None:
        node, port, radio = await relay_to_radio(cycle=0.005)
        tx = udp(SENDER)
        try:
            for seq in range(1, 401):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
                node.send(msg(RELAY, VEHICLE, seq.to_bytes(2, "little"), code=0x0405))
                if seq % 20 == 0:
                    await asyncio.sleep(0.002)
                    radio.read()
            await until(lambda: radio.read() == 800, timeout=5.0)
            forwarded = [p.sequence for p in radio.frames if p.source == OPERATOR]
            own = [int.from_bytes(p.payload[2:], "little") for p in radio.frames
                   if p.source == RELAY]
            assert forwarded == list(range(1, 401))
            assert own == list(range(1, 401))
            assert radio.errors == []
            assert node.links["radio"].stats().drops == {}
        finally:
            tx.close()
            await node.stop()
            radio.pty.close()

    run(scenario())


def test_closing_while_traffic_flows_ends_the_thread_promptly() -> None:
    async def scenario() -> None:
        node, port, radio = await relay_to_radio(cycle=0.1)
        tx = udp(SENDER)
        try:
            assert len(link_threads()) == 1
            for seq in range(1, 50):
                tx.sendto(pack_datagram([telemetry(seq)]), (HOST, port))
            await until(lambda: radio.read() > 0)
            start = time.monotonic()
            await node.stop()
            assert time.monotonic() - start < 0.5
            assert not link_threads()
            lan = node.links["lan"]
            assert lan.state == "closed"
            lan.send([telemetry(100)], (SENDER, 1))
            assert lan.stats().drops["link closed"] == 1
            # the port is free again
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
                again.bind((HOST, port))
        finally:
            tx.close()
            radio.pty.close()

    run(scenario())


def test_the_relay_runtime_handles_a_threaded_link_on_that_thread_under_the_lock() -> None:
    """``edge-vis run``'s runtime with a threaded link: a vehicle's ReportIdentification
    is read, routed and handed to the engine on the link thread, holding the loop's lock
    (nothing else runs meanwhile), and what the engine answers leaves on the link."""
    from edge_vis.catalogue import default_catalogue
    from edge_vis.config import from_mapping
    from edge_vis.shell.relay import Runtime

    catalogue = default_catalogue()
    vehicle = JausAddress(126, 1, 1)
    port = free_port()
    profile = from_mapping({
        "relay": {"jaus_id": str(RELAY)},
        "links": {"lan": {"url": f"udp://{HOST}:{port}?thread=1&cycle=0.01&multicast=off"
                                 f"&peers={SENDER}:{port}"}},
        "translators": {"enabled": ["core"]},
    }, file="thread.toml")

    async def scenario() -> None:
        runtime = Runtime(profile, publisher_factory=None)
        peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        peer.bind((SENDER, port))
        peer.setblocking(False)
        await runtime.start()
        try:
            lan = runtime.links["lan"]
            assert isinstance(lan, UdpLink) and lan._thread is not None
            link_thread = lan._thread.ident
            lock = sharedloop.shared_lock(asyncio.get_running_loop())
            assert lock is not None
            seen: list[tuple[int, bool]] = []
            engine = runtime.engine
            assert engine is not None
            receive = engine.receive_message

            def watched(*args: object, **kw: object) -> None:
                seen.append((threading.get_ident(), lock.locked()))
                receive(*args, **kw)  # type: ignore[arg-type]

            engine.receive_message = watched  # type: ignore[method-assign]
            ident = catalogue.encode("ReportIdentification", {
                "query_type": 2, "type": 10001, "identification": "ugv"})
            peer.sendto(pack_datagram([Packet(RELAY, vehicle, ident)]), (HOST, port))
            await until(lambda: runtime.first_discovery_at is not None)
            assert seen == [(link_thread, True)]
            # the engine asks the new vehicle about itself: out on the link, to the peer
            asked: list[str] = []

            def read() -> bool:
                while True:
                    try:
                        data = peer.recv(65535)
                    except BlockingIOError:
                        return any(a != "QueryIdentification" for a in asked)
                    asked.extend(catalogue.decode(p.payload).name
                                 for p in unpack_datagram(data) if p.destination == vehicle)

            await until(read)
        finally:
            peer.close()
            await runtime.stop()
        assert not link_threads()

    run(scenario())
