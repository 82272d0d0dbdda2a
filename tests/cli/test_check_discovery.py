"""``edge-vis check`` on discovery profiles: the shipped battery example passes, and each
name a hello or passive profile gives that the catalogue lacks is refused by its key."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from edge_vis.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"


def check(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    status = main(["check", str(path)])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def problems(out: str) -> list[str]:
    """The problem lines under ``check``'s heading (indented), without log lines."""
    return [line.strip() for line in out.splitlines() if line.startswith("  ")]


@pytest.fixture
def example(tmp_path: Path) -> Path:
    """A copy of the battery example to break."""
    for name in ("BatteryPack.xml", "battery-pack.toml", "battery-pack-passive.toml",
                 "relay.toml"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    return tmp_path


def test_the_example_passes(example: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = check(example / "relay.toml", capsys)
    assert status == 0, out
    status, out = check(example / "battery-pack.toml", capsys)
    assert status == 0 and "found by its hello ReportBatteryHello" in out, out


@pytest.mark.parametrize(("old", "new", "key", "reason"), [
    ('hello = "ReportBatteryHello"', 'hello = "ReportBatteryHi"', "discovery.hello",
     "no message 'ReportBatteryHi' in the catalogue"),
    ('name_field = "pack_name"', 'name_field = "pack_label"', "discovery.name_field",
     "'pack_label' of ReportBatteryHello: no field 'pack_label' in the message"),
    ('type_field = "chemistry"', 'type_field = "chemistry.cells"', "discovery.type_field",
     "chemistry is a single value"),
    ('"battery_hello_rec.pack_serial"', '"battery_rec.serial"', "discovery.vehicle_id_field",
     "no field 'battery_rec'"),
])
def test_a_hello_profile_naming_what_does_not_exist_is_refused(
        example: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, key: str,
        reason: str) -> None:
    vehicle = example / "battery-pack.toml"
    assert old in vehicle.read_text()
    vehicle.write_text(vehicle.read_text().replace(old, new))
    status, out = check(example / "relay.toml", capsys)
    assert status == 2
    (line,) = problems(out)
    assert line.startswith(f"{vehicle}: {key}: "), line  # named in the vehicle's own file
    assert reason in line, line


def test_a_passive_profile_naming_no_message_is_refused(
        example: Path, capsys: pytest.CaptureFixture[str]) -> None:
    relay = example / "relay.toml"
    relay.write_text(relay.read_text() + '\n[[vehicles]]\nvehicle_type = "BATTERY"\n'
                     '[vehicles.discovery]\npassive = true\n'
                     'messages = ["ReportBatteryPack", "ReportBateryPack"]\n')
    status, out = check(relay, capsys)
    assert status == 2
    (line,) = problems(out)
    assert line.startswith(f"{relay}: vehicles[1].discovery.messages[1]: no message "
                           "'ReportBateryPack'"), line


@pytest.mark.parametrize(("table", "key", "reason"), [
    ("passive = true", "discovery.passive", "needs a subsystem, or the messages"),
    ('hello = "X"\npassive = true', "discovery.hello", "either hello"),
    ("passive = true\nmessages = [\"A\"]\nname_field = \"n\"", "discovery.name_field",
     "only a hello has fields"),
    ('hello = "X"\nsilence_timeout = -1', "discovery.silence_timeout", "at least 0"),
])
def test_a_discovery_table_is_read_with_its_schema(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], table: str, key: str,
        reason: str) -> None:
    vehicle = tmp_path / "vehicles" / "pack.toml"
    vehicle.parent.mkdir()
    vehicle.write_text(f"[discovery]\n{table}\n")
    status, out = check(vehicle, capsys)
    assert status == 2, out
    assert any(f"{key}: " in line and reason in line for line in out.splitlines()), out
