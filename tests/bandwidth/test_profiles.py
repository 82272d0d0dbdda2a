"""Link profiles and per-report rates in TOML: validation with file and key path, the
shipped profiles, ``edge-vis check`` and ``edge-vis plan``."""

from __future__ import annotations

from pathlib import Path

import pytest

from edge_vis.cli import main
from edge_vis.config import from_mapping, load_profile
from edge_vis.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
LINKS = ROOT / "profiles" / "links"


@pytest.mark.parametrize("name", ["serial-9600", "serial-57600", "ip-radio-2m", "ethernet"])
def test_shipped_link_profiles_load(name: str) -> None:
    profile = from_mapping({"links": {"radio": {"url": "serial:///dev/null",
                                                "profile": name}}},
                           file="site.toml", base_dir=ROOT / "profiles")
    spec = profile.links[0].spec
    assert spec is not None and spec.limited and spec.source.endswith(f"{name}.toml")
    assert spec.priority_of("command") > spec.priority_of("telemetry")


def test_serial_9600_figures() -> None:
    profile = from_mapping({"links": {"radio": {"url": "serial:///dev/null",
                                                "profile": "serial-9600", "budget": 0.5}}},
                           base_dir=ROOT / "profiles")
    spec = profile.links[0].spec
    assert spec is not None
    assert spec.capacity_bytes == 960  # 10 bits per byte on an async serial line
    assert spec.budget_bytes == 480    # the inline key overrides the file


def test_every_problem_is_named_with_file_and_key_path(tmp_path: Path) -> None:
    (tmp_path / "links").mkdir()
    (tmp_path / "links" / "bad.toml").write_text("bit_rate = -5\nmtu = 9000\ncolour = 1\n")
    site = tmp_path / "site.toml"
    site.write_text(
        '[links.radio]\nurl = "serial:///dev/null"\nprofile = "bad"\n'
        '[links.other]\nurl = "udp://127.0.0.1:3794"\nbudget = 1.5\n'
        '[links.third]\nurl = "udp://127.0.0.1:3795"\nprofile = "missing"\n'
        '[links.third.priorities]\ncommand = 0\nvoice = 2\n'
        '[report_rates]\nReportGlobalPose = { desired = 5.0, minimum = 9.0, priority = 12 }\n'
        '[[vehicles]]\nvehicle_id = "a"\n'
        '[vehicles.report_rates]\nReportVelocityState = { minimum = 1.0 }\n')
    with pytest.raises(ConfigError) as info:
        load_profile(site)
    problems = {(Path(f).name, key): msg for f, key, msg in info.value.problems}
    bad = str(tmp_path / "links" / "bad.toml")
    assert ("bad.toml", "bit_rate") in problems, problems
    assert ("bad.toml", "mtu") in problems and ("bad.toml", "colour") in problems
    assert any(f == bad for f, _k, _m in info.value.problems)
    assert "budget" in problems[("site.toml", "links.other.budget")] or \
        "<= 1" in problems[("site.toml", "links.other.budget")]
    assert "bit_rate" in problems[("site.toml", "links.other.bit_rate")]
    assert "no link profile 'missing'" in problems[("site.toml", "links.third.profile")]
    assert ("site.toml", "links.third.priorities.voice") in problems
    assert "above the desired" in problems[("site.toml", "report_rates.ReportGlobalPose.minimum")]
    assert ("site.toml", "report_rates.ReportGlobalPose.priority") in problems
    assert ("site.toml", "vehicles[0].report_rates.ReportVelocityState.desired") in problems


def test_check_and_plan_commands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    site = tmp_path / "site.toml"
    site.write_text(
        f'[links.radio]\nurl = "serial:///dev/null"\nprofile = "{LINKS / "serial-9600.toml"}"\n'
        '[report_rates]\nReportGlobalPose = { desired = 10.0, minimum = 2.0, priority = 7 }\n'
        'ReportVelocityState = { desired = 10.0, minimum = 1.0 }\n'
        '[[vehicles]]\nvehicle_id = "ugv-1"\nsubsystem = 101\nlink = "radio"\n')
    assert main(["check", str(site)]) == 0
    assert main(["plan", str(site), "--vehicles", "2"]) == 0
    out = capsys.readouterr().out
    assert "link radio: 9600 bit/s half duplex" in out
    lines = [line for line in out.splitlines() if "ReportGlobalPose" in line]
    assert len(lines) == 2 and all("degraded" in line for line in lines)
    assert any("ugv-1-2" in line for line in lines)
    # ten vehicles cannot all have even their minimums: the plan says so and exits 1
    assert main(["plan", str(site), "--vehicles", "10"]) == 1
    out = capsys.readouterr().out
    assert "WARNING" in out and "DROPPED" in out


def test_plan_without_vehicles_says_how_to_get_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    site = tmp_path / "site.toml"
    site.write_text('[links.radio]\nurl = "serial:///dev/null"\nprofile = "serial-57600"\n'
                    '[report_rates]\nReportGlobalPose = 5.0\n')
    assert main(["plan", str(site)]) == 0
    captured = capsys.readouterr()
    assert "planned 0 B/s" in captured.out
    assert "nothing planned on link radio" in captured.err
    assert f"edge-vis plan {site} --vehicles N" in captured.err
    assert main(["plan", str(site), "--vehicles", "1"]) == 0
    captured = capsys.readouterr()
    assert "vehicle-1" in captured.out and captured.err == ""


def test_the_demo_profile_plans_its_serial_radio(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(ROOT / "profiles" / "demo.toml")]) == 0
    captured = capsys.readouterr()
    assert "uuv-delta-300    ReportGlobalPose" in captured.out
    assert "planned 0 B/s" not in captured.out and captured.err == ""
