"""``edge-vis demo --duration``: simulator, relay and monitor as real processes on loopback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from edge_vis.cli.demo import relay_links
from edge_vis.tools.sim.profile import load_profile

ROOT = Path(__file__).resolve().parents[1]


def test_relay_links_reach_every_fleet_vehicle() -> None:
    links = relay_links(load_profile(ROOT / "profiles" / "sim" / "fleet.toml"))
    assert links == [
        "udp://127.0.0.10:3794?peers=127.0.0.11:3794,127.0.0.12:3794",
        "serial:///tmp/edge-vis-sim/uuv-delta?baud=57600",
    ]


@pytest.mark.slow
@pytest.mark.dds
@pytest.mark.serial
def test_demo_runs_unattended_and_reports_what_dds_showed(tmp_path: Path) -> None:
    pytest.importorskip("cyclonedds")
    domain = 140 + os.getpid() % 40
    # the shipped fleet on addresses and a pty link of this test's own, so a demo someone
    # runs on the same host at the same time does not interfere
    fleet = tmp_path / "fleet.toml"
    fleet.write_text((ROOT / "profiles" / "sim" / "fleet.toml").read_text()
                     .replace("127.0.0.11:", "127.0.0.121:")
                     .replace("127.0.0.12:", "127.0.0.122:")
                     .replace("/tmp/edge-vis-sim/", f"{tmp_path}/pty-"))
    logs = tmp_path / "logs"
    done = subprocess.run(
        [sys.executable, "-m", "edge_vis", "demo", "--duration", "20", "--json",
         "--domain", str(domain), "--log-dir", str(logs), "--fleet", str(fleet),
         "--relay-address", "127.0.0.120:3794"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr + done.stdout
    summary = json.loads(done.stdout[done.stdout.index("{"):])
    assert summary["vehicles_seen"] == 3
    vehicles = summary["vehicles"]
    assert {v["name"] for v in vehicles.values()} == {"ugv-alpha", "ugv-bravo", "uuv-delta"}
    topics = summary["samples_per_topic"]
    # 5 Hz pose from three vehicles for well over 10 s
    assert topics["GlobalPose"] > 3 * 5 * 10
    assert topics["EnvironmentalData"] > 5  # the UUV on the serial line
    assert topics.get("ImageProduct", 0) >= 1  # its ATR notice
    delivered = summary["commands_delivered"]
    assert "control ugv-alpha-101" in delivered and "drive ugv-alpha-101" in delivered
    # ugv-bravo drops out 8 s after start for 5 s and comes back rebooted
    bravo = vehicles["ugv-bravo-102"]
    assert bravo["dropouts"] == 1 and bravo["recovered"] == 1
    assert summary["faults_recovered"] >= 1
    assert set(summary["exit_codes"].values()) == {0}
    for name in ("sim", "relay", "monitor"):
        assert (logs / f"{name}.log").exists()
    assert "ugv-alpha-101" in (logs / "monitor.log").read_text()
    assert "peers=127.0.0.121:3794,127.0.0.122:3794" in done.stdout
