"""deploy/edge-vis.service: the keys a relay depends on, and systemd's own verdict."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
from deploykit import REPO

from edge_vis.cli import build_parser
from edge_vis.config import load_profile

UNIT = REPO / "deploy" / "edge-vis.service"
PROFILE = REPO / "deploy" / "relay.toml"


def parse_unit(text: str) -> dict[str, list[tuple[str, str]]]:
    """Sections -> (key, value) in order; repeated keys stay (systemd's semantics)."""
    sections: dict[str, list[tuple[str, str]]] = {}
    current: list[tuple[str, str]] | None = None
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1], [])
            continue
        assert current is not None, f"line {number}: key outside a section"
        assert "=" in line and not raw.endswith("\\"), f"line {number}: not KEY=value: {raw}"
        key, value = line.split("=", 1)
        assert re.fullmatch(r"[A-Za-z]+", key.strip()), f"line {number}: bad key {key!r}"
        current.append((key.strip(), value.strip()))
    return sections


def values(section: list[tuple[str, str]], key: str) -> list[str]:
    return [v for k, v in section if k == key]


def one(section: list[tuple[str, str]], key: str) -> str:
    found = values(section, key)
    assert len(found) == 1, f"{key}: expected exactly one, got {found}"
    return found[0]


def test_unit_runs_the_relay_as_a_watched_notify_service() -> None:
    unit = parse_unit(UNIT.read_text())
    assert set(unit) == {"Unit", "Service", "Install"}
    service = unit["Service"]
    assert one(service, "Type") == "notify"
    assert one(service, "NotifyAccess") == "main"
    assert int(one(service, "WatchdogSec")) >= 2
    assert one(service, "Restart") == "on-failure"
    assert one(service, "ExecReload") == "/bin/kill -HUP $MAINPID"
    assert one(unit["Install"], "WantedBy") == "multi-user.target"

    # the command line is one the CLI accepts, with JSON logs and the installed profile
    argv = shlex.split(one(service, "ExecStart"))
    assert argv[0].startswith("/")
    args = build_parser().parse_args(argv[1:])
    assert args.command == "run" and args.log_format == "json"
    assert str(args.profile) == "/etc/edge-vis/relay.toml"

    # the bundle unpacks into a directory the service may write
    env = dict(v.split("=", 1) for v in values(service, "Environment"))
    assert env["SHIV_ROOT"] == "/var/cache/edge-vis"
    assert one(service, "CacheDirectory") == "edge-vis"


def test_hardening_leaves_serial_ports_usable() -> None:
    service = parse_unit(UNIT.read_text())["Service"]
    assert values(service, "PrivateDevices") in ([], ["no"], ["false"])  # it hides /dev/tty*
    if one(service, "DevicePolicy") in ("closed", "strict"):
        allowed = {v.split()[0] for v in values(service, "DeviceAllow")}
        assert {"char-ttyUSB", "char-ttyACM"} <= allowed
    assert "dialout" in values(service, "SupplementaryGroups")
    assert one(service, "NoNewPrivileges") == "yes"
    assert one(service, "ProtectSystem") == "strict"
    families = one(service, "RestrictAddressFamilies").split()
    assert {"AF_INET", "AF_UNIX"} <= set(families)  # JUDP, and the notify socket
    assert not values(service, "MemoryDenyWriteExecute")


def test_example_relay_profile_is_valid() -> None:
    profile = load_profile(PROFILE)
    assert {link.scheme for link in profile.links} == {"serial", "udp"}
    assert profile.vehicles and profile.vehicles[0].link == "uuv_modem"


def _installed_copy(tmp_path: Path) -> Path:
    """The unit with ExecStart pointing at an executable that exists here."""
    binary = tmp_path / "edge-vis"
    binary.write_text("#!/bin/sh\n")
    binary.chmod(0o755)
    unit = tmp_path / "edge-vis.service"
    unit.write_text(UNIT.read_text().replace("/usr/local/bin/edge-vis", str(binary)))
    return unit


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
def test_systemd_analyze_verify_finds_nothing(tmp_path: Path) -> None:
    unit = _installed_copy(tmp_path)
    done = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True,
                          text=True, timeout=60)
    about_unit = [line for line in (done.stdout + done.stderr).splitlines()
                  if unit.name in line]
    assert done.returncode == 0 and not about_unit, done.stdout + done.stderr

    # and it does notice a mistake
    bad = tmp_path / "bad" / "edge-vis.service"
    bad.parent.mkdir()
    bad.write_text(unit.read_text().replace("WatchdogSec=", "WatchdogSecs="))
    done = subprocess.run(["systemd-analyze", "verify", str(bad)], capture_output=True,
                          text=True, timeout=60)
    assert "Unknown key 'WatchdogSecs'" in done.stdout + done.stderr


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
def test_systemd_rates_the_hardening_ok(tmp_path: Path) -> None:
    unit = _installed_copy(tmp_path)
    done = subprocess.run(["systemd-analyze", "security", "--offline=yes", str(unit)],
                          capture_output=True, text=True, timeout=60)
    match = re.search(r"Overall exposure level for \S+: ([\d.]+)", done.stdout + done.stderr)
    if match is None:
        pytest.skip(f"this systemd-analyze cannot rate offline: {done.stderr.strip()[:200]}")
    assert float(match.group(1)) <= 3.0, done.stdout
