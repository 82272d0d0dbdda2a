"""Cells of the fault matrix with several relay processes sharing one DDS domain.

Two (or three) ``edge-vis run`` processes reach one simulated vehicle over their own
radio paths; no profile says anything about the others. Each cell establishes the
normal state - one relay serves the vehicle, holds JAUS control for the operator who
drives at 10 Hz, a plain default-QoS reader sees its poses - then applies the fault and
checks that another relay takes over (events, control for the same operator, commands
obeyed again without a new request) within the bound, that the vehicle never obeyed a
sender without control, and that the plain reader saw one writer at a time.
"""

from __future__ import annotations

import asyncio
import signal
import time
from collections.abc import Awaitable, Callable
from pathlib import Path

import pytest

from .conftest import FaultResult
from .harness import until
from .relay_group import RelayGroup, relay_id

pytestmark = [pytest.mark.dds]

#: the vehicle's control timeout (s): a dead relay's control lapses after it
CONTROL_TIMEOUT = 2
#: lease (1.5 s) + heartbeat (0.25 s) + the control timeout + retries and event set-up
TAKEOVER_BOUND = 1.75 + CONTROL_TIMEOUT + 1.5


def run(group: RelayGroup, body: Callable[[], Awaitable[None]], timeout: float = 75.0) -> None:
    async def main() -> None:
        try:
            await group.start()
            await asyncio.wait_for(body(), timeout)
        except BaseException as exc:
            raise AssertionError(f"{exc}\n{group.log_tail()}") from exc
        finally:
            await group.stop()

    asyncio.run(main())


def agreed(group: RelayGroup) -> bool:
    """Every relay is up and reaches the vehicle, and exactly one says it serves it."""
    relays = [s for s in group.latest("RelayStatus") if not s["leaving"]]
    reach = [v for s in relays for v in s["vehicles"] if v["vehicle_id"] == group.vehicle_id]
    return (len(relays) == group.count and len(reach) == group.count
            and sum(v["serving"] for v in reach) == 1)


async def establish(group: RelayGroup) -> int:
    """Every relay up (a loaded host starts them seconds apart), one serves and drives for
    the operator; returns its index."""
    await until(lambda: bool(group.vehicle_id) and bool(group.serving()), 40,
                "the first GlobalPose and VehicleStatus")
    await until(lambda: agreed(group), 20, "every relay up and reaching the vehicle, one serving")
    group.request()
    group.start_driving()
    await until(lambda: group.commands_obeyed > 5, 15, "commands obeyed through one relay")
    server = group.serving()
    assert group.controllers() == {relay_id(group.index_of(server))}
    return group.index_of(server)


def one_writer(group: RelayGroup, since: float, result: FaultResult) -> None:
    writers = group.writers_since(since)
    assert len(writers) == 1, f"a plain reader saw {len(writers)} writers of one vehicle"
    result.checks.append("1 writer")


def no_command_without_control(group: RelayGroup, result: FaultResult) -> None:
    assert group.commands_ignored == 0, (
        f"the vehicle got {group.commands_ignored} command(s) from a sender without control")
    result.checks.append("0 cmds w/o control")


async def taken_over(group: RelayGroup, old: int, since: float, result: FaultResult,
                     bound: float) -> int:
    """Another relay serves, controls, and the operator's commands are obeyed again."""
    obeyed = group.commands_obeyed
    old_name = str(relay_id(old))
    await until(lambda: group.serving() not in ("", old_name)
                and group.controllers() == {relay_id(group.index_of(group.serving()))}
                and group.commands_obeyed > obeyed + 3, bound + 5,
                "take-over: another relay serves, holds control, commands obeyed")
    took = time.monotonic() - since
    result.recovery_s = took
    assert took <= bound, f"take-over took {took:.1f} s, bound {bound:.1f} s"
    result.checks += ["taken over", "control kept for operator", "commands"]
    return group.index_of(group.serving())


def test_relays_started_together_one_serves(tmp_path: Path, domain_id: int, partition: str,
                                            fault_record: FaultResult) -> None:
    """Three relays started at the same instant, all reaching the vehicle: one serves,
    the others stand by (no events, no control, nothing published for it)."""
    fault_record.fault = "3 relays, same start"
    group = RelayGroup(tmp_path, domain_id, partition, 3)

    async def body() -> None:
        server = await establish(group)
        since = time.monotonic()
        await asyncio.sleep(2.0)
        one_writer(group, since, fault_record)
        assert group.event_subscribers() == {relay_id(server)}, (
            f"events held by {group.event_subscribers()}")
        assert {r for _, r in group.statuses} == {str(relay_id(server))}, \
            "VehicleStatus named another relay"
        fault_record.checks += ["1 server", "standbys: no events/control"]
        names = {str(relay_id(i)) for i in range(3)}
        links = {(s["relay"], s["link"]) for s in group.latest("LinkStatus")}
        assert links == {(name, "radio") for name in names}, "LinkStatus keyed by relay"
        relays = {s["relay"]: s for s in group.latest("RelayStatus")}
        assert set(relays) == names
        for name, status in relays.items():
            (entry,) = status["vehicles"]
            assert entry["vehicle_id"] == group.vehicle_id and entry["quality"] > 0.5
            assert entry["serving"] == (name == str(relay_id(server)))
            assert status["links"] == [{"link": "radio", "up": True}]
        fault_record.checks.append("LinkStatus/RelayStatus per relay")
        no_command_without_control(group, fault_record)

    run(group, body)


def test_serving_relay_sigkill_while_driving(tmp_path: Path, domain_id: int, partition: str,
                                             fault_record: FaultResult) -> None:
    fault_record.fault = "serving relay SIGKILL"
    group = RelayGroup(tmp_path, domain_id, partition, 2, control_timeout=CONTROL_TIMEOUT)

    async def body() -> None:
        server = await establish(group)
        since = time.monotonic()
        group.signal(server, signal.SIGKILL)
        new = await taken_over(group, server, since, fault_record, TAKEOVER_BOUND)
        await asyncio.sleep(1.0)
        steady = time.monotonic()
        await asyncio.sleep(1.0)
        one_writer(group, steady, fault_record)
        assert relay_id(new) in group.event_subscribers()
        no_command_without_control(group, fault_record)

    run(group, body)


def test_serving_relay_sigterm_hands_over(tmp_path: Path, domain_id: int, partition: str,
                                          fault_record: FaultResult) -> None:
    """A planned stop: the relay releases control and says it leaves; the other takes
    over at once, without waiting for a lease or the vehicle's control timeout."""
    fault_record.fault = "serving relay SIGTERM"
    group = RelayGroup(tmp_path, domain_id, partition, 2, control_timeout=CONTROL_TIMEOUT)

    async def body() -> None:
        server = await establish(group)
        since = time.monotonic()
        group.signal(server, signal.SIGTERM)
        await taken_over(group, server, since, fault_record, 1.5)
        gap = max((b - a for (a, _), (b, _) in zip(group.poses, group.poses[1:], strict=False)
                   if a >= since - 1), default=0.0)
        fault_record.checks.append(f"pose gap {gap:.2f} s")
        no_command_without_control(group, fault_record)

    run(group, body)


def test_serving_relay_loses_its_link(tmp_path: Path, domain_id: int, partition: str,
                                      fault_record: FaultResult) -> None:
    """The serving relay's radio path fails while the other relay still reaches the
    vehicle: it hands the vehicle over (its control lapses on the vehicle)."""
    fault_record.fault = "serving relay loses link"
    group = RelayGroup(tmp_path, domain_id, partition, 2, control_timeout=CONTROL_TIMEOUT)

    async def body() -> None:
        server = await establish(group)
        since = time.monotonic()
        group.wires[server].down = True
        # silence timeout 0.75 s + the vehicle's control timeout + retries
        await taken_over(group, server, since, fault_record, TAKEOVER_BOUND)
        no_command_without_control(group, fault_record)

    run(group, body)


def test_emergency_stop_while_serving_relay_dead(tmp_path: Path, domain_id: int,
                                                 partition: str,
                                                 fault_record: FaultResult) -> None:
    """The serving relay died a moment ago and nobody has noticed yet: an emergency stop
    still reaches the vehicle at once, because every relay that reaches it sends one."""
    fault_record.fault = "E-stop, server just died"
    group = RelayGroup(tmp_path, domain_id, partition, 2, control_timeout=CONTROL_TIMEOUT)

    async def body() -> None:
        server = await establish(group)
        group.signal(server, signal.SIGKILL)
        since = time.monotonic()
        group.emergency("SET")
        took = await until(lambda: all(c.state == 5 for c in group.sim.components.values()
                                       if c.state is not None), 2.0,
                           "the vehicle in EMERGENCY")
        fault_record.recovery_s = took
        assert time.monotonic() - since < 1.0, "the stop waited for the take-over"
        fault_record.checks.append(f"stopped in {took:.2f} s")
        no_command_without_control(group, fault_record)

    run(group, body)


def test_emergency_set_and_cleared_through_two_relays(tmp_path: Path, domain_id: int,
                                                      partition: str,
                                                      fault_record: FaultResult) -> None:
    """Both relays set the stop (the one standing by too), so both must clear it: the
    operator's one CLEAR reaches both, and the vehicle leaves EMERGENCY."""
    fault_record.fault = "E-stop set+clear, 2 relays"
    group = RelayGroup(tmp_path, domain_id, partition, 2, control_timeout=CONTROL_TIMEOUT)

    def in_emergency() -> bool:
        return all(c.state == 5 for c in group.sim.components.values() if c.state is not None)

    async def body() -> None:
        await establish(group)
        group.driving = False
        group.emergency("SET")
        await until(in_emergency, 2.0, "the vehicle in EMERGENCY")
        await asyncio.sleep(0.5)  # the relay standing by sets it too
        setters = {s for c in group.sim.components.values() for s in c.emergency_ids}
        assert setters == {relay_id(0), relay_id(1)}, f"set by {setters}"
        group.emergency("CLEAR")
        took = await until(lambda: not in_emergency(), 5.0, "the vehicle out of EMERGENCY")
        fault_record.recovery_s = took
        fault_record.checks.append(f"set by both relays, cleared in {took:.2f} s")
        no_command_without_control(group, fault_record)

    run(group, body)
