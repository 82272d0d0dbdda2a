"""The relay end to end: a real UDP JAUS vehicle, the relay, and real Cyclone DDS."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import time
from collections.abc import Awaitable, Callable

import pytest

from edge_vis.config import LinkProfile, load_default_profile
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .peer_sets import SetPeer, pose_peer

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

RELAY_IP, PEER_IP = "127.0.0.31", "127.0.0.32"
PEER_ID = JausAddress(77, 1, 1)


async def wait_for(check: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.02)


async def with_relay(domain: int, partition: str, *, confirm_events: bool,
                     body: Callable[[Runtime, SetPeer, dds.DdsBridge], Awaitable[None]]) -> None:
    loop = asyncio.get_running_loop()
    peer = pose_peer(PEER_ID, confirm_events=confirm_events)
    await loop.create_datagram_endpoint(lambda: peer, local_addr=(PEER_IP, 3794))
    base = load_default_profile()
    profile = dataclasses.replace(
        base,
        links=(LinkProfile("lan", f"udp://{RELAY_IP}:3794?peers={PEER_IP}:3794"),),
        dds=dataclasses.replace(base.dds, domain=domain, partitions=(partition,)),
        discovery=dataclasses.replace(base.discovery, period=0.5, liveness_period=0.5),
        # unanswered CreateEvents give up after 2 x 1 s (not 2 x 3 s) before polling
        events=dataclasses.replace(base.events, response_timeout=1.0),
        commands=dataclasses.replace(base.commands, rate=5.0, lifespan=2.0,
                                     deadman_timeout=30.0),
        report_rates={"ReportGlobalPose": 10.0},
    )
    runtime = Runtime(profile)
    operator = dds.DdsBridge(domain, (partition,))
    await runtime.start()
    try:
        await body(runtime, peer, operator)
    finally:
        await runtime.stop()
        operator.close()
        peer.close()


def test_pose_reaches_dds_and_commands_need_control(
    domain_id: int, partition: str
) -> None:
    async def body(runtime: Runtime, peer: SetPeer, operator: dds.DdsBridge) -> None:
        poses = operator.reader("GlobalPose")
        idents = operator.reader("VehicleIdentification")
        got = await asyncio.to_thread(poses.collect, 1, 10.0)
        assert got, "no GlobalPose sample reached DDS"
        assert got[0]["latitude"] == pytest.approx(28.5, abs=1e-5)
        assert got[0]["longitude"] == pytest.approx(-81.25, abs=1e-5)
        assert got[0]["altitude"] == pytest.approx(12.5, abs=0.01)
        vehicle_id = got[0]["vehicle_id"]
        ident = await asyncio.to_thread(idents.collect, 1, 5.0)
        assert ident and ident[0]["name"] == "TestBot" and ident[0]["jaus_subsystem"] == 77
        status = await asyncio.to_thread(operator.reader("VehicleStatus").collect, 1, 5.0)
        assert status and status[-1]["link"] == "lan"  # the link the vehicle was heard on
        # The relay asked for events and the peer confirmed them: no fallback polling.
        assert peer.names("CreateEvent")

        # A command from an operator without control is not sent.
        drive = {"vehicle_id": vehicle_id, "operator_id": "op1", "propulsive_linear_x": 40.0}
        for _ in range(5):
            operator.publish("WrenchEffortCommand", drive)
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.3)
        assert not peer.names("SetWrenchEffort")

        # Take control: the relay requests JAUS control, the peer grants it.
        operator.publish("ControlRequest", {"vehicle_id": vehicle_id, "operator_id": "op1",
                                            "authority": 50, "action": "request"})
        await wait_for(lambda: bool(peer.names("RequestControl")), 5, "RequestControl")
        # Now drive hard: 50 commands in one second, the profile allows 5 per second.
        start = time.monotonic()
        while time.monotonic() - start < 1.0:
            operator.publish("WrenchEffortCommand", drive)
            await asyncio.sleep(0.02)
        await wait_for(lambda: bool(peer.names("SetWrenchEffort")), 5, "SetWrenchEffort")
        await asyncio.sleep(0.3)
        sent = peer.names("SetWrenchEffort")
        assert sent[0].fields["propulsive_linear_effort_x"] == pytest.approx(40.0, abs=0.01)
        first_control = peer.names("ConfirmControl") or peer.names("RequestControl")
        assert sent[0].at >= first_control[0].at
        window = [r for r in sent if r.at - sent[0].at <= 1.0]
        assert len(window) <= 6, f"{len(window)} commands in one second, limit 5 Hz"

    asyncio.run(with_relay(domain_id, partition, confirm_events=True, body=body))


def test_vehicle_ignoring_events_is_polled(domain_id: int, partition: str) -> None:
    async def body(runtime: Runtime, peer: SetPeer, operator: dds.DdsBridge) -> None:
        poses = operator.reader("GlobalPose")
        got = await asyncio.to_thread(poses.collect, 3, 15.0)
        assert len(got) >= 3
        assert peer.names("CreateEvent")  # asked, never answered ...
        assert len(peer.names("QueryGlobalPose")) >= 3  # ... so the relay polls

    asyncio.run(with_relay(domain_id, partition, confirm_events=False, body=body))


def test_mirror_writes_every_datagram_to_a_pcap(tmp_path) -> None:
    from edge_vis.catalogue import default_catalogue
    from edge_vis.jaus.pcap import read_udp
    from edge_vis.jaus.transport import unpack_datagram
    from edge_vis.shell.mirror import Mirror

    capture = tmp_path / "relay.pcap"

    async def main() -> None:
        loop = asyncio.get_running_loop()
        peer = pose_peer(JausAddress(78, 1, 1), "MirrorBot")
        await loop.create_datagram_endpoint(lambda: peer, local_addr=("127.0.0.34", 3794))
        base = load_default_profile()
        profile = dataclasses.replace(
            base, links=(LinkProfile("lan", "udp://127.0.0.33:3794?peers=127.0.0.34:3794"),),
            discovery=dataclasses.replace(base.discovery, period=0.5))
        runtime = Runtime(profile, publisher_factory=None, mirror=Mirror(pcap=capture))
        await runtime.start()
        await wait_for(lambda: bool(peer.names("QueryServices")), 10, "discovery")
        await runtime.stop()
        peer.close()

    asyncio.run(main())
    catalogue = default_catalogue()
    names = [catalogue.decode(p.payload).name
             for d in read_udp(capture.read_bytes()) for p in unpack_datagram(d.payload)
             if p.message_code is not None]
    # both directions are in the capture: the relay's queries and the vehicle's answers
    assert "QueryIdentification" in names and "ReportIdentification" in names
    assert "QueryServices" in names and "ReportServices" in names


def test_totals_account_for_every_pose_the_operator_received(
    domain_id: int, partition: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The ``totals:`` line a stopping relay logs matches what an operator counted."""
    counted: list[dict] = []

    async def body(runtime: Runtime, peer: SetPeer, operator: dds.DdsBridge) -> None:
        poses = operator.reader("GlobalPose", depth=64)
        while len(counted) < 10:
            counted.extend(await asyncio.to_thread(poses.take, 1.0))
        with caplog.at_level("INFO", logger="edge_vis.shell.relay"):
            await runtime.stop()
        counted.extend(await asyncio.to_thread(poses.take, 0.5))
        published = runtime.published["GlobalPose"]
        assert published == len(counted)
        assert runtime.totals()["published GlobalPose"] == published
        line = next(r.getMessage() for r in caplog.records if "totals: " in r.getMessage())
        logged = json.loads(line.split("totals: ", 1)[1])
        assert logged["published GlobalPose"] == published
        assert logged["events received"] > 0  # the peer sends its poses as Events
        assert "events missed" not in logged  # loopback: no Event went missing

    asyncio.run(with_relay(domain_id, partition, confirm_events=True, body=body))
