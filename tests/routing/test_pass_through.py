"""The router's pass-through path (``Router.forward``) against its full path
(``Router.receive``): the same traffic, the same decisions, bytes, counters and state."""

from __future__ import annotations

import random
import struct

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, encode_packet, unpack_message
from edge_vis.routing.router import ForwardWires, Router, SendPackets

ME = JausAddress(200, 1, 1)
UDP_PEER = ("127.0.0.3", 3794)
OTHER_PEER = ("127.0.0.5", 3794)
RADIO = "/dev/ttyUSB0"
SOURCES = [JausAddress(42, 1, 1), JausAddress(42, 1, 2), JausAddress(43, 1, 1)]
TARGETS = [JausAddress(126, 1, 199), JausAddress(126, 1, 1), JausAddress(127, 2, 3),
           JausAddress(126, 0xFF, 0xFF), ME, JausAddress(42, 1, 2)]


def make_router(*, bandwidth: float | None = None, queue_limit: int = 32768) -> Router:
    router = Router([ME])
    router.add_link("udp")
    router.add_link("radio", bandwidth_bps=bandwidth, overhead=18, queue_limit=queue_limit,
                    mtu=64)
    router.set_relay("udp", "radio")
    router.add_route(JausAddress(126, 0xFF, 0xFF), "radio", RADIO)
    router.add_route(JausAddress(127, 0xFF, 0xFF), "radio", RADIO)
    return router


def random_wire(rng: random.Random, seq: int, plain: bool) -> bytes:
    """One general transport message as it comes off the wire: ``plain`` telemetry for
    a vehicle behind the radio, or anything (what the full path must handle too)."""
    source = rng.choice(SOURCES)
    dest = TARGETS[0] if plain else rng.choice(TARGETS)
    flags = 1 if plain else rng.choice([1, 0, 2, 3, 1 | 0x10, 1 | 0x30, 1 | 0x40])
    size = rng.choice([2, 6, 12, 40, 60, 64] if plain else [2, 12, 64, 70])
    payload = bytes(rng.choice([0x10, 0x05, 0x44, 0xFF, 0x00]) for _ in range(size))
    wire = encode_packet(Packet(dest, source, payload, sequence=seq & 0xFFFF))
    return wire[:3] + bytes((flags,)) + wire[4:]


def sent_bytes(actions: list) -> list[tuple[str, object, bytes]]:
    """What leaves, message by message, whichever action carries it."""
    out = []
    for action in actions:
        if isinstance(action, SendPackets):
            out += [(action.link, action.peer, encode_packet(p)) for p in action.packets]
        elif isinstance(action, ForwardWires):
            out += [(action.link, action.peer, w) for w in action.wires]
    return out


def through_full_path(router: Router, peer: object, wires: list[bytes], now: float) -> list:
    packets = [p for w in wires for p in unpack_message(w)]
    return sent_bytes(router.receive("udp", peer, packets, now))


def through_pass_through(router: Router, peer: object, wires: list[bytes], now: float
                         ) -> tuple[list, int]:
    taken, actions, _ = router.forward("udp", peer, wires, now)
    rest = [p for w in wires[taken:] for p in unpack_message(w)]
    if rest:
        actions += router.receive("udp", peer, rest, now)
    return sent_bytes(actions), taken


def state_of(router: Router) -> tuple:
    stats = router.stats()
    routes = sorted((str(a), r.link, str(r.peer), r.seen) for a, r in router.routes())
    links = {name: (s.depth, s.queued_bytes, s.sent, s.drops) for name, s in stats.links.items()}
    return dict(stats.counters), links, routes


@pytest.mark.parametrize("bandwidth", [None, 2_000_000.0, 20_000.0])
def test_pass_through_matches_the_full_path_on_random_traffic(bandwidth: float | None) -> None:
    rng = random.Random(2411 + int(bandwidth or 0))
    full, fast = make_router(bandwidth=bandwidth), make_router(bandwidth=bandwidth)
    taken_total = 0
    now = 0.0
    for step in range(600):
        now += rng.choice([0.001, 0.005, 0.02, 0.5])
        if step % 50 == 25:  # the address book changes under the cache
            full.add_route(JausAddress(127, 2, 3), "udp", OTHER_PEER)
            fast.add_route(JausAddress(127, 2, 3), "udp", OTHER_PEER)
        peer = UDP_PEER if rng.random() < 0.9 else OTHER_PEER
        plain = rng.random() < 0.7
        wires = [random_wire(rng, rng.randrange(200), plain or rng.random() < 0.7)
                 for _ in range(rng.randrange(1, 12))]
        if rng.random() < 0.2:  # a repeat of a datagram already seen: a duplicate
            wires.insert(rng.randrange(len(wires) + 1), wires[0])
        expected = through_full_path(full, peer, wires, now)
        got, taken = through_pass_through(fast, peer, wires, now)
        taken_total += taken
        assert got == expected, f"step {step}"
        assert state_of(fast) == state_of(full), f"step {step}"
        if step % 40 == 0:
            assert sent_bytes(fast.on_timer(now)) == sent_bytes(full.on_timer(now))
    assert taken_total > 1000  # the pass-through path did carry much of it


def test_a_stream_that_only_passes_through_is_taken_whole_and_byte_for_byte() -> None:
    router = make_router()
    source, dest = SOURCES[0], TARGETS[0]
    wires = [encode_packet(Packet(dest, source, b"\x02\x44" + bytes([i]), sequence=i))
             for i in range(1, 9)]
    # the first packet of a new source teaches its route: the full path takes it
    assert router.forward("udp", UDP_PEER, wires[:1], 1.0)[0] == 0
    router.receive("udp", UDP_PEER, unpack_message(wires[0]), 1.0)
    taken, actions, queued = router.forward("udp", UDP_PEER, wires[1:], 1.01)
    assert (taken, queued) == (7, False)
    assert actions == [ForwardWires("radio", RADIO, tuple(wires[1:]))]
    assert router.stats().counters["forwarded"] == 8
    # the same bytes again within the window are duplicates: left to the full path
    assert router.forward("udp", UDP_PEER, wires[1:3], 1.02)[0] == 0
    assert router.receive("udp", UDP_PEER, unpack_message(wires[1]), 1.02) == []
    assert router.stats().counters["dropped: duplicate"] == 1


def test_what_changes_a_decision_sends_the_stream_back_to_the_full_path() -> None:
    router = make_router()
    source, dest = SOURCES[0], TARGETS[0]

    def wire(seq: int) -> bytes:
        return encode_packet(Packet(dest, source, b"\x02\x44", sequence=seq))

    router.receive("udp", UDP_PEER, unpack_message(wire(1)), 1.0)
    assert router.forward("udp", UDP_PEER, [wire(2)], 1.0)[0] == 1
    router.set_relay("udp", "radio", False)  # relay switched off: nothing may pass
    assert router.forward("udp", UDP_PEER, [wire(3)], 1.0)[0] == 0
    router.set_relay("udp", "radio")
    assert router.forward("udp", UDP_PEER, [wire(4)], 1.0)[0] == 1
    router.add_local(dest)  # now ours: delivered up, not forwarded
    assert router.forward("udp", UDP_PEER, [wire(5)], 1.0)[0] == 0
    router.remove_local(dest)
    # the source moved to another peer: the full path learns it first
    assert router.forward("udp", OTHER_PEER, [wire(6)], 1.0)[0] == 0
    router.receive("udp", OTHER_PEER, unpack_message(wire(6)), 1.0)
    assert router.forward("udp", UDP_PEER, [wire(7)], 1.0)[0] == 0
    assert router.forward("udp", OTHER_PEER, [wire(8)], 1.0)[0] == 1
    # an ACK request or a malformed message is never the pass-through path's
    ack = bytearray(wire(9))
    ack[3] |= 0x10
    assert router.forward("udp", OTHER_PEER, [bytes(ack)], 1.0)[0] == 0
    short = wire(10)
    bad = short[:1] + struct.pack("<H", len(short) + 3) + short[3:]
    assert router.forward("udp", OTHER_PEER, [bad, short], 1.0)[0] == 0
    assert router.forward("udp", OTHER_PEER, [short[:8]], 1.0)[0] == 0


def test_a_busy_or_paced_link_gets_the_queues_decision() -> None:
    router = make_router(bandwidth=8_000.0)  # 1,000 bytes/s, a 64-byte burst
    source, dest = SOURCES[0], TARGETS[0]
    wires = [encode_packet(Packet(dest, source, b"\x02\x44" + bytes(30), sequence=i))
             for i in range(1, 6)]
    router.receive("udp", UDP_PEER, unpack_message(wires[0]), 1.0)
    taken, actions, queued = router.forward("udp", UDP_PEER, wires[1:], 1.0)
    assert taken == 4 and queued  # over the budget: queued, as the full path would
    now = [w for _, _, w in sent_bytes(actions)]
    assert len(now) < 4 and router.stats().links["radio"].depth == 4 - len(now)
    later = [w for t in (2.0, 3.0, 4.0, 5.0) for _, _, w in sent_bytes(router.on_timer(t))]
    assert now + later == wires[1:]
