"""A ``kind = "custom"`` vehicle from the shipped battery example's sim.toml and its JSIDL
(sans-I/O, fake clock): hello, answered and periodic reports with drift, unknown messages
counted, and ``edge-vis check`` naming what a bad entry gets wrong."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from conftest import Wire, named

from edge_vis.cli import main
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.tools.sim.profile import load_profile
from edge_vis.tools.sim.scripted import vehicle_catalogue
from edge_vis.tools.sim.subsystem import SimVehicle

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"
PACK = JausAddress(77, 1, 3)


def battery_wire(**changes: object) -> Wire:
    (vehicle,) = load_profile(EXAMPLE / "sim.toml").vehicles
    wire = Wire()
    wire.catalogue = vehicle_catalogue(vehicle.jsidl)
    wire.vehicle = SimVehicle(replace(vehicle, **changes), wire.catalogue, start=0.0)
    return wire


def test_custom_vehicle_says_its_hello_and_answers_its_query() -> None:
    wire = battery_wire()
    outs = wire.advance(4.5)
    hellos = named(outs, "ReportBatteryHello")
    assert len(hellos) == 3 and {(h.source, h.destination) for h in hellos} == {(PACK, BROADCAST)}
    assert hellos[0].fields == {"pack_serial": "BP-0042", "pack_name": "Aft pack",
                                "chemistry": 1, "services": ["urn:example:battery:BatteryPack"]}
    first = wire.query("QueryBatteryPack", to=PACK)
    assert (first.name, first.source, first.destination) == ("ReportBatteryPack", PACK,
                                                             JausAddress(200, 1, 1))
    assert first.fields["voltage"] == pytest.approx(48.2, abs=0.01)
    assert first.fields["current"] == pytest.approx(-12.5, abs=0.01)
    assert first.fields["pack_state"] == 2  # "DISCHARGING"
    assert first.fields["state_of_charge"] == pytest.approx(81.0 - 0.05 * 4.5, abs=0.4)
    wire.advance(100.0, step=1.0)
    later = wire.query("QueryBatteryPack", to=PACK).fields
    assert later["state_of_charge"] == pytest.approx(81.0 - 0.05 * 104.5, abs=0.4)  # ramps
    assert later["temperature"] != pytest.approx(first.fields["temperature"], abs=0.1)  # sine


def test_periodic_report_and_unknown_messages_are_counted() -> None:
    (vehicle,) = load_profile(EXAMPLE / "sim.toml").vehicles
    wire = battery_wire(reports=(replace(vehicle.reports[0], period=1.0),))
    assert len(named(wire.advance(3.05), "ReportBatteryPack")) == 3
    # a pack knows no JAUS Discovery or Access Control: counted, never answered
    assert wire.send("QueryIdentification", {"query_type": 2}, to=BROADCAST) == []
    assert wire.send("RequestControl", {"authority_code": 5}, to=PACK) == []
    assert wire.vehicle.counters["unsupported"] == 2


def test_check_names_a_bad_custom_entry(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "sim.toml"
    bad.write_text(f'''
[[vehicles]]
name = "pack"
kind = "custom"
subsystem = 77
link = "udp://127.0.0.88:3794"
jsidl = ["{EXAMPLE / 'BatteryPack.xml'}"]
hello = {{ message = "ReportBatteryHelo" }}
[[vehicles.reports]]
message = "ReportBatteryPack"
query = "QueryBatteryPack"
fields = {{ voltag = 1.0 }}
drift = {{ current = {{ ramp = 1.0 }} }}
rate = 2.0
[[vehicles]]
name = "ugv"
subsystem = 78
link = "udp://127.0.0.89:3794"
reports = [{{ message = "ReportGlobalPose", period = 1.0 }}]
''')
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "vehicles[0].hello.message: no message 'ReportBatteryHelo'" in err
    assert "vehicles[0].reports[0].fields: ReportBatteryPack cannot be sent" in err
    assert "no field 'voltag'" in err
    assert "vehicles[0].reports[0].drift.current: drifts a number" in err
    assert "vehicles[0].reports[0].rate: unknown key" in err
    assert 'vehicles[1].reports: only a vehicle of kind = "custom"' in err


def test_check_names_a_missing_mandatory_field(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    text = (EXAMPLE / "sim.toml").read_text().replace("current = -12.5\n", "")
    (tmp_path / "sim.toml").write_text(text)
    (tmp_path / "BatteryPack.xml").write_text((EXAMPLE / "BatteryPack.xml").read_text())
    assert main(["check", str(tmp_path / "sim.toml")]) == 2
    assert "missing mandatory fields ['current']" in capsys.readouterr().err
