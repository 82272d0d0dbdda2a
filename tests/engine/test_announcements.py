"""Vehicles found from what they send, as the shipped battery example declares them in TOML:
by their hello (id, name, type and services read from its fields) or passively (the first
message declares the vehicle); alive while they send anything."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from edge_vis.catalogue.jsidl import profile_catalogue
from edge_vis.config import load_profile
from edge_vis.engine.manager import TranslationManager
from edge_vis.jaus.address import JausAddress

from .conftest import Harness, profile, published, sent

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"
PACK = "urn:example:battery:BatteryPack"
HELLO = {"pack_serial": "BP-0042", "pack_name": "Aft pack", "chemistry": 1,
         "services": [PACK]}
REPORT = {"voltage": 48.2, "current": -12.5, "state_of_charge": 81.0, "pack_state": 2}


@pytest.fixture(scope="module")
def catalogue() -> Any:
    return profile_catalogue([EXAMPLE / "BatteryPack.xml"])


def relay(catalogue: Any, **sections: Any) -> Harness:
    """The example's relay (relay.toml, battery-pack.toml), or ``sections`` instead."""
    prof = profile(**sections) if sections else load_profile(EXAMPLE / "relay.toml")
    manager = TranslationManager.from_selection(prof.translators)
    manager.verify(catalogue, prof.source)
    harness = Harness(catalogue, prof, manager.translators)
    harness.advance(0.1)
    return harness


def test_the_hello_declares_the_vehicle_as_the_profile_reads_it(catalogue: Any) -> None:
    h = relay(catalogue)
    out = h.deliver("77.1.3", "ReportBatteryHello", HELLO)
    vehicle = h.engine.vehicle("BP-0042")  # vehicle_id_field, a record-qualified path
    assert vehicle is not None and vehicle.online and vehicle.subsystem == 77
    assert (vehicle.name, vehicle.vehicle_type) == ("Aft pack", "LIFEPO4")  # enum label
    assert vehicle.components == {JausAddress(77, 1, 3): ((PACK, "1.0"),)}
    (ident,) = published(out, "VehicleIdentification")
    assert ident["vehicle_id"] == "BP-0042" and ident["jaus_address"] == "77.1.3"
    # no Events service listed: the report is polled at once, never asked by CreateEvent
    assert sent(out, "QueryBatteryPack", to="77.1.3") and not sent(out, "CreateEvent")
    # and it never took part in JAUS discovery
    assert not sent(h.advance(5.0), to="77.1.3", name="QueryServices")
    out = h.deliver("77.1.3", "ReportBatteryPack", REPORT)
    (sample,) = published(out, "BatteryPack")  # typed from the JSIDL
    assert sample["vehicle_id"] == "BP-0042"
    assert sample["voltage_v"] == pytest.approx(48.2, abs=0.01)  # record-qualified path
    assert sample["current_a"] == pytest.approx(-12.5, abs=0.01)  # flattened path
    assert sample["state"] == 2 and sample.get("temperature_c") is None  # absent


def test_a_later_hello_updates_the_vehicle(catalogue: Any) -> None:
    h = relay(catalogue)
    h.deliver("77.1.3", "ReportBatteryHello", HELLO)
    out = h.deliver("77.1.3", "ReportBatteryHello", {**HELLO, "pack_name": "Bow pack"})
    assert h.engine.vehicle("BP-0042").name == "Bow pack"  # type: ignore[union-attr]
    assert published(out, "VehicleIdentification")[-1]["name"] == "Bow pack"
    assert len(h.engine.vehicles) == 1 and h.engine.counters["hellos_accepted"] == 2


def test_any_message_keeps_it_alive_and_it_is_never_probed(catalogue: Any) -> None:
    h = relay(catalogue)
    h.deliver("77.1.3", "ReportBatteryHello", HELLO)
    vehicle = h.engine.vehicle("BP-0042")
    assert vehicle is not None
    for _ in range(8):  # 8 s of reports only, past the deployment's 3 s silence timeout
        out = h.advance(1.0)
        h.deliver("77.1.3", "ReportBatteryPack", REPORT)
        assert not sent(out, "QueryIdentification", to="77.1.3")
        assert not sent(out, "QueryHeartbeatPulse") and not sent(out, "QueryStatus")
    assert vehicle.online
    h.advance(5.9)
    assert vehicle.online  # silence_timeout = 6 s in battery-pack.toml
    out = h.advance(0.2)
    assert not vehicle.online
    assert published(out, "VehicleStatus")[-1]["online"] is False
    h.deliver("77.1.3", "ReportBatteryPack", REPORT)
    assert vehicle.online  # found again by the next message of any kind


def test_a_hello_of_another_subsystem_for_a_known_one_is_refused(catalogue: Any) -> None:
    uuv_like = {"hello": "ReportBatteryHello", "address_field": "pack_serial",
                "name_field": "pack_name"}
    h = relay(catalogue, vehicles=[{"discovery": uuv_like}])
    h.deliver("77.1.3", "ReportBatteryHello", {**HELLO, "pack_serial": "77.1.3"})
    assert h.engine.vehicle("Aft_pack-77") is not None  # id from name and subsystem
    h.deliver("77.1.3", "ReportBatteryHello", {**HELLO, "pack_serial": "78.1.1"})
    assert list(h.engine.vehicles) == [77] and h.engine.counters["hellos_refused"] == 1


def test_passive_discovery_from_the_first_message(catalogue: Any) -> None:
    h = relay(catalogue, vehicles=[{"file": str(EXAMPLE / "battery-pack-passive.toml")}],
              translators={"enabled": ["core"]})
    out = h.deliver("311.1.2", "ReportBatteryPack", REPORT)
    vehicle = h.engine.vehicle("battery-311")
    assert vehicle is not None and vehicle.online
    assert (vehicle.name, vehicle.vehicle_type) == ("Spare pack", "BATTERY")
    # inferred from what it sent: the JSIDL says ReportBatteryPack is BatteryPack's
    assert vehicle.components == {JausAddress(311, 1, 2): ((PACK, "1.0"),)}
    assert published(out, "VehicleIdentification")
    # a message of the core set from another component adds that component's services
    h.deliver("311.1.5", "ReportHeartbeatPulse", {})
    declaring = {uri for uri, _ in catalogue.by_name("ReportHeartbeatPulse").services}
    offered = {uri for uri, _ in vehicle.components[JausAddress(311, 1, 5)]}
    assert "urn:jaus:jss:core:Liveness" in declaring and declaring <= offered
    # another subsystem is not this profile's: it is asked who it is, as ever
    out = h.deliver("312.1.1", "ReportBatteryPack", REPORT)
    assert h.engine.vehicle("battery-312") is None
    assert sent(out, "QueryIdentification", to="312.1.1")


def test_passive_family_declares_every_sender_of_its_messages(catalogue: Any) -> None:
    h = relay(catalogue, vehicles=[{"vehicle_type": "BATTERY", "discovery": {
        "passive": True, "messages": ["ReportBatteryPack"]}}])
    h.deliver("90.1.1", "ReportBatteryPack", REPORT)
    h.deliver("91.1.1", "ReportBatteryPack", REPORT)
    h.deliver("92.1.1", "ReportHeartbeatPulse", {})  # not one of its messages
    assert sorted(v.vehicle_id for v in h.engine.vehicles.values()) == ["jaus-90", "jaus-91"]
    assert h.engine.counters["vehicles_found_passively"] == 2


def test_a_reloaded_family_profile_reaches_its_running_vehicles(catalogue: Any) -> None:
    family = {"hello": "ReportBatteryHello", "name_field": "pack_name"}
    h = relay(catalogue, vehicles=[{"discovery": {**family, "silence_timeout": 5.0}}])
    h.deliver("77.1.3", "ReportBatteryHello", HELLO)
    vehicle = h.engine.vehicle("Aft_pack-77")
    assert vehicle is not None
    h.engine.apply_profile(profile(vehicles=[{"report_rates": {"ReportBatteryPack": 0.5},
                                              "discovery": {**family,
                                                            "silence_timeout": 20.0}}]),
                           h.now)
    assert vehicle.silence_timeout(3.0) == 20.0
    assert vehicle.profile is not None and vehicle.profile.report_rates == {
        "ReportBatteryPack": 0.5}
    h.advance(10.0)
    assert vehicle.online  # the new 20 s, not the old 5 s
