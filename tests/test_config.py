"""Profiles: TOML -> frozen dataclasses, every problem reported with file and key path."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from edge_vis.cli import main
from edge_vis.config import (
    RelayProfile,
    default_profile_path,
    from_mapping,
    load_default_profile,
    load_profile,
)
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress

REPO = Path(__file__).resolve().parents[1]


def test_default_profile_is_shipped_and_valid() -> None:
    path = default_profile_path()
    assert path.is_file()
    profile = load_default_profile()
    assert isinstance(profile, RelayProfile)
    assert profile.jaus_id == JausAddress(200, 1, 1)
    assert profile.translators.selects("core") and profile.translators.selects("mobility")
    assert profile.discovery.silence_timeout == pytest.approx(3.0)
    assert profile.commands.rate == 10.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        profile.authority = 1  # type: ignore[misc]


def test_example_vehicle_profiles_load(tmp_path: Path) -> None:
    site = tmp_path / "site.toml"
    site.write_text(f"""
[relay]
jaus_id = "42.1.1"
authority = 120
[links.radio]
url = "udp://0.0.0.0:3794"
bandwidth = 115200
[[vehicles]]
file = "{REPO / 'profiles' / 'vehicles' / 'jts-example.toml'}"
[[vehicles]]
file = "{REPO / 'profiles' / 'vehicles' / 'static-ugv.toml'}"
[[vehicles]]
vehicle_id = "inline"
subsystem = 3
link = "radio"
report_rates = {{ ReportGlobalPose = 0.5 }}
""")
    profile = load_profile(site)
    jts, static, inline = profile.vehicles
    assert (jts.vehicle_id, jts.subsystem, jts.is_static) == ("jts-example", 126, False)
    assert static.is_static and static.components[0].address == JausAddress(150, 1, 1)
    assert static.components[0].services[0].uri == "urn:jaus:jss:core:Management"
    assert profile.vehicle_by_subsystem(3) is inline
    assert profile.report_rate("ReportGlobalPose", 5.0, inline) == 0.5
    assert profile.report_rate("ReportLocalPose", 5.0, jts) == 2.0
    assert profile.report_rate("ReportVelocityState", 5.0, jts) == 5.0
    assert profile.links[0].scheme == "udp" and profile.links[0].bandwidth == 115200


def test_every_problem_named_with_file_and_key_path(tmp_path: Path) -> None:
    vehicle = tmp_path / "bad-vehicle.toml"
    vehicle.write_text('vehicle_id = "v"\naddress = "1.2"\n')
    site = tmp_path / "site.toml"
    site.write_text(f"""
[relay]
jaus_id = "42.1"
authority = 300
colour = "blue"
[links.radio]
url = "no-scheme"
[commands]
rate = -1
[discovery]
period = "fast"
[[vehicles]]
file = "{vehicle.name}"
[[vehicles]]
vehicle_id = "a"
link = "wifi"
[[vehicles]]
vehicle_id = "a"
[catalogue]
jsidl = ["missing.xml"]
""")
    with pytest.raises(ConfigError) as info:
        load_profile(site)
    problems = {(Path(f).name, k): m for f, k, m in info.value.problems}
    assert problems[("site.toml", "relay.jaus_id")].startswith("JAUS address '42.1'")
    assert "0..255" in problems[("site.toml", "relay.authority")]
    assert problems[("site.toml", "relay.colour")] == "unknown key"
    assert "no scheme" in problems[("site.toml", "links.radio.url")]
    assert "positive" in problems[("site.toml", "commands.rate")]
    assert "expected float" in problems[("site.toml", "discovery.period")]
    assert "S.N.C" in problems[("bad-vehicle.toml", "address")]
    assert "unknown link 'wifi'" in problems[("site.toml", "vehicles[1].link")]
    assert "duplicate vehicle_id" in problems[("site.toml", "vehicles[2].vehicle_id")]
    assert "no such file" in problems[("site.toml", "catalogue.jsidl[0]")]
    assert len(info.value.problems) == 10
    assert "site.toml: relay.authority: must be in 0..255" in str(info.value)


def test_invalid_toml_and_missing_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[relay\n")
    with pytest.raises(ConfigError, match="invalid TOML"):
        load_profile(bad)
    with pytest.raises(ConfigError, match="cannot read"):
        load_profile(tmp_path / "absent.toml")


def test_translator_selection() -> None:
    profile = from_mapping({"translators": {"enabled": ["core"], "disabled": []}})
    assert profile.translators.selects("core") and not profile.translators.selects("mobility")
    profile = from_mapping({"translators": {"disabled": ["mobility"]}})
    assert profile.translators.selects("core") and not profile.translators.selects("mobility")


def test_check_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(default_profile_path())]) == 0
    assert capsys.readouterr().out.startswith("OK ")
    bad = tmp_path / "bad.toml"
    bad.write_text('[relay]\njaus_id = "x"\n[control]\nrenewal_period = 0\n')
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "2 problem(s)" in err
    assert "relay.jaus_id" in err and "control.renewal_period" in err
