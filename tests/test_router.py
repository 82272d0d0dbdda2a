"""The sans-I/O router (node-manager role), driven with a hand-advanced clock."""

from __future__ import annotations

import pytest

from edge_vis.errors import LocalProtocolError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.transport import AckNak, Broadcast, DataFlags, Packet, Priority
from edge_vis.routing.router import Deliver, DeliveryFailed, Router, RouterConfig, SendPackets

ME = JausAddress(200, 1, 1)
ME2 = JausAddress(200, 1, 2)
ROBOT = JausAddress(126, 1, 199)
OCU = JausAddress(42, 1, 1)
UDP_PEER = ("127.0.0.3", 3794)
RADIO = "/dev/ttyUSB0"


def make_router(**config: float) -> Router:
    router = Router([ME, ME2], config=RouterConfig(**config))  # type: ignore[arg-type]
    router.add_link("udp")
    router.add_link("radio")
    return router


def pkt(src: JausAddress, dst: JausAddress, payload: bytes = b"\x02\x20", seq: int = 1,
        **kw: int) -> Packet:
    return Packet(destination=dst, source=src, payload=payload, sequence=seq, **kw)


def sends(actions: list, link: str | None = None) -> list[SendPackets]:
    return [a for a in actions if isinstance(a, SendPackets) and link in (None, a.link)]


def test_local_delivery_and_learning() -> None:
    router = make_router()
    p = pkt(ROBOT, ME)
    assert router.receive("radio", RADIO, [p], now=0.0) == [Deliver(p, "radio", RADIO)]
    route = router.lookup(ROBOT)
    assert route is not None and (route.link, route.peer) == ("radio", RADIO)


def test_ack_request_is_answered_on_the_arrival_link() -> None:
    router = make_router()
    p = pkt(ROBOT, ME, seq=14, ack_nak=AckNak.REQUEST)
    actions = router.receive("udp", UDP_PEER, [p], now=0.0)
    (ack_send,) = sends(actions)
    assert (ack_send.link, ack_send.peer) == ("udp", UDP_PEER)
    (ack,) = ack_send.packets
    assert (ack.destination, ack.source, ack.sequence, ack.ack_nak, ack.payload) == (
        ROBOT, ME, 14, AckNak.ACK, b"")
    assert Deliver(p, "udp", UDP_PEER) in actions


def test_duplicates_over_redundant_paths_are_delivered_once_and_re_acked() -> None:
    router = make_router()
    p = pkt(ROBOT, ME, seq=7, ack_nak=AckNak.REQUEST)
    first = router.receive("udp", UDP_PEER, [p], now=0.0)
    second = router.receive("radio", RADIO, [p], now=0.1)
    assert sum(isinstance(a, Deliver) for a in first + second) == 1
    assert len(sends(second)) == 1  # our first ACK may have been lost: ACK again
    assert router.stats().counters["dropped: duplicate"] == 1
    # outside the window the same numbers are a new message (sequence numbers wrap)
    third = router.receive("udp", UDP_PEER, [p], now=5.0)
    assert any(isinstance(a, Deliver) for a in third)


def test_relay_is_off_by_default_and_switchable_per_link_pair() -> None:
    router = make_router()
    router.receive("radio", RADIO, [pkt(ROBOT, OCU, seq=1)], now=0.0)  # learn ROBOT@radio
    to_robot = pkt(OCU, ROBOT, seq=5)
    assert sends(router.receive("udp", UDP_PEER, [to_robot], now=0.1)) == []
    assert router.stats().counters["dropped: relay off"] == 1
    router.set_relay("udp", "radio")
    actions = router.receive("udp", UDP_PEER, [pkt(OCU, ROBOT, seq=6)], now=0.2)
    assert sends(actions) == [SendPackets("radio", RADIO, (pkt(OCU, ROBOT, seq=6),))]
    # and the reply finds its way back to the OCU's UDP address
    reply = pkt(ROBOT, OCU, seq=2)
    assert sends(router.receive("radio", RADIO, [reply], now=0.3)) == [
        SendPackets("udp", UDP_PEER, (reply,))]


def test_broadcast_fans_out_to_other_links_never_back() -> None:
    router = make_router()
    router.add_link("lan2")
    router.set_relay("udp", "radio")
    router.set_relay("udp", "lan2")
    b = pkt(OCU, BROADCAST, seq=3, broadcast=Broadcast.GLOBAL)
    actions = router.receive("udp", UDP_PEER, [b], now=0.0)
    assert sorted((s.link, s.peer) for s in sends(actions)) == [("lan2", None), ("radio", None)]
    assert Deliver(b, "udp", UDP_PEER) in actions  # matches our local components too


def test_send_numbers_per_component_from_one() -> None:
    router = make_router()
    router.add_route(ROBOT, "radio", RADIO)
    seqs = []
    for source in (ME, ME, ME2, ME):
        (s,) = sends(router.send(pkt(source, ROBOT, seq=999), now=0.0))
        seqs.append(s.packets[0].sequence)
    assert seqs == [1, 2, 1, 3]


def test_unknown_destination_broadcast_with_ack_request_then_learned_from_the_ack() -> None:
    router = make_router()
    actions = router.send(pkt(ME, ROBOT), now=0.0)
    out = sends(actions)
    assert sorted(s.link for s in out) == ["radio", "udp"] and {s.peer for s in out} == {None}
    sent = out[0].packets[0]
    assert sent.ack_nak == AckNak.REQUEST and sent.broadcast == Broadcast.GLOBAL
    assert sent.destination == ROBOT  # the header keeps the concrete id (JTS)
    ack = Packet(ME, ROBOT, b"", sequence=sent.sequence, ack_nak=AckNak.ACK)
    assert router.receive("radio", RADIO, [ack], now=0.05) == []  # never delivered up
    assert router.lookup(ROBOT).link == "radio"  # type: ignore[union-attr]
    assert router.on_timer(1.0) == [] and router.stats().pending_acks == 0
    (unicast,) = sends(router.send(pkt(ME, ROBOT), now=1.1))
    assert (unicast.link, unicast.peer) == ("radio", RADIO)


def test_ack_retries_then_delivery_failed() -> None:
    router = make_router()
    router.add_route(ROBOT, "radio", RADIO)
    router.send(pkt(ME, ROBOT), now=0.0, ack=True)
    resent: list[SendPackets] = []
    now = 0.0
    failures: list[DeliveryFailed] = []
    while router.stats().pending_acks:
        now = router.next_deadline()  # type: ignore[assignment]
        assert now is not None
        actions = router.on_timer(now)
        resent += sends(actions)
        failures += [a for a in actions if isinstance(a, DeliveryFailed)]
    assert len(resent) == 3  # JTS: 3 retries, 100 ms apart
    assert now == pytest.approx(0.4)
    assert len(failures) == 1 and "after 4 attempts" in failures[0].reason
    assert router.stats().pending_acks == 0


def test_priority_queue_sends_highest_first_and_drops_lowest_first() -> None:
    router = Router([ME])
    # 8000 bit/s = 1000 bytes/s; a 40-byte payload costs 40 + 14 + 29 = 83 bytes
    router.add_link("slow", bandwidth_bps=8000, queue_limit=500)
    router.add_route(ROBOT, "slow", "r")
    first = []
    for _i in range(10):
        first += sends(router.send(pkt(ME, ROBOT, b"\x00" * 40, priority=Priority.LOW),
                               now=0.0))
    burst = sum(len(s.packets) for s in first)
    assert 1 <= burst < 10  # the burst allowance went out at once, the rest waits
    router.send(pkt(ME, ROBOT, b"\x01" * 40, priority=Priority.HIGH), now=0.0)
    stats = router.stats()
    assert stats.links["slow"].queued_bytes <= 500
    assert stats.counters.get("dropped: queue full (priority 0)", 0) >= 1
    deadline = router.next_deadline()
    assert deadline is not None and deadline > 0.0
    (nxt,) = sends(router.on_timer(deadline + 0.001))
    assert nxt.packets[0].priority == Priority.HIGH  # jumps the low-priority backlog


def test_busy_link_holds_packets_until_ready() -> None:
    router = Router([ME])
    router.add_link("udp")
    router.add_route(ROBOT, "udp", UDP_PEER)
    router.set_busy("udp", True, now=0.0)
    assert sends(router.send(pkt(ME, ROBOT), now=0.0)) == []
    assert router.stats().links["udp"].depth == 1
    released = sends(router.set_busy("udp", False, now=0.1))
    assert len(released) == 1 and router.stats().links["udp"].depth == 0


def test_stale_peers_expire() -> None:
    router = make_router(peer_timeout=10.0)
    router.receive("udp", UDP_PEER, [pkt(ROBOT, ME)], now=0.0)
    router.on_timer(5.0)
    assert router.lookup(ROBOT) is not None
    router.on_timer(11.0)
    assert router.lookup(ROBOT) is None


def test_static_wildcard_routes_most_specific_wins() -> None:
    router = make_router()
    router.add_route(JausAddress.parse("126.*.*"), "udp", UDP_PEER)
    router.add_route(JausAddress.parse("126.1.*"), "radio", RADIO)
    assert router.lookup(ROBOT).link == "radio"  # type: ignore[union-attr]
    assert router.lookup(JausAddress(126, 2, 1)).link == "udp"  # type: ignore[union-attr]
    router.receive("udp", ("127.0.0.9", 3794), [pkt(ROBOT, ME)], now=0.0)
    assert router.lookup(ROBOT).peer == ("127.0.0.9", 3794)  # type: ignore[union-attr]


def test_large_message_fragmented_to_mtu_and_reassembled() -> None:
    sender = Router([ME])
    sender.add_link("radio", mtu=100)
    sender.add_route(ROBOT, "radio", RADIO)
    payload = bytes(range(256)) * 3
    (out,) = sends(sender.send(pkt(ME, ROBOT, payload), now=0.0))
    assert len(out.packets) == 8
    assert [p.data_flags for p in out.packets][:2] == [DataFlags.FIRST, DataFlags.MIDDLE]
    assert out.packets[-1].data_flags == DataFlags.LAST
    assert [p.sequence for p in out.packets] == list(range(1, 9))
    receiver = Router([ROBOT])
    receiver.add_link("radio")
    delivered = [a for a in receiver.receive("radio", "x", list(reversed(out.packets)), 0.0)
                 if isinstance(a, Deliver)]
    assert len(delivered) == 1 and delivered[0].packet.payload == payload
    # the counter moved past the fragments
    (nxt,) = sends(sender.send(pkt(ME, ROBOT), now=0.1))
    assert nxt.packets[0].sequence == 9


def test_broadcast_larger_than_mtu_is_refused() -> None:
    router = Router([ME])
    router.add_link("radio", mtu=50)
    with pytest.raises(LocalProtocolError, match="broadcast"):
        router.send(pkt(ME, BROADCAST, b"\x00" * 80), now=0.0)


def test_send_from_a_foreign_component_is_refused() -> None:
    with pytest.raises(LocalProtocolError, match="not a local component"):
        make_router().send(pkt(OCU, ROBOT), now=0.0)


def test_own_packets_looping_back_are_dropped() -> None:
    router = make_router()
    assert router.receive("udp", UDP_PEER, [pkt(ME, BROADCAST)], now=0.0) == []
    assert router.stats().counters["dropped: own source"] == 1


def test_local_to_local_is_delivered_without_a_link() -> None:
    router = make_router()
    (d,) = router.send(pkt(ME, ME2), now=0.0)
    assert isinstance(d, Deliver) and d.link is None and d.packet.sequence == 1


def test_duplicate_table_is_rebuilt_after_a_burst_and_still_catches_duplicates() -> None:
    router = make_router(duplicate_window=2.0)
    router.set_relay("udp", "radio")
    router.add_route(ROBOT, "radio", RADIO)
    burst = [pkt(OCU, ROBOT, payload=b"\x05\x04" + i.to_bytes(4, "little"), seq=i & 0xFFFF)
             for i in range(20_000)]
    forwarded = sends(router.receive("udp", UDP_PEER, burst, now=0.0), "radio")
    assert sum(len(s.packets) for s in forwarded) == 20_000
    assert router.compactions == 0
    router.on_timer(1.0)  # the burst is still within the duplicate window
    assert router.compactions == 0
    late = pkt(OCU, ROBOT, payload=b"\x05\x04late", seq=3)
    router.receive("udp", UDP_PEER, [late], now=2.5)
    for step in range(1, 40):  # sweeps until the burst's entries are forgotten
        router.on_timer(2.5 + step * 0.05)
    assert router.compactions == 1
    # the rebuilt table still knows the packet seen after the burst ...
    assert sends(router.receive("udp", UDP_PEER, [late], now=4.0)) == []
    assert router.counters["dropped: duplicate"] == 1
    # ... and has forgotten the burst itself (window over): a repeat is forwarded again
    assert sends(router.receive("udp", UDP_PEER, [burst[0]], now=4.0), "radio")


def test_a_new_static_route_replaces_a_remembered_match() -> None:
    router = make_router()
    router.add_route(JausAddress(126, 0xFF, 0xFF), "radio", RADIO)
    route = router.lookup(ROBOT)
    assert route is not None and route.link == "radio"
    router.add_route(ROBOT, "udp", UDP_PEER)  # more specific: wins from now on
    route = router.lookup(ROBOT)
    assert route is not None and (route.link, route.peer) == ("udp", UDP_PEER)
    router.remove_link("udp")
    route = router.lookup(ROBOT)
    assert route is not None and route.link == "radio"


def test_urgent_jumps_paced_full_and_busy_queues_and_is_never_dropped() -> None:
    router = Router([ME])
    router.add_link("slow", bandwidth_bps=2400, queue_limit=500)
    router.add_route(ROBOT, "slow", RADIO)
    for i in range(40):  # 40 x 50 bytes of telemetry: paced, over the limit
        router.send(pkt(ME, ROBOT, bytes([i]) * 50, priority=Priority.LOW), now=0.0)
    assert router.stats().counters.get("dropped: queue full (priority 0)", 0) > 0
    depth = router.stats().links["slow"].depth
    stop = pkt(ME, ROBOT, b"\x06\x00\x01\x00", priority=Priority.SAFETY_CRITICAL)
    (out,) = sends(router.send(stop, now=0.0, urgent=True))  # no budget left: still now
    assert out.urgent and out.packets[0].payload == stop.payload
    assert router.stats().links["slow"].depth == depth  # nothing else left with it
    # its bytes count against the budget: the next telemetry waits longer
    deadline = router.next_deadline()
    assert deadline is not None and deadline > 0.1
    router.set_busy("slow", True, now=0.0)
    (out,) = sends(router.send(stop, now=0.01, urgent=True))  # a busy link too
    assert out.urgent
    assert router.stats().counters["sent urgently"] == 2
    assert not [k for k in router.stats().counters if "dropped" in k and "priority 3" in k]


def test_urgent_on_an_unpaced_link_goes_out_flagged() -> None:
    router = make_router()
    router.add_route(ROBOT, "udp", UDP_PEER)
    (plain,) = sends(router.send(pkt(ME, ROBOT), now=0.0))
    (urgent,) = sends(router.send(pkt(ME, ROBOT), now=0.0, urgent=True))
    assert not plain.urgent and urgent.urgent and urgent.peer == UDP_PEER


# -- batches: several packets of one stream in one receive call (a link's read cycle) -------
def test_a_batch_of_one_stream_is_forwarded_in_order_and_duplicates_in_it_dropped() -> None:
    router = make_router()
    router.set_relay("udp", "radio")
    router.add_route(ROBOT, "radio", RADIO)
    stream = [pkt(OCU, ROBOT, seq=s, payload=b"\x05\x04" + bytes([s])) for s in range(1, 6)]
    batch = [*stream[:3], stream[2], *stream[3:], stream[0]]  # two radio retries in it
    (out,) = sends(router.receive("udp", UDP_PEER, batch, now=0.0))
    assert (out.link, out.peer) == ("radio", RADIO)
    assert [p.sequence for p in out.packets] == [1, 2, 3, 4, 5]
    assert router.counters["dropped: duplicate"] == 2
    assert sends(router.receive("udp", UDP_PEER, stream, now=0.5)) == []  # all seen
    assert router.counters["dropped: duplicate"] == 7
    (again,) = sends(router.receive("udp", UDP_PEER, stream, now=3.0))  # window passed
    assert [p.sequence for p in again.packets] == [1, 2, 3, 4, 5]
    assert router.stats().counters["forwarded"] == 10


def test_a_route_learned_inside_a_batch_applies_to_the_rest_of_it() -> None:
    router = make_router()
    router.set_relay("udp", "radio")
    router.receive("radio", RADIO, [pkt(ROBOT, OCU, seq=1)], now=0.0)  # ROBOT: radio
    # in one read: a command to ROBOT, then ROBOT itself heard on the UDP side (it moved
    # networks), then the next command: that one must not go to the radio any more
    batch = [pkt(OCU, ROBOT, seq=1), pkt(ROBOT, OCU, seq=2), pkt(OCU, ROBOT, seq=3)]
    (out,) = sends(router.receive("udp", UDP_PEER, batch, now=0.1))
    assert out.link == "radio" and [p.sequence for p in out.packets] == [1]
    route = router.lookup(ROBOT)
    assert route is not None and (route.link, route.peer) == ("udp", UDP_PEER)
    assert router.counters["dropped: destination on arrival link"] == 2


def test_a_batch_within_a_paced_links_budget_leaves_at_once_and_is_charged() -> None:
    router = Router([ME])
    # 80,000 bit/s: a 500-byte burst allowance; each packet costs 6 + 14 + 29 = 49 bytes
    router.add_link("radio", bandwidth_bps=80_000)
    router.add_link("lan")
    router.set_relay("lan", "radio")
    router.add_route(ROBOT, "radio", RADIO)
    batch = [pkt(OCU, ROBOT, seq=s, payload=b"\x05\x04" + bytes(4)) for s in range(1, 9)]
    (out,) = sends(router.receive("lan", UDP_PEER, batch, now=0.0))
    assert [p.sequence for p in out.packets] == list(range(1, 9))
    # the budget paid for them: the next batch (the allowance spent) waits in the queue
    more = [pkt(OCU, ROBOT, seq=s, payload=b"\x05\x04" + bytes(4)) for s in range(9, 17)]
    (rest,) = sends(router.receive("lan", UDP_PEER, more, now=0.0))
    assert 0 < len(rest.packets) < 8
    assert router.stats().links["radio"].queued_bytes == 49 * (8 - len(rest.packets))
