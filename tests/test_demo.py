"""``edge-vis demo``: free addresses, paths and domain; the demo as real processes on loopback."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import tomllib
import uuid
from pathlib import Path

import pytest

from edge_vis.cli import demo, main
from edge_vis.config import load_profile as load_relay_profile
from edge_vis.tools.demo_place import (
    Placement,
    claim,
    dds_domain_free,
    dds_ports,
    dump_toml,
    fleet_addresses,
    move_fleet,
    move_relay,
    moved_hosts,
    place,
    place_domain,
    relay_addresses,
)
from edge_vis.tools.sim.profile import load_profile, parse_profile

ROOT = Path(__file__).resolve().parents[1]
FLEET = ROOT / "profiles" / "sim" / "fleet.toml"
RELAY = ROOT / "profiles" / "demo.toml"
DEMO = [sys.executable, "-m", "edge_vis", "demo"]
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="claims use Linux abstract sockets")


def test_relay_links_reach_every_fleet_vehicle() -> None:
    links = demo.relay_links(load_profile(FLEET))
    assert links == [
        "udp://127.0.0.10:3794?peers=127.0.0.11:3794,127.0.0.12:3794",
        "serial:///tmp/edge-vis-sim/uuv-delta?baud=57600",
    ]


def test_shipped_profiles_survive_being_written_back() -> None:
    for path in (FLEET, RELAY):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        assert tomllib.loads(dump_toml(data, header="a\n\nb")) == data


def test_the_moved_demo_relay_still_reaches_the_moved_fleet(tmp_path: Path) -> None:
    fleet = tomllib.loads(FLEET.read_text(encoding="utf-8"))
    relay = tomllib.loads(RELAY.read_text(encoding="utf-8"))
    wanted = relay_addresses(relay) + fleet_addresses(fleet)
    assert wanted == [("127.0.0.10", 3794), ("127.0.0.11", 3794), ("127.0.0.12", 3794),
                      ("127.0.0.1", 9100)]  # the UUV's image server (UDT)
    hosts = moved_hosts([host for host, _ in wanted], 3)
    placement = Placement(3, 5, {(h, p): (hosts[h], p) for h, p in wanted})

    moved_fleet, paths = move_fleet(fleet, placement, tmp_path)
    spec = parse_profile(moved_fleet)
    assert [v.link for v in spec.vehicles] == ["udp://127.77.3.11:3794",
                                               "udp://127.77.3.12:3794", "pty"]
    uuv = spec.vehicles[2]
    assert uuv.pty_link == str(tmp_path / "uuv-delta.pty")
    assert Path(uuv.pty_path_file).parent == tmp_path and Path(uuv.atr_dir).parent == tmp_path
    assert uuv.image_server == "127.77.3.1:9100"

    written = tmp_path / "relay.toml"
    written.write_text(dump_toml(move_relay(relay, placement, paths)), encoding="utf-8")
    profile = load_relay_profile(written)  # also checks the link profile is still found
    urls = {link.name: link.url for link in profile.links}
    assert urls == {"lan": "udp://127.77.3.10:3794?peers=127.77.3.11:3794,127.77.3.12:3794",
                    "radio": f"serial://{tmp_path}/uuv-delta.pty?baud=57600"}
    assert next(link for link in profile.links if link.name == "radio").spec is not None
    # JAUS identification says only "VEHICLE": the demo profile names the UGVs' kind
    assert {v.vehicle_id: v.vehicle_type for v in profile.vehicles if v.vehicle_type} == {
        "ugv-alpha-101": "UGV", "ugv-bravo-102": "UGV"}


@linux_only
def test_a_claim_is_held_until_released() -> None:
    name = f"test/{uuid.uuid4().hex}"
    first = claim(name)
    assert first is not None
    assert claim(name) is None
    first.release()
    again = claim(name)
    assert again is not None
    again.release()


@linux_only
def test_taken_addresses_and_domains_are_avoided() -> None:
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.76", 0))
    taken = ("127.0.0.76", holder.getsockname()[1])
    wanted = [("127.0.0.75", taken[1]), taken]
    first: Placement | None = None
    second: Placement | None = None
    try:
        first = place(wanted, None)
        second = place(wanted, None)  # as a second demo would, while the first runs
        assert first.slot != second.slot and first.domain != second.domain
        for placement in (first, second):
            assert taken not in placement.addresses.values()
            assert len(set(placement.addresses.values())) == 2
            assert placement.slot > 0 and placement.moved
        assert not set(first.addresses.values()) & set(second.addresses.values())
    finally:
        holder.close()
        for held_placement in (first, second):
            if held_placement is not None:
                held_placement.release()
    domain, held = place_domain()
    try:
        port = dds_ports(domain)[0]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as cyclone:
            cyclone.bind(("0.0.0.0", port))  # what a DDS participant on the domain holds
            assert not dds_domain_free(domain)
    finally:
        held.release()


def test_demo_outside_a_checkout_says_it_needs_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # as in the one-file bundle: the package without the repository's profiles beside it
    monkeypatch.setattr(demo, "DEFAULT_FLEET", tmp_path / "site" / "profiles" / "fleet.toml")
    assert main(["demo"]) == 2
    err = capsys.readouterr().err
    assert "source checkout" in err and "bash scripts/demo.sh" in err
    assert "site" not in err and "No such file" not in err


def test_demo_names_why_the_simulator_did_not_start(tmp_path: Path) -> None:
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.77", 0))
    port = holder.getsockname()[1]
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[[vehicles]]\nname = "ugv-x"\nsubsystem = 160\n'
                     f'link = "udp://127.0.0.77:{port}"\n')
    relay = tmp_path / "relay.toml"  # as written, so the demo does not move the fleet
    relay.write_text('[relay]\njaus_id = "200.1.1"\n[links.lan]\n'
                     f'url = "udp://127.0.0.78:0?peers=127.0.0.77:{port}"\n')
    logs = tmp_path / "logs"
    try:
        done = subprocess.run([*DEMO, "--fleet", str(fleet), "--relay-profile", str(relay),
                               "--duration", "10", "--log-dir", str(logs)],
                              capture_output=True, text=True, timeout=60)
    finally:
        holder.close()
    assert done.returncode == 1, done.stdout + done.stderr
    assert (f"the sim did not start: edge-vis sim: ugv-x: cannot open udp://127.0.0.77:{port}: "
            "Address already in use") in done.stderr
    assert str(logs / "sim.log") in done.stderr
    assert "Address already in use" in (logs / "sim.log").read_text()


def _tables(text: str) -> list[str]:
    """The monitor's tables in ``text``, one string each."""
    parts = re.split(r"^ VEHICLE .*$", text, flags=re.MULTILINE)
    return parts[1:]


@pytest.mark.slow
@pytest.mark.dds
@pytest.mark.serial
def test_two_demos_side_by_side_unattended_and_reporting_until_stopped(tmp_path: Path) -> None:
    """Both on the shipped profiles: one, with no terminal, prints its table again and again
    until SIGTERM; the other starts beside it, runs 20 s and reports what DDS showed.

    The second starts once the first shows its vehicles, so the two do not share the
    processor while both start up (a loaded machine would slow the summary's figures)."""
    pytest.importorskip("cyclonedds")
    logs_a, logs_b = tmp_path / "a", tmp_path / "b"
    reporting = subprocess.Popen([*DEMO, "--interval", "1", "--log-dir", str(logs_b)],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out_b: list[str] = []
    reader = threading.Thread(target=lambda: out_b.extend(reporting.stdout or ()), daemon=True)
    reader.start()
    names = ("ugv-alpha-101", "ugv-bravo-102", "uuv-delta-300")

    def full_tables() -> list[str]:
        return [t for t in _tables("".join(out_b)) if all(n in t for n in names)]

    def wait_for(count: int) -> None:
        deadline = time.monotonic() + 60
        while (time.monotonic() < deadline and reporting.poll() is None
               and len(full_tables()) < count):
            time.sleep(0.2)

    unattended: subprocess.Popen[str] | None = None
    try:
        wait_for(1)
        before = len(full_tables())
        unattended = subprocess.Popen([*DEMO, "--duration", "20", "--json", "--log-dir",
                                       str(logs_a)], stdout=subprocess.PIPE,
                                      stderr=subprocess.PIPE, text=True)
        wait_for(before + 2)  # and it goes on reporting while the other one runs
        full = full_tables()
        still_running = reporting.poll() is None
        reporting.send_signal(signal.SIGTERM)
        code_b = reporting.wait(timeout=40)
        reader.join(timeout=5)
        out_a, err_a = unattended.communicate(timeout=120)
    finally:
        for proc in (unattended, reporting):
            if proc is not None and proc.poll() is None:
                proc.kill()
    text_b = "".join(out_b)
    err_b = reporting.stderr.read() if reporting.stderr else ""
    assert still_running and before >= 1 and len(full) >= before + 2, text_b + err_b
    assert code_b == 0, err_b
    assert "exited early" not in err_b and "did not start" not in err_b
    assert " UGV " in full[-1]  # the demo profile names the ground vehicles' kind

    assert unattended is not None and unattended.returncode == 0, err_a + out_a
    summary = json.loads(out_a[out_a.index("{"):])
    assert summary["vehicles_seen"] == 3
    vehicles = summary["vehicles"]
    assert {v["name"] for v in vehicles.values()} == {"ugv-alpha", "ugv-bravo", "uuv-delta"}
    assert vehicles["ugv-alpha-101"]["type"] == "UGV"
    topics = summary["samples_per_topic"]
    # 5 Hz pose from three vehicles for well over 10 s
    assert topics["GlobalPose"] > 3 * 5 * 10
    assert topics["EnvironmentalData"] > 5  # the UUV on the serial line
    assert topics.get("ImageProduct", 0) >= 1  # its ATR notice
    delivered = summary["commands_delivered"]
    assert "control ugv-alpha-101" in delivered and "drive ugv-alpha-101" in delivered
    assert "emergency stop ugv-alpha-101" in delivered
    assert "emergency clear ugv-alpha-101" in delivered
    # ugv-bravo drops out 8 s after start for 5 s and comes back rebooted
    bravo = vehicles["ugv-bravo-102"]
    assert bravo["dropouts"] == 1 and bravo["recovered"] == 1
    assert summary["faults_recovered"] >= 1
    assert set(summary["exit_codes"].values()) == {0}
    for name in ("sim", "relay", "monitor"):
        assert (logs_a / f"{name}.log").exists()
    assert "ugv-alpha-101" in (logs_a / "monitor.log").read_text()

    # side by side: different vehicle addresses, relay addresses and DDS domains
    def where(text: str) -> tuple[set[str], str]:
        vehicles = set(re.findall(r"^vehicle \S+ \S+ \d+ (udp://\S+)", text, re.MULTILINE))
        relay = re.search(r"^relay: edge-vis run (.*)--domain (\d+)", text, re.MULTILINE)
        assert relay is not None and len(vehicles) == 2, text[:2000]
        return vehicles, relay.group(2)

    (vehicles_a, domain_a), (vehicles_b, domain_b) = where(out_a), where(text_b)
    assert not vehicles_a & vehicles_b and domain_a != domain_b
    moved = out_a if "not all free (another demo running?)" in out_a else text_b
    assert re.search(r"^relay: edge-vis run --profile \S+/relay\.toml", moved, re.MULTILINE)
