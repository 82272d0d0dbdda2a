"""The fault matrix: one simulated vehicle, the relay and an operator, over UDP and serial.

Each cell establishes the normal state first - the vehicle discovered, the pose event
active on both sides, the relay holding JAUS control on behalf of an operator who drives
at 10 Hz - then injects one fault and checks what must hold afterwards (rediscovered,
events and control re-established, commands obeyed again, no command obeyed from a
sender without control) and how long recovery took. The table is printed at the end of
the run (see ``conftest.py``). Timers are scaled down as ``harness`` explains.
"""

from __future__ import annotations

import asyncio
import random
import time
from collections.abc import Awaitable, Callable

import pytest

from edge_vis.tools.sim.profile import FaultSpec

from .conftest import FaultResult
from .harness import Rig, until

pytestmark = [pytest.mark.dds]

MEDIA = [pytest.param("udp"), pytest.param("serial", marks=pytest.mark.serial)]


def run(rig: Rig, body: Callable[[], Awaitable[None]], result: FaultResult, *,
        operator: bool = True, timeout: float = 25.0) -> None:
    async def main() -> None:
        try:
            await rig.start(operator=operator)
            await asyncio.wait_for(body(), timeout)
            nothing_accepted_lost(rig, result)
        finally:
            await rig.stop()

    asyncio.run(main())


def nothing_accepted_lost(rig: Rig, result: FaultResult) -> None:
    """What the relay took in, it passed on: no queue drops, no publish or send errors.
    Events the wire lost are the wire's (shown as gaps), refused garbage is not a loss."""
    assert rig.runtime is not None
    totals = rig.runtime.totals()
    lost = rig.runtime.losses()
    assert not lost, f"the relay lost what it had accepted: {lost}"
    gaps = totals.get("events missed", 0)
    result.checks.append("0 accepted lost" + (f" ({gaps} Event gaps on the wire)"
                                               if gaps else ""))


async def establish(rig: Rig) -> None:
    """Discovered, pose event active, control held for the operator who drives."""
    await until(lambda: bool(rig.vehicle_id), 10, "the first GlobalPose on DDS")
    rig.start_driving()
    start = time.monotonic()
    await until(lambda: rig.healthy(start) and rig.commands_obeyed > 0, 10,
                "control, events and commands obeyed")


async def recover(rig: Rig, result: FaultResult, since: float, timeout: float = 10.0) -> None:
    """Wait for the full normal state again; record how long it took since ``since``."""
    obeyed = rig.commands_obeyed
    await until(lambda: rig.healthy(since) and rig.commands_obeyed > obeyed, timeout,
                "recovery: online, events, control, poses, commands obeyed")
    result.recovery_s = time.monotonic() - since
    result.checks += ["rediscovered", "events", "control", "commands"]


def no_command_without_control(rig: Rig, result: FaultResult) -> None:
    assert rig.commands_ignored == 0, (
        f"the vehicle got {rig.commands_ignored} command(s) from a sender without control")
    result.checks.append("0 cmds w/o control")


@pytest.mark.parametrize("medium", MEDIA)
@pytest.mark.parametrize("kind,settings", [
    ("loss 20%", {"loss": 0.2}),
    ("duplication 50%", {"duplicate": 0.5}),
    ("reordering 30%", {"reorder": 0.3}),
    ("corruption 10%", {"corrupt": 0.1}),
])
def test_impaired_link(medium: str, kind: str, settings: dict[str, float], domain_id: int,
                       partition: str, fault_record: FaultResult) -> None:
    fault_record.fault = kind
    rig = Rig(medium, domain_id, partition)

    async def body() -> None:
        await establish(rig)
        assert rig.runtime is not None
        router_before = rig.runtime.router.counters["dropped: duplicate"]
        link = rig.runtime.links["radio"]
        malformed_before = link.stats().malformed
        undecodable_before = rig.runtime.counters["undecodable messages"]
        start = time.monotonic()
        rig.wire.both(**settings)
        await asyncio.sleep(2.0)
        rig.wire.both()
        end = time.monotonic()
        during = sum(1 for at, _ in rig.poses if start <= at < end)
        # the pose stream (10 Hz) keeps flowing through the impairment
        assert during >= 8, f"only {during} poses in 2 s of {kind}"
        fault_record.checks.append(f"{during} poses/2s")
        if "duplicate" in settings:
            dropped = rig.runtime.router.counters["dropped: duplicate"] - router_before
            assert dropped > 0, "duplicated packets were not recognised"
            stamps = [s["timestamp_ms"] for at, s in rig.poses if start <= at < end]
            assert len(stamps) == len(set(stamps)), "a duplicated pose reached DDS twice"
            fault_record.checks.append(f"{dropped} dups dropped")
        if "corrupt" in settings:
            bad = (link.stats().malformed - malformed_before
                   + rig.runtime.counters["undecodable messages"] - undecodable_before)
            fault_record.checks.append(f"{rig.wire.counters['corrupted']} corrupted, "
                                       f"{bad} counted bad")
        await recover(rig, fault_record, end)
        if "corrupt" in settings:
            # JUDP carries no checksum (UDP's is checked before a radio modem could flip
            # bits in a user-space bridge like this one): a flipped source address makes
            # the vehicle see a command from a stranger, which it must ignore
            toward_vehicle = rig.wire.counters["corrupted toward vehicle"]
            assert rig.commands_ignored <= toward_vehicle
            fault_record.checks.append(f"{rig.commands_ignored} corrupted cmds ignored")
        else:
            no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


@pytest.mark.parametrize("medium", MEDIA)
def test_link_down_1s(medium: str, domain_id: int, partition: str,
                      fault_record: FaultResult) -> None:
    """A 1 s fade with real-sized timers (silence timeout 1.5 s): nothing is torn down."""
    fault_record.fault = "link down 1 s"
    rig = Rig(medium, domain_id, partition)

    async def body() -> None:
        await establish(rig)
        assert rig.runtime is not None
        rig.wire.down = True
        online_throughout = True
        for _ in range(50):
            await asyncio.sleep(0.02)
            online_throughout &= rig.relay_online()
        rig.wire.down = False
        end = time.monotonic()
        await recover(rig, fault_record, end)
        assert online_throughout, "a 1 s outage made the relay declare the vehicle lost"
        fault_record.checks.append("never lost")
        no_command_without_control(rig, fault_record)

    rig.profile_overrides = {"discovery": {"period": 0.5, "liveness_period": 0.5,
                                           "lost_after": 3, "response_timeout": 0.5}}
    run(rig, body, fault_record)


@pytest.mark.parametrize("medium", MEDIA)
def test_link_down_30s_scaled(medium: str, domain_id: int, partition: str,
                              fault_record: FaultResult) -> None:
    """30 s outage scaled by 1/10: 3 s, longer than the relay's silence timeout (0.75 s)
    and the vehicle's control timeout (1 s), as 30 s is longer than the real 3 s / 5 s."""
    fault_record.fault = "link down 30 s (scaled to 3 s)"
    rig = Rig(medium, domain_id, partition, control_timeout=1)

    async def body() -> None:
        await establish(rig)
        rig.wire.down = True
        await until(lambda: not rig.relay_online(), 2, "the relay to declare the vehicle lost")
        await until(lambda: not rig.vehicle_controlled(), 3,
                    "the vehicle's control timeout")
        await asyncio.sleep(max(0.0, 3.0 - 1.0))
        rig.wire.down = False
        end = time.monotonic()
        fault_record.checks.append("lost+control timed out")
        await recover(rig, fault_record, end)
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


@pytest.mark.parametrize("medium", MEDIA)
def test_vehicle_reboot(medium: str, domain_id: int, partition: str,
                        fault_record: FaultResult) -> None:
    """The vehicle reboots (silent 1 s): new sequence numbers, its events and control gone."""
    fault_record.fault = "vehicle reboot"
    rig = Rig(medium, domain_id, partition, faults=FaultSpec(
        dropout_every=1000.0, dropout_duration=1.0, dropout_first=3.5, dropout_reboot=True))

    async def body() -> None:
        await establish(rig)
        before = rig.relay_events_on_vehicle()
        await until(lambda: rig.sim.reboots == 1, 8, "the reboot")
        end = time.monotonic()
        await recover(rig, fault_record, end)
        # the relay may re-create its events within one poll of the reboot: compare objects
        after = rig.relay_events_on_vehicle()
        assert before and after and not any(a is b for a in after for b in before), (
            "the relay's events after the reboot are not new ones")
        fault_record.checks.append("seq restarted")
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


@pytest.mark.parametrize("medium", MEDIA)
def test_relay_restart(medium: str, domain_id: int, partition: str,
                       fault_record: FaultResult) -> None:
    """The relay dies without goodbyes and starts again while the vehicle runs."""
    fault_record.fault = "relay crash + restart"
    rig = Rig(medium, domain_id, partition)

    async def body() -> None:
        await establish(rig)
        events_before = rig.vehicle_events()
        await rig.crash_relay()
        await asyncio.sleep(0.5)
        start = time.monotonic()
        await rig.start_relay()
        await recover(rig, fault_record, start)
        # the dead relay's events stay on the vehicle until its event timeout; the new
        # relay creates its own once, it does not pile them up
        await asyncio.sleep(1.0)
        events_after = rig.vehicle_events()
        assert events_after <= 2 * events_before, (
            f"{events_after} events on the vehicle, {events_before} before the crash")
        fault_record.checks.append(f"events on vehicle {events_before}->{events_after}")
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


@pytest.mark.parametrize("medium", MEDIA)
def test_malformed_flood_10x(medium: str, domain_id: int, partition: str,
                             fault_record: FaultResult) -> None:
    """Garbage at ten times the vehicle's valid rate, for 2 s, on the vehicle's side."""
    fault_record.fault = "malformed flood 10x"
    rig = Rig(medium, domain_id, partition)
    rng = random.Random(5)

    def garbage() -> bytes:
        if medium == "serial":  # broken frames and noise: a start marker, then junk
            return b"\x10\x01" + rng.randbytes(rng.randrange(4, 40))
        return bytes((rng.choice((2, 7, 0)),)) + rng.randbytes(rng.randrange(1, 60))

    async def body() -> None:
        await establish(rig)
        assert rig.runtime is not None
        # measure the valid rate toward the relay
        before_units = rig.runtime.links["radio"].stats().messages_in
        t0 = time.monotonic()
        await asyncio.sleep(1.0)
        valid_rate = (rig.runtime.links["radio"].stats().messages_in - before_units) / (
            time.monotonic() - t0)
        poses_before = rig.poses_since(t0)
        link = rig.runtime.links["radio"]
        malformed_before = link.stats().malformed
        obeyed = rig.commands_obeyed
        wire = rig.udp or rig.serial
        assert wire is not None
        sent = 0
        start = time.monotonic()
        while time.monotonic() - start < 2.0:
            for _ in range(max(1, int(valid_rate * 10 * 0.02))):
                wire.inject(garbage())
                sent += 1
            await asyncio.sleep(0.02)
        end = time.monotonic()
        poses_during = sum(1 for at, _ in rig.poses if start <= at < end) / 2.0
        counted = link.stats().malformed - malformed_before
        fault_record.checks.append(f"{sent} bad / {valid_rate * 2:.0f} valid, "
                                   f"{counted} counted")
        assert counted > 0, "the malformed input was not counted"
        assert poses_during >= 0.5 * poses_before, (
            f"poses fell from {poses_before}/s to {poses_during}/s under the flood")
        assert rig.commands_obeyed > obeyed, "commands stopped under the flood"
        fault_record.checks.append(f"poses {poses_before}/s -> {poses_during:.0f}/s")
        await recover(rig, fault_record, end)
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


# -- the DDS side ---------------------------------------------------------------------------


def test_operator_joins_late(domain_id: int, partition: str,
                             fault_record: FaultResult) -> None:
    """A station started after the relay sees the vehicle at once (transient-local state)."""
    fault_record.fault = "operator joins late"
    rig = Rig("udp", domain_id, partition)

    async def body() -> None:
        assert rig.runtime is not None
        await until(lambda: rig.relay_events_active(), 10, "the relay's pose event")
        await asyncio.sleep(0.5)
        rig.open_operator()
        ident = rig._readers["VehicleIdentification"]
        status = rig._readers["VehicleStatus"]
        got: dict[str, list[dict]] = {"ident": [], "status": []}

        def seen() -> bool:
            got["ident"] += ident.take(0.0)
            got["status"] += status.take(0.0)
            return bool(got["ident"]) and any(s["online"] for s in got["status"]) and bool(
                rig.poses)

        fault_record.recovery_s = await until(seen, 5, "identification, status and a pose")
        assert got["ident"][0]["jaus_subsystem"] == rig.endpoint.spec.subsystem
        fault_record.checks += ["identity", "status online", "poses"]
        rig.start_driving()
        await until(lambda: rig.commands_obeyed > 0, 5, "the late operator's commands")
        fault_record.checks.append("commands")
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record, operator=False)


def test_operator_leaves_abruptly(domain_id: int, partition: str,
                                  fault_record: FaultResult) -> None:
    """The controlling station's process dies: the vehicle stops (dead-man) and another
    listed operator can take over with a higher authority."""
    fault_record.fault = "operator leaves abruptly"
    rig = Rig("udp", domain_id, partition)

    async def body() -> None:
        from edge_vis.dds import DdsBridge

        await establish(rig)
        await rig.stop_driving()
        await rig.close_operator_abruptly()  # no release: the participant goes away
        gone = time.monotonic()
        await until(lambda: not rig.driving(), 3, "the dead-man stop")
        fault_record.checks.append(f"stopped after {time.monotonic() - gone:.2f} s")
        other = DdsBridge(rig.domain, (rig.partition,))
        try:
            other.open_writers(["ControlRequest", "WrenchEffortCommand"])
            obeyed = rig.commands_obeyed
            while rig.commands_obeyed == obeyed and time.monotonic() - gone < 8:
                rig.request("op-late", 220, bridge=other)
                rig.drive(30.0, "op-late", bridge=other)
                await asyncio.sleep(0.1)
            assert rig.commands_obeyed > obeyed, "another operator could not take over"
            fault_record.recovery_s = time.monotonic() - gone
            fault_record.checks.append("op-late took over")
            no_command_without_control(rig, fault_record)
        finally:
            other.close()

    run(rig, body, fault_record)


def test_operator_vanishes_mid_drive(domain_id: int, partition: str,
                                     fault_record: FaultResult) -> None:
    """Commands stop mid-drive: the relay sends one stop after the dead-man timeout."""
    fault_record.fault = "operator vanishes mid-drive (dead-man)"
    rig = Rig("udp", domain_id, partition)

    async def body() -> None:
        await establish(rig)
        assert rig.driving()
        await rig.stop_driving()
        took = await until(lambda: not rig.driving(), 3, "the dead-man stop")
        fault_record.recovery_s = took
        # the stop follows the dead-man timeout (0.5 s); generous margin for a busy host
        assert took < 0.5 + 1.5, f"stop after {took:.2f} s, dead-man timeout 0.5 s"
        fault_record.checks.append(f"stopped {took:.2f} s after the last command")
        await asyncio.sleep(0.5)
        assert rig.relay_controlled(), "control was dropped, not just the motion"
        fault_record.checks.append("control kept")
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)


def test_operator_vanishes_mid_drive_emergency(domain_id: int, partition: str,
                                               fault_record: FaultResult) -> None:
    """With ``[emergency] on_operator_lost``, the station's process dying mid-drive sets the
    vehicle's emergency (its DDS writers are gone), well before the dead-man would stop it."""
    fault_record.fault = "operator vanishes, relay-side emergency"
    rig = Rig("udp", domain_id, partition)
    rig.profile_overrides = {"emergency": {"on_operator_lost": True},
                             "commands": {"rate": 10.0, "lifespan": 0.5,
                                          "deadman_timeout": 5.0}}

    async def body() -> None:
        await establish(rig)
        assert rig.driving()
        await rig.stop_driving()
        await rig.close_operator_abruptly()
        took = await until(rig.in_emergency, 3, "the relay-side emergency")
        fault_record.recovery_s = took
        assert not rig.driving(), "the vehicle still moves in EMERGENCY"
        fault_record.checks.append(f"EMERGENCY {took:.2f} s after the station died")
        view = rig.relay_view().view
        assert view.emergency and "vanished" in view.emergency_reason
        fault_record.checks.append("VehicleStatus.emergency set")
        no_command_without_control(rig, fault_record)

    run(rig, body, fault_record)
