"""``edge-vis messages`` as a user runs it: listing, filtering, JSON and checking JSIDL."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.cli import main

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"

LAMP = """<?xml version="1.0" encoding="UTF-8"?>
<service_def xmlns="urn:jaus:jsidl:1.0" name="Lamp" id="urn:example:lamp:LampDriver"
  version="1.0">
  <description>Switches a lamp.</description>
  <assumptions>Messages may be delayed, lost or reordered.</assumptions>
  <message_set>
    <input_set>
      <message_def name="SetLamp" message_id="D0B0" is_command="true">
        <description>Set the lamp brightness.</description>
        <header name="Header"/>
        <body name="Body">
          <record name="LampRec" optional="false">
            <fixed_field name="Brightness" field_type="unsigned byte" field_units="one"
              optional="false"/>
          </record>
        </body>
        <footer name="Footer"/>
      </message_def>
      {extra}
    </input_set>
    <output_set/>
  </message_set>
  <internal_events_set/>
  <protocol_behavior is_stateless="true"/>
</service_def>
"""
#: a ReportStatus whose Status is 16 bits: not the AS5710 layout
BAD_STATUS = """<message_def name="ReportStatus" message_id="4002" is_command="false">
        <description>Not the standard one.</description>
        <header name="Header"/>
        <body name="Body">
          <record name="R" optional="false">
            <fixed_field name="Status" field_type="unsigned short integer" field_units="one"
              optional="false"/>
          </record>
        </body>
        <footer name="Footer"/>
      </message_def>"""


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict]:
    code = main(["messages", "--json", *argv])
    return code, json.loads(capsys.readouterr().out)


def test_lists_every_known_message_with_counts(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["messages"]) == 0
    out = capsys.readouterr().out
    catalogue = default_catalogue()
    lines = out.splitlines()
    assert lines[0].split() == ["CODE", "NAME", "SET", "SERVICES"]
    assert any(line.startswith("0x4402  ReportGlobalPose") and
               "urn:jaus:jss:mobility:GlobalPoseSensor 1.0" in line for line in lines)
    rows = [line for line in lines if line.startswith("0x")]
    assert len(rows) == len(catalogue)
    totals = {line.split()[0]: int(line.split()[1]) for line in lines
              if line and not line.startswith(("0x", "CODE"))}
    assert totals.pop("total") == len(catalogue)
    assert totals == catalogue.sets()
    assert totals["uuv"] == 4


def test_json_for_machines(capsys: pytest.CaptureFixture[str]) -> None:
    code, report = run_json(capsys)
    assert code == 0
    catalogue = default_catalogue()
    assert report["total"] == len(catalogue) == len(report["messages"])
    assert {name: entry["count"] for name, entry in report["sets"].items()} == catalogue.sets()
    event = next(m for m in report["messages"] if m["code"] == 0x41F1)
    assert event["name"] == "Event" and event["code_hex"] == "0x41F1"
    assert event["source"] == "built-in"
    assert {"uri": "urn:jaus:jss:core:Events", "version": "1.1"} in event["services"]
    assert report["sets"]["uuv"]["source"] == "plugin"


def test_filter_by_set(capsys: pytest.CaptureFixture[str]) -> None:
    code, report = run_json(capsys, "--set", "uuv", "--set", "core")
    assert code == 0
    assert set(report["sets"]) == {"uuv", "core"}
    assert report["total"] == report["sets"]["uuv"]["count"] + report["sets"]["core"]["count"]
    uuv = [m for m in report["messages"] if m["service_set"] == "uuv"]
    assert {m["code_hex"] for m in uuv} == {"0xF0A0", "0xE0A1", "0xF0A1", "0xF0A2"}
    assert all(m["from"] == "shipped JSIDL uuv" for m in uuv)


def test_unknown_set_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["messages", "--set", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "no message set named nosuch" in err and "mobility" in err


def test_checks_a_users_jsidl(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lamp = tmp_path / "lamp.xml"
    lamp.write_text(LAMP.format(extra=""), encoding="utf-8")
    code, report = run_json(capsys, "--jsidl", str(lamp))
    assert code == 0
    (mine,) = [m for m in report["messages"] if m["source"] == "jsidl"]
    assert (mine["code_hex"], mine["name"], mine["status"]) == ("0xD0B0", "SetLamp", "new")
    assert mine["services"] == [{"uri": "urn:example:lamp:LampDriver", "version": "1.0"}]
    assert report["total"] == len(default_catalogue()) + 1


def test_a_conflicting_definition_fails_the_check(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lamp = tmp_path / "lamp.xml"
    lamp.write_text(LAMP.format(extra=BAD_STATUS), encoding="utf-8")
    assert main(["messages", "--jsidl", str(lamp)]) == 1
    captured = capsys.readouterr()
    (line,) = [x for x in captured.out.splitlines() if "DIFFERS" in x]
    assert line.startswith("0x4002  ReportStatus") and "DIFFERS from ReportStatus in core" in line
    assert "1 JSIDL message(s) differ" in captured.err
    code, report = run_json(capsys, "--jsidl", str(lamp), "--set", "urn:example:lamp")
    assert code == 1 and report["conflicts"] == 1
    flagged = {m["name"]: m["conflict"] for m in report["messages"]}
    assert flagged == {"ReportStatus": True, "SetLamp": False}
    # a listing that leaves the conflicting message out is not failed by it
    assert main(["messages", "--jsidl", str(lamp), "--set", "uuv"]) == 0


@pytest.mark.skipif(not (SHARED / "jsidl").is_dir(), reason="JSIDL reference not found")
def test_the_public_core_jsidl_matches_the_built_in_set(
        capsys: pytest.CaptureFixture[str]) -> None:
    code, report = run_json(capsys, "--jsidl", str(SHARED / "jsidl" / "urn.jaus.jss.core-v1.1"))
    assert code == 0
    statuses = {m["status"] for m in report["messages"] if m["source"] == "jsidl"}
    assert statuses == {"same as core"}


def test_broken_jsidl_is_reported_not_a_traceback(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.xml"
    broken.write_text("<service_def xmlns='urn:jaus:jsidl:1.0'><message_set>", encoding="utf-8")
    assert main(["messages", "--jsidl", str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("edge-vis messages: ") and "broken.xml" in err
