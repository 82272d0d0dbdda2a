"""SIGHUP re-reads the profile: what changes at once, what waits, what needs a restart."""

from __future__ import annotations

import asyncio
import dataclasses
import signal
import time
from pathlib import Path

import pytest
from deploykit import NotifyListener, Relay, relay_env
from e2e.peer_sets import SetPeer, pose_peer

from edge_vis.config import LinkProfile, RelayProfile, from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.reload import APPLIED, DEFERRED, RESTART, diff_profiles, effective_profile

RELAY_IP, PEER_IP = "127.0.61.11", "127.0.61.12"
PEER_ID = JausAddress(61, 1, 1)


def profile_text(*, liveness: float, rate: float, bandwidth: int = 0,
                 period: float = 0.5) -> str:
    return f"""
[relay]
jaus_id = "200.1.1"
name = "reload-test"

[links.lan]
url = "udp://{RELAY_IP}:3794?peers={PEER_IP}:3794&multicast=off"
bandwidth = {bandwidth}

[discovery]
period = {period}
liveness_period = {liveness}
lost_after = 5

[report_rates]
ReportGlobalPose = {rate}
"""


# -- the pure comparison ----------------------------------------------------------------


def _profile(**changes: object) -> RelayProfile:
    base = from_mapping({"links": {"radio": {"url": "udp://0.0.0.0:3794"}},
                         "report_rates": {"ReportGlobalPose": 5.0}})
    return dataclasses.replace(base, **changes)


def test_diff_names_each_changed_setting_and_its_fate() -> None:
    old = _profile()
    new = dataclasses.replace(
        old,
        jaus_id=JausAddress(201, 1, 1),
        links=(LinkProfile("radio", "udp://0.0.0.0:3795"), LinkProfile("modem", "loop://m")),
        discovery=dataclasses.replace(old.discovery, period=2.0),
        report_rates={"ReportGlobalPose": 2.0, "ReportVelocityState": 1.0},
    )
    changes = {c.key: c for c in diff_profiles(old, new)}
    assert set(changes) == {"jaus_id", "links.radio.url", "links.modem", "discovery.period",
                            "report_rates.ReportGlobalPose",
                            "report_rates.ReportVelocityState"}
    assert changes["jaus_id"].outcome == RESTART
    assert changes["links.radio.url"].outcome == RESTART
    assert changes["links.radio.url"].describe() == \
        "links.radio.url: 'udp://0.0.0.0:3794' -> 'udp://0.0.0.0:3795'"
    assert changes["discovery.period"].outcome == APPLIED
    assert changes["report_rates.ReportGlobalPose"].outcome == APPLIED
    assert changes["report_rates.ReportGlobalPose"].describe() == \
        "report_rates.ReportGlobalPose: 5.0 -> 2.0"
    without_engine = {c.key: c.outcome for c in diff_profiles(old, new, engine_applies=False)}
    assert without_engine["report_rates.ReportGlobalPose"] == DEFERRED
    assert without_engine["discovery.period"] == APPLIED
    # the running relay keeps its identity and links; everything else is taken
    kept = effective_profile(old, new)
    assert kept.jaus_id == old.jaus_id and kept.links == old.links
    assert kept.discovery.period == 2.0 and kept.report_rates["ReportGlobalPose"] == 2.0


def test_a_relays_preference_reloads_but_not_its_name() -> None:
    old = _profile()
    new = dataclasses.replace(old, serving=dataclasses.replace(
        old.serving, preference=1.0, prefer=("ugv-1",), relay_name="shore"))
    changes = {c.key: c.outcome for c in diff_profiles(old, new)}
    assert changes == {"serving.preference": APPLIED, "serving.prefer": APPLIED,
                       "serving.relay_name": RESTART}
    kept = effective_profile(old, new)
    assert kept.serving.preference == 1.0 and kept.serving.prefer == ("ugv-1",)
    assert kept.relay_name == old.relay_name


def test_same_profile_means_no_changes() -> None:
    assert diff_profiles(_profile(), _profile()) == []


# -- a running relay and a real UDP vehicle -----------------------------------------------


async def _count(peer: SetPeer, name: str, seconds: float) -> int:
    start = len(peer.names(name))
    await asyncio.sleep(seconds)
    return len(peer.names(name)) - start


async def _until(check, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.05)


def test_sighup_applies_new_timing_without_dropping_the_vehicle(
    notify_socket: NotifyListener, tmp_path: Path
) -> None:
    profile = tmp_path / "relay.toml"
    profile.write_text(profile_text(liveness=1.0, rate=2.0))

    async def main() -> None:
        loop = asyncio.get_running_loop()
        peer = pose_peer(PEER_ID, "ReloadBot")
        await loop.create_datagram_endpoint(lambda: peer, local_addr=(PEER_IP, 3794))
        relay = Relay(["run", "--no-dds", "--profile", str(profile)], tmp_path / "relay.log",
                      relay_env(NOTIFY_SOCKET=notify_socket.path, WATCHDOG_USEC="2000000"))
        try:
            await _until(lambda: peer.names("CreateEvent"), 10, "the relay's CreateEvent")
            first_rate = peer.names("CreateEvent")[0].fields["requested_periodic_rate"]
            assert first_rate == pytest.approx(2.0, rel=0.01)  # a scaled field on the wire
            slow = await _count(peer, "QueryHeartbeatPulse", 2.0)

            profile.write_text(profile_text(liveness=0.2, rate=8.0, bandwidth=9600))
            mark = len(notify_socket.drain())
            relay.signal(signal.SIGHUP)
            await _until(lambda: any("RELOADING" in n.fields
                                     for n in notify_socket.drain()[mark:]), 5, "RELOADING=1")
            await _until(lambda: any("READY" in n.fields for n in notify_socket.drain()[mark:]),
                         5, "READY=1 after the reload")
            ready = next(n for n in notify_socket.messages[mark:] if "READY" in n.fields)
            assert ready.fields["STATUS"] == \
                "1 vehicle(s), 1 online; links 1/1 up; restart needed for links"
            fast = await _count(peer, "QueryHeartbeatPulse", 2.0)
            assert slow <= 3 and fast >= 6, (slow, fast)

            # a profile with a mistake changes nothing; the relay runs on
            profile.write_text(profile_text(liveness=0.2, rate=8.0, period=-1.0))
            relay.signal(signal.SIGHUP)
            await _until(lambda: "keeping the running profile" in relay.log(), 5,
                         "the refused reload")
            assert await _count(peer, "QueryHeartbeatPulse", 1.0) >= 3
            assert relay.proc.poll() is None
        finally:
            stop_requested = time.monotonic()
            code = await asyncio.to_thread(relay.stop)  # the peer answers the goodbyes
            peer.close()
        log = relay.log()
        assert code == 0, log
        # the vehicle was never dropped: discovered once, never lost, events kept
        assert log.count("discovered") == 1, log
        assert " lost" not in log
        assert len(peer.names("QueryServices")) <= 2
        assert "reload: applied discovery.liveness_period: 1.0 -> 0.2" in log
        assert "needs a restart: links.lan.bandwidth: 0 -> 9600" in log
        assert "discovery.period: must be a positive number, got -1.0" in log
        assert "reload: applied report_rates.ReportGlobalPose: 2.0 -> 8.0" in log
        # the running event was updated in place: asked again at the new rate, never
        # cancelled
        rates = [round(r.fields["requested_periodic_rate"], 1)
                 for r in peer.names("CreateEvent")
                 if r.fields["query_message"][:2] == b"\x02\x24"]  # QueryGlobalPose
        assert rates[0] == 2.0 and rates[-1] == 8.0, rates
        assert not [r for r in peer.names("CancelEvent") if r.at < stop_requested]

    asyncio.run(main())


def test_subscription_set_rate_updates_an_active_event_and_retimes_polling() -> None:
    from edge_vis.config import EventsProfile
    from edge_vis.engine.subscriptions import Subscription, SubscriptionState

    ids = iter(range(1, 100))
    sub = Subscription(PEER_ID, "ReportGlobalPose", "QueryGlobalPose", {}, 2.0, False,
                       EventsProfile(), lambda name, fields: b"\x02\x24", lambda: next(ids))
    sub.start(0.0)
    sub.on_confirm(event_id=4, rate=2.0, now=0.1)
    [request] = sub.set_rate(8.0, 1.0)
    assert request.name == "CreateEvent"
    assert request.fields["requested_periodic_rate"] == 8.0
    assert sub.state is SubscriptionState.ACTIVE and sub.event_id == 4  # never dropped
    sub.on_confirm(event_id=4, rate=8.0, now=1.1)
    assert sub.confirmed_rate == 8.0

    sub.on_reject(code=1, now=2.0)  # the provider will not do events: polled
    assert sub.state is SubscriptionState.POLLING
    assert sub.set_rate(0.5, 2.0) == []
    assert sub.next_deadline() == 4.0
