"""UDP -> serial through the router's pass-through path against the full path: real UDP
sockets on loopback, a real pty, the same datagrams; the same bytes on the serial line and
the same counters on both links and in the router."""

from __future__ import annotations

import asyncio
import random
import socket
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar

import pytest
from linkkit import Pty, free_port, msg, until

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import frame, frame_parts
from edge_vis.jaus.transport import Packet, encode_packet, pack_datagram
from edge_vis.routing.link import create_link
from edge_vis.routing.router import Router
from edge_vis.shell import sharedloop
from edge_vis.tools.testing import RouterNode

RELAY = JausAddress(200, 1, 1)
OPERATOR = JausAddress(42, 1, 1)
VEHICLE = JausAddress(126, 1, 199)
HOST, SENDER = "127.0.0.2", "127.0.0.3"
T = TypeVar("T")


def run(coro: Awaitable[T], timeout: float = 30.0) -> T:
    async def guarded() -> T:
        return await asyncio.wait_for(coro, timeout)

    return sharedloop.run(guarded())


def traffic(seed: int) -> list[list[bytes]]:
    """Bursts of datagrams: mostly telemetry for the vehicle behind the radio (bodies full
    of DLE bytes, so the framing stuffs), with duplicates, messages for the relay itself,
    ACK requests, several messages in one datagram and garbage among them."""
    rng = random.Random(seed)
    bursts: list[list[bytes]] = []
    seq = 0
    for _ in range(40):
        burst: list[bytes] = []
        for _ in range(rng.randrange(1, 9)):
            seq += 1
            body = bytes(rng.choice([0x10, 0x10, 0x01, 0x03, 0x7E, 0x00])
                         for _ in range(rng.randrange(0, 40)))
            kind = rng.random()
            if kind < 0.75:
                packet = msg(OPERATOR, VEHICLE, body, code=0x0405, sequence=seq)
            elif kind < 0.82:
                packet = msg(OPERATOR, RELAY, body, code=0x2B00, sequence=seq)
            elif kind < 0.88:
                packet = msg(OPERATOR, VEHICLE, body, code=0x0405, sequence=seq, ack_nak=1)
            elif kind < 0.93:
                two = [msg(OPERATOR, VEHICLE, body, code=0x0405, sequence=seq),
                       msg(OPERATOR, VEHICLE, body, code=0x0406, sequence=seq + 1)]
                seq += 1
                burst.append(pack_datagram(two))
                continue
            elif kind < 0.96:
                burst.append(b"\x07garbage" + body)
                continue
            else:
                burst.append(burst[-1] if burst else b"\x02")  # a repeat, or too short
                continue
            burst.append(pack_datagram([packet]))
        bursts.append(burst)
    return bursts


async def send_bursts(node: RouterNode, tx: socket.socket, port: int,
                      bursts: list[list[bytes]], after_each: Callable[[], object]) -> None:
    """The operator heard once first (its route learned, as in a running relay), then
    each burst sent back to back, with ``after_each`` (reading what came out) between."""
    tx.sendto(pack_datagram([msg(OPERATOR, RELAY, b"", sequence=60000)]), (HOST, port))
    await until(lambda: node.router.stats().counters.get("received", 0) >= 1)
    for burst in bursts:
        for datagram in burst:
            tx.sendto(datagram, (HOST, port))
        await asyncio.sleep(0.003)
        after_each()


async def relay_traffic(bursts: list[list[bytes]], url_options: str, pass_through: bool
                        ) -> tuple[bytes, dict[str, Any]]:
    port = free_port((HOST, SENDER))
    pty = Pty()
    node = RouterNode(Router([RELAY]), [
        create_link(f"udp://{HOST}:{port}?multicast=off{url_options}", name="lan"),
        create_link(f"serial://{pty.path}?baud=20000000&pace=0", name="radio"),
    ], pass_through=pass_through)
    taken = [0]
    forward = node.router.forward

    def counting(*args: Any) -> tuple[int, list[Any], bool]:
        result = forward(*args)
        taken[0] += result[0]
        return result

    node.router.forward = counting  # type: ignore[method-assign]
    await node.start()
    node.router.set_relay("lan", "radio")
    node.router.add_route(VEHICLE, "radio", pty.path)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx.bind((SENDER, 0))
    line = bytearray()
    try:
        await send_bursts(node, tx, port, bursts, lambda: line.extend(pty.read()))
        expected = sum(1 for burst in bursts for _ in burst)
        await until(lambda: node.links["lan"].counters.messages_in
                    + node.links["lan"].counters.malformed >= expected - 10, 5.0)
        await asyncio.sleep(0.1)
        while chunk := pty.read():
            line += chunk
        stats = {name: link.stats().as_dict() for name, link in node.links.items()}
        stats["router"] = node.router.stats().counters
        stats["taken"] = taken[0]
    finally:
        tx.close()
        await node.stop()
        pty.close()
    return bytes(line), stats


@pytest.mark.parametrize("options", ["", "&cycle=0.005&thread=1"])
def test_pass_through_writes_the_full_paths_bytes_and_counts(options: str) -> None:
    bursts = traffic(24)
    full_line, full = run(relay_traffic(bursts, options, pass_through=False))
    fast_line, fast = run(relay_traffic(bursts, options, pass_through=True))
    assert full["taken"] == 0
    assert fast["taken"] > 20  # batches of telemetry alone took the pass-through path
    assert fast_line == full_line
    assert len(full_line) > 3000
    for name in ("lan", "radio"):
        for key in ("bytes_in", "bytes_out", "messages_in", "messages_out", "malformed",
                    "drops"):
            assert fast[name][key] == full[name][key], (name, key)
        # per peer (the sender's port differs between the two runs)
        assert list(fast[name]["peers"].values()) == list(full[name]["peers"].values())
    assert fast["router"] == full["router"]


def test_frame_parts_are_frame_byte_for_byte() -> None:
    rng = random.Random(5)
    packets = [Packet(JausAddress(rng.randrange(1, 0xFFFF), rng.randrange(256), 0x10),
                      JausAddress(0x1010, 0x10, rng.randrange(256)),
                      bytes(rng.choice([0x10, 0x01, 0x03, 0xFF]) for _ in range(rng.randrange(60))),
                      sequence=rng.randrange(0x10000), priority=rng.randrange(4))
               for _ in range(3000)]
    parts = frame_parts([encode_packet(p) for p in packets])
    assert b"".join(parts) == b"".join(frame(p) for p in packets)
    assert [b"".join(parts[i:i + 5]) for i in range(0, len(parts), 5)] == list(map(frame, packets))


async def relay_udp(bursts: list[list[bytes]], pass_through: bool
                    ) -> tuple[list[bytes], dict[str, Any]]:
    """The same traffic relayed UDP -> UDP: the datagrams the next hop receives."""
    port = free_port((HOST, SENDER, "127.0.0.4"))
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.4", 0))
    sink.setblocking(False)
    node = RouterNode(Router([RELAY]), [
        create_link(f"udp://{HOST}:{port}?multicast=off", name="lan"),
        create_link(f"udp://127.0.0.4:{port}?multicast=off", name="far"),
    ], pass_through=pass_through)
    await node.start()
    node.router.set_relay("lan", "far")
    node.router.add_route(VEHICLE, "far", sink.getsockname())
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx.bind((SENDER, 0))
    received: list[bytes] = []

    def drain() -> None:
        while True:
            try:
                received.append(sink.recv(65535))
            except BlockingIOError:
                return

    try:
        await send_bursts(node, tx, port, bursts, drain)
        await asyncio.sleep(0.2)
        drain()
        stats = {name: link.stats().as_dict() for name, link in node.links.items()}
        stats["router"] = node.router.stats().counters
    finally:
        tx.close()
        sink.close()
        await node.stop()
    return received, stats


def test_pass_through_to_udp_sends_the_full_paths_datagrams() -> None:
    bursts = traffic(7)
    full_out, full = run(relay_udp(bursts, pass_through=False))
    fast_out, fast = run(relay_udp(bursts, pass_through=True))
    assert len(full_out) > 100
    assert fast_out == full_out
    for name in ("lan", "far"):
        for key in ("bytes_in", "bytes_out", "messages_in", "messages_out", "malformed"):
            assert fast[name][key] == full[name][key], (name, key)
    assert fast["router"] == full["router"]
