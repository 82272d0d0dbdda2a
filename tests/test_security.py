"""Who may command: the profile's operator allowlist, from TOML to the vehicle.

The end-to-end test runs a simulated vehicle over real UDP, the relay and real Cyclone
DDS on loopback: an operator missing from the list, or asking above its maximum
authority, is refused, the refusal is published in ``ControlStatus`` and logged, and the
vehicle never hears a RequestControl or a command on its behalf.
"""

from __future__ import annotations

import asyncio
import logging
import time
import uuid
from pathlib import Path

import pytest

from edge_vis.config import from_mapping, load_profile
from edge_vis.config.operators import OperatorPolicy
from edge_vis.errors import ConfigError

# -- the policy --------------------------------------------------------------------------------


def test_listed_operator_within_its_maximum_is_allowed() -> None:
    policy = OperatorPolicy({"op1": 150, "op2": 50})
    assert policy.refusal("op1", 150) == ""
    assert policy.refusal("op2", 10) == ""


def test_above_maximum_and_unlisted_are_refused_with_the_reason() -> None:
    policy = OperatorPolicy({"op1": 150})
    assert policy.refusal("op1", 151) == "op1 refused: authority 151 above its maximum 150"
    assert policy.refusal("intruder", 1) == "intruder refused: not in the profile's [[operators]]"
    assert policy.refusal("", 1) == "control request without an operator_id refused"


def test_empty_list_refuses_everyone_unless_opened_explicitly() -> None:
    closed = OperatorPolicy()
    assert closed.closed
    assert "allows no operator" in closed.refusal("op1", 0)
    opened = OperatorPolicy({"op1": 10}, any_operator=True)
    assert opened.refusal("anyone", 255) == ""
    assert opened.refusal("op1", 11) != ""  # a listed operator keeps its own maximum


# -- the profile -------------------------------------------------------------------------------


def test_profile_file_without_operators_fails_closed(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    path.write_text('[relay]\njaus_id = "200.1.1"\n')
    assert load_profile(path).operators.closed
    path.write_text('[relay]\njaus_id = "200.1.1"\n[access]\nany_operator = true\n')
    assert not load_profile(path).operators.closed


def test_profile_lists_operators_with_maximum_authority(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    path.write_text('[[operators]]\nid = "op1"\nmax_authority = 150\n\n'
                    '[[operators]]\nid = "op2"\n')
    policy = load_profile(path).operators
    assert dict(policy.operators) == {"op1": 150, "op2": 255}
    assert not policy.any_operator


def test_bad_operator_entries_are_reported_with_their_path() -> None:
    with pytest.raises(ConfigError) as err:
        from_mapping({"operators": [{"id": "op1", "max_authority": 300},
                                    {"id": "op1"}, {"max_authority": 5},
                                    {"id": "op3", "authority": 5}, "op4"],
                      "access": {"any_operator": "yes"}}, file="site.toml")
    problems = err.value.problems
    assert ("site.toml", "operators[0].max_authority", "must be in 0..255, got 300") in problems
    assert ("site.toml", "operators[1].id", "duplicate operator id 'op1'") in problems
    assert ("site.toml", "operators[2].id", "missing: every operator needs an id") in problems
    assert ("site.toml", "operators[3].authority", "unknown key") in problems
    assert ("site.toml", "operators[4]", "expected a table {id, max_authority}") in problems
    assert ("site.toml", "access.any_operator", "expected bool, got str 'yes'") in problems


def test_shipped_profiles_say_explicitly_that_anyone_may_command() -> None:
    root = Path(__file__).resolve().parents[1]
    for name in ("profiles/default.toml", "profiles/demo.toml", "edge_vis/data/default.toml"):
        text = (root / name).read_text()
        assert "any_operator = true" in text, name


# -- end to end ---------------------------------------------------------------------------------


@pytest.mark.dds
def test_refused_operators_never_reach_the_vehicle(monkeypatch: pytest.MonkeyPatch,
                                                    caplog: pytest.LogCaptureFixture) -> None:
    dds = pytest.importorskip("edge_vis.dds")
    from edge_vis.shell.relay import Runtime
    from edge_vis.tools.sim.profile import VehicleSpec
    from edge_vis.tools.sim.runner import UdpVehicle

    monkeypatch.setenv("CYCLONEDDS_URI", dds.loopback_config())
    domain, partition = 180 + int(time.time()) % 40, f"edge-vis-sec-{uuid.uuid4().hex[:8]}"
    relay_ip, vehicle_ip = "127.0.0.198", "127.0.0.199"
    profile = from_mapping({
        "relay": {"jaus_id": "200.1.1", "authority": 150},
        "links": {"lan": {"url": f"udp://{relay_ip}:3794?peers={vehicle_ip}:3794"}},
        "dds": {"domain": domain, "partitions": [partition]},
        "translators": {"enabled": ["core", "mobility"]},
        "operators": [{"id": "op1", "max_authority": 100}],
        "discovery": {"period": 0.5, "liveness_period": 0.5},
        "report_rates": {"ReportGlobalPose": 10.0},
    }, file="secure.toml")
    assert not profile.operators.any_operator

    async def main() -> None:
        vehicle = UdpVehicle(VehicleSpec("ugv-sec", 131, f"udp://{vehicle_ip}:3794",
                                         init_time=0.1))
        await vehicle.start()
        runtime = Runtime(profile)
        await runtime.start()
        operator = dds.DdsBridge(domain, (partition,))
        try:
            operator.open_writers(["ControlRequest", "WrenchEffortCommand"])
            poses = operator.reader("GlobalPose")
            control = operator.reader("ControlStatus")
            got = await asyncio.to_thread(poses.collect, 1, 10.0)
            assert got, "no pose reached DDS"
            vid = got[0]["vehicle_id"]

            async def attempt(op: str, authority: int) -> dict:
                for _ in range(10):
                    operator.publish("ControlRequest", {"vehicle_id": vid, "operator_id": op,
                                                        "authority": authority,
                                                        "action": "request"})
                    await asyncio.sleep(0.05)
                await asyncio.sleep(0.5)
                samples = await asyncio.to_thread(control.take, 1.0)
                status = samples[-1]
                for _ in range(10):  # then it drives as if it had control
                    operator.publish("WrenchEffortCommand", {
                        "vehicle_id": vid, "operator_id": op, "propulsive_linear_x": 50.0})
                    await asyncio.sleep(0.05)
                return status

            status = await attempt("intruder", 50)
            assert status["operator_id"] == "" and status["state"] == "NOT_CONTROLLED"
            assert "intruder refused: not in the profile's [[operators]]" in (
                status["last_rejection"])
            status = await attempt("op1", 101)
            assert status["operator_id"] == ""
            assert status["last_rejection"] == "op1 refused: authority 101 above its maximum 100"
            sim = vehicle.vehicle
            assert sim is not None
            assert all(c.controller is None for c in sim.components.values())
            assert sim.counters["commands_obeyed"] == 0
            assert sim.counters["commands_ignored"] == 0  # nothing was even sent
            assert runtime.engine is not None
            assert runtime.engine.counters["control_requests_refused"] >= 20

            # the listed operator within its maximum gets control and drives
            for _ in range(40):
                operator.publish("ControlRequest", {"vehicle_id": vid, "operator_id": "op1",
                                                    "authority": 100, "action": "request"})
                operator.publish("WrenchEffortCommand", {
                    "vehicle_id": vid, "operator_id": "op1", "propulsive_linear_x": 50.0})
                await asyncio.sleep(0.1)
                if sim.counters["commands_obeyed"]:
                    break
            assert sim.counters["commands_obeyed"] > 0
        finally:
            operator.close()
            await runtime.stop()
            await vehicle.stop()

    with caplog.at_level(logging.WARNING, logger="edge_vis.engine.engine"):
        asyncio.run(main())
    refusals = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert any("intruder refused" in m for m in refusals)
    assert any("op1 refused: authority 101" in m for m in refusals)
    # logged once per distinct refusal, not once per request
    assert len(refusals) <= 6
