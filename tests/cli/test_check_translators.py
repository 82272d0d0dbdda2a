"""``edge-vis check`` builds the enabled translators with their profile tables, as the relay
does at start-up, so their configuration errors show before the relay runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from edge_vis.cli import main

HEAD = '[relay]\njaus_id = "200.1.1"\n'
#: a user's own JSIDL: a water quality probe
WATER_QUALITY = Path(__file__).resolve().parents[1] / "translators" / "WaterQuality.xml"


def _check(tmp_path: Path, body: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    profile = tmp_path / "relay.toml"
    profile.write_text(HEAD + body)
    status = main(["check", str(profile)])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def test_good_generic_mapping_passes_and_counts_translators(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "WaterQuality.xml").write_text(WATER_QUALITY.read_text())
    status, out = _check(tmp_path, """
[catalogue]
jsidl = ["WaterQuality.xml"]

[translators]
enabled = ["core", "generic"]

[[translators.generic.mappings]]
message = "ReportWaterQuality"
topic = "WaterQuality"
fields = { ph = "ph" }
""", capsys)
    assert status == 0, out
    assert out.startswith("OK ") and "2 translator(s)" in out


def test_bad_generic_mapping_is_reported_with_its_key_path(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = _check(tmp_path, """
[[translators.generic.mappings]]
message = "ReportWaterQuality"
topic = "Water Quality"
rate = -1
colour = "blue"
""", capsys)
    assert status == 2
    assert "3 problem(s)" in out
    for key in ("translators.generic.mappings[0].topic", "translators.generic.mappings[0].rate",
                "translators.generic.mappings[0].colour"):
        assert key in out, (key, out)
    assert "relay.toml" in out  # the file is named even though the translator does not know it


def test_unknown_enabled_translator_is_reported(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = _check(tmp_path, '[translators]\nenabled = ["core", "nosuch"]\n', capsys)
    assert status == 2
    assert "nosuch" in out and "core" in out  # names what is installed instead


def test_options_for_a_translator_without_options_are_reported(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = _check(tmp_path, "[translators.ugv]\nspeed = 3\n", capsys)
    assert status == 2
    assert "ugv" in out and "takes no options" in out


def test_bad_mobility_extra_reports_are_reported(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = _check(tmp_path, '[translators.mobility]\n'
                                   'extra_reports = ["ReportWrenchEffort", "ReportNothing"]\n'
                                   'speed = 1\n', capsys)
    assert status == 2
    assert "2 problem(s)" in out
    assert "translators.mobility.extra_reports[1]" in out and "ReportNothing" in out
    assert "translators.mobility.speed" in out
