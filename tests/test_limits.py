"""Every table that grows with what the network sends has a bound and a counter.

Each test floods one structure (10,000 distinct source ids, malformed floods, endless
partial frames) and checks that its size stays within the bound, that the counter says
how often the bound was hit, and that legitimate traffic arriving afterwards still works.
"""

from __future__ import annotations

import asyncio
import random
import socket
from typing import Any

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.config import from_mapping
from edge_vis.engine.engine import Engine
from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import Reassembler
from edge_vis.jaus.transport import DataFlags, Packet
from edge_vis.kit.actions import SendMessage
from edge_vis.plugins import LINKS, load
from edge_vis.routing.link import MAX_TRACKED_PEERS
from edge_vis.routing.router import Deliver, Router, RouterConfig

RELAY = JausAddress(200, 1, 1)
FLOOD = 10_000
#: first fragments of 1 kB into a 256 kB reassembler: 39 times what it may hold, so the
#: byte cap is hit some 9,700 times
REASSEMBLY_FLOOD = FLOOD


def _payload(code: int = 0x4202, body: bytes = b"\x00" * 8) -> bytes:
    return code.to_bytes(2, "little") + body


def _stranger(i: int) -> JausAddress:
    """The ``i``-th distinct address, never the relay's own subsystem (200)."""
    return JausAddress(1000 + i % 60000, 1 + (i // 60000), 1)


# -- router: address book and duplicate table ------------------------------------------------


def test_router_address_book_is_bounded_and_keeps_learning() -> None:
    router = Router([RELAY], config=RouterConfig(max_routes=500))
    router.add_link("lan")
    for i in range(FLOOD):
        router.receive("lan", ("10.0.0.1", 40000 + i % 20000),
                       [Packet(RELAY, _stranger(i), _payload())], now=0.001 * i)
    stats = router.stats()
    assert stats.routes <= 500
    assert stats.counters["routes forgotten: table full"] == FLOOD - 500
    # a vehicle heard after the flood is routable at once
    vehicle = JausAddress(65000, 1, 1)
    router.receive("lan", ("127.0.0.9", 3794), [Packet(RELAY, vehicle, _payload())], now=20.0)
    route = router.lookup(vehicle)
    assert route is not None and route.peer == ("127.0.0.9", 3794)


def test_router_duplicate_table_is_bounded_and_counted() -> None:
    router = Router([RELAY], config=RouterConfig(max_duplicates=1000))
    router.add_link("lan")
    delivered = 0
    for i in range(FLOOD):  # all within one duplicate window
        packet = Packet(RELAY, JausAddress(7, 1, 1), _payload(body=i.to_bytes(4, "little")),
                        sequence=i % 65536)
        delivered += sum(isinstance(a, Deliver)
                         for a in router.receive("lan", ("10.0.0.2", 3794), [packet], 1.0))
    assert delivered == FLOOD  # distinct packets are never taken for duplicates
    assert len(router._seen) <= 1000  # the table has no public size
    assert router.stats().counters["duplicate table full"] == FLOOD - 1000
    # after the window the table drains and duplicates are caught again
    router.on_timer(10.0)
    router.on_timer(10.02)
    again = Packet(RELAY, JausAddress(7, 1, 1), _payload(body=b"\x01"), sequence=1)
    router.receive("lan", ("10.0.0.2", 3794), [again], 10.1)
    assert not router.receive("lan", ("10.0.0.2", 3794), [again], 10.2)
    assert router.stats().counters["dropped: duplicate"] == 1


# -- reassembly -------------------------------------------------------------------------------


def test_reassembler_holds_at_most_its_byte_bound_under_a_first_fragment_flood() -> None:
    reassembler = Reassembler(max_bytes=256 * 1024, timeout=5.0)
    chunk = _payload(body=b"\xAA" * 1000)
    for i in range(REASSEMBLY_FLOOD):
        reassembler.feed(Packet(RELAY, _stranger(i), chunk, data_flags=DataFlags.FIRST,
                                sequence=1), now=0.0001 * i)
        assert reassembler.bytes_held <= 256 * 1024
    assert reassembler.stats.dropped_byte_cap > REASSEMBLY_FLOOD - 300
    # a whole large message from a real vehicle still goes through
    vehicle = JausAddress(9, 1, 1)
    parts = [(DataFlags.FIRST, b"\x01" * 900), (DataFlags.MIDDLE, b"\x02" * 900),
             (DataFlags.LAST, b"\x03" * 100)]
    whole = None
    for n, (flags, data) in enumerate(parts):
        whole = reassembler.feed(Packet(RELAY, vehicle, _payload(body=data) if n == 0 else data,
                                        data_flags=flags, sequence=100 + n), now=1.0)
    assert whole is not None and len(whole.payload) == 2 + 1900
    assert reassembler.expire(10.0) >= 1
    assert reassembler.bytes_held == 0


# -- serial deframer ------------------------------------------------------------------------


def test_serial_deframer_buffer_is_bounded_under_noise_and_endless_frames() -> None:
    deframer = jserial.SerialDeframer(max_frame=4096)
    rng = random.Random(1)
    errors = 0
    # a start marker and a header announcing a huge frame, then endless bytes
    endless = b"\x10\x01" + bytes([0x02, 0xFF, 0xFF]) + b"\x55" * 100
    for i in range(2000):
        data = endless if i % 10 == 0 else rng.randbytes(rng.randrange(1, 600))
        items = deframer.feed(data, now=i * 0.001)
        errors += sum(isinstance(x, jserial.SerialError) for x in items)
        assert deframer.buffered <= 4096 + 600
    assert errors > 0
    # a valid frame right after the noise is decoded
    packet = Packet(RELAY, JausAddress(5, 1, 1), _payload(), sequence=3)
    items = deframer.feed(b"\x10\x04" * 0 + jserial.frame(packet), now=10.0)
    frames = [x for x in items if isinstance(x, jserial.SerialFrame)]
    assert frames and frames[-1].packet.payload == packet.payload


# -- engine: vehicle table and identification probes ------------------------------------------


def _engine(**limits: int) -> Engine:
    profile = from_mapping({"relay": {"jaus_id": str(RELAY)}, "limits": limits,
                            "translators": {"enabled": ["core"]}}, file="limits.toml")
    return Engine(profile, catalogue=default_catalogue())


def test_engine_vehicle_table_is_bounded() -> None:
    catalogue = default_catalogue()
    engine = _engine(max_vehicles=50)
    ident = catalogue.decode(catalogue.encode("ReportIdentification", {
        "query_type": 2, "type": 10001, "identification": "Spoof"}))
    for i in range(FLOOD):
        engine.receive_message(_stranger(i), ident, now=0.001 * i)
        engine.drain_actions()
    assert len(engine.vehicles) == 50
    assert engine.counters["vehicles_refused_table_full"] == FLOOD - 50


def test_engine_probes_of_strangers_are_bounded() -> None:
    """Messages from unknown subsystems make the relay ask who they are; a flood of
    distinct strangers must not make it send (or remember) one query each."""
    catalogue = default_catalogue()
    engine = _engine(max_unidentified=100)
    status = catalogue.decode(catalogue.encode("ReportStatus", {"status": 0, "reserved": 0}))
    queries = 0
    for i in range(FLOOD):
        engine.receive_message(_stranger(i), status, now=0.0001 * i)
        queries += sum(isinstance(a, SendMessage) and a.name == "QueryIdentification"
                       and not a.destination.is_broadcast for a in engine.drain_actions())
    assert queries <= 100
    assert len(engine._probed) <= 100  # the table under test
    assert engine.counters["probes_skipped_table_full"] == FLOOD - 100
    # once the probes expire, a new stranger is asked again
    engine.receive_message(JausAddress(65001, 1, 1), status, now=100.0)
    assert any(isinstance(a, SendMessage) and a.name == "QueryIdentification"
               and a.destination.subsystem == 65001 for a in engine.drain_actions())


# -- the UDP link: peer tables and malformed floods -------------------------------------------


def test_udp_link_peer_tables_are_bounded_and_malformed_floods_counted() -> None:
    async def main() -> dict[str, Any]:
        cls = load(LINKS, "udp")
        link = cls("udp://127.0.0.190:0", name="lan")
        got: list[Any] = []
        await link.open(lambda name, peer, packets: got.extend(packets),
                        lambda *a: None)
        port = link.local_address[1] if hasattr(link, "local_address") else None
        if port is None:
            port = link._transport.get_extra_info("sockname")[1]
        target = ("127.0.0.190", port)
        rng = random.Random(3)
        sockets = []
        try:
            for _ in range(MAX_TRACKED_PEERS + 60):  # more distinct peers than tracked
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                s.bind(("127.0.0.191", 0))
                sockets.append(s)
            sent = 0
            for _round in range(8):
                for s in sockets:
                    s.sendto(bytes((rng.choice((0, 2, 7)),)) + rng.randbytes(
                        rng.randrange(0, 40)), target)
                    sent += 1
                await asyncio.sleep(0.05)
            valid = Packet(RELAY, JausAddress(5, 1, 1), _payload(), sequence=9)
            from edge_vis.jaus.transport import pack_datagram
            sockets[0].sendto(pack_datagram([valid]), target)
            for _ in range(100):
                if got:
                    break
                await asyncio.sleep(0.02)
            stats = link.stats()
            return {"stats": stats, "sent": sent, "got": got,
                    "learned": len(getattr(link, "_learned", {}))}
        finally:
            for s in sockets:
                s.close()
            await link.close()

    out = asyncio.run(main())
    stats = out["stats"]
    assert len(stats.peers) <= MAX_TRACKED_PEERS
    assert out["learned"] <= 256
    # the evictions are counted, so a flood of sources shows in LinkStatus
    assert stats.drops.get("peer counters forgotten: table full", 0) >= 60
    # every datagram either decoded or was counted as malformed: none vanished
    assert stats.malformed >= out["sent"] - 50  # a few may still sit in the socket
    assert out["got"], "a valid datagram after the flood was not delivered"



@pytest.mark.parametrize("key,value", [("max_vehicles", 0), ("max_routes", -1)])
def test_limits_are_checked_in_the_profile(key: str, value: int) -> None:
    from edge_vis.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        from_mapping({"limits": {key: value}}, file="x.toml")
    assert (("x.toml", f"limits.{key}", f"must be at least 1, got {value}")
            in err.value.problems)


def test_link_drop_reasons_are_a_small_vocabulary() -> None:
    """The drop counters (published in LinkStatus) must not grow with random input."""
    from edge_vis.jaus.transport import unpack_datagram
    from edge_vis.routing.link import Link

    class Probe(Link):
        scheme = "probe"

        async def _open(self) -> None: ...
        async def _close(self) -> None: ...
        def _send(self, *args: Any) -> None: ...

    link = Probe("probe://x", name="p")
    rng = random.Random(9)
    for _ in range(FLOOD):
        data = bytes((2,)) + rng.randbytes(rng.randrange(0, 40))
        try:
            unpack_datagram(data)
        except Exception as exc:  # the reason is what is under test
            link._malformed(None, str(exc), data)
    assert len(link.stats().drops) < 64, len(link.stats().drops)


# -- DDS bridge: samples handed to the event loop ----------------------------------------------


@pytest.mark.dds
def test_dds_bridge_hands_over_a_bounded_number_of_batches(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A relay whose loop is stuck must not pile up every incoming sample in the loop's
    queue: the delivery thread stops at MAX_IN_FLIGHT batches and counts the wait."""
    import time
    import uuid

    dds = pytest.importorskip("edge_vis.dds")
    from edge_vis.dds import bridge as bridge_module

    monkeypatch.setenv("CYCLONEDDS_URI", dds.loopback_config())
    domain, partition = 170 + int(time.time()) % 10, f"limits-{uuid.uuid4().hex[:8]}"
    loop = asyncio.new_event_loop()  # never run until the end: a stuck relay
    delivered: list[str] = []
    relay = dds.DdsBridge(domain, (partition,))
    operator = dds.DdsBridge(domain, (partition,))
    try:
        relay.subscribe(["ControlRequest"], lambda topic, s: delivered.append(s["vehicle_id"]),
                        loop=loop)
        operator.open_writers(["ControlRequest"])
        time.sleep(0.5)  # discovery
        for i in range(3000):
            operator.publish("ControlRequest", {"vehicle_id": f"v{i}", "operator_id": "op",
                                                "authority": 1, "action": "request"})
            if i % 20 == 0:
                time.sleep(0.002)  # let the delivery thread take small batches
        time.sleep(0.5)
        queued = len(loop._ready)  # the loop's pending callbacks (no public size)
        assert queued <= bridge_module.MAX_IN_FLIGHT
        assert relay.counters["handover_waits"] > 0
        # once the loop runs again, delivery resumes
        loop.run_until_complete(asyncio.sleep(0.5))
        assert delivered
    finally:
        relay.close()
        operator.close()
        loop.close()


@pytest.mark.dds
def test_dds_image_products_kept_for_late_joiners_are_bounded(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Image products are transient-local keep-all: without a bound every still image a
    vehicle ever reported stays in the relay's memory. The newest are kept, the oldest
    disposed, and a station joining late gets only the newest."""
    import time
    import uuid

    dds = pytest.importorskip("edge_vis.dds")
    monkeypatch.setenv("CYCLONEDDS_URI", dds.loopback_config())
    domain, partition = 180 + int(time.time()) % 10, f"limits-{uuid.uuid4().hex[:8]}"
    relay = dds.DdsBridge(domain, (partition,), max_products=5)
    try:
        relay.open_writers(["ImageProduct"])
        for i in range(40):
            relay.publish("ImageProduct", {"vehicle_id": "uuv1", "image_id": f"img-{i}",
                                           "file_name": f"img-{i}.png", "size_bytes": 10,
                                           "sha256": "0" * 64})
        assert relay.counters["products_retired"] == 35
        late = dds.DdsBridge(domain, (partition,))
        try:
            reader = late.reader("ImageProduct")
            got = reader.collect(10, 2.0)
            assert sorted(s["image_id"] for s in got) == [f"img-{i}" for i in range(35, 40)]
        finally:
            late.close()
    finally:
        relay.close()
