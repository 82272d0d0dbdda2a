"""The shipped uuv support: discovery by its VendorHello from a TOML profile (no Python),
and the uuv translator's ocean data and ATR image announcements."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import pytest
from rulekit import CAT, CTX, TYPES, Relay, check_report_rule

from edge_vis.config import from_mapping, load_profile
from edge_vis.dds.convert import converter_for
from edge_vis.jaus.address import JausAddress
from translators.uuv import UuvTranslator

TR = UuvTranslator
OCEAN = ("urn:edge-vis:uuv:OceanEnvironmentSensor", "1.0")
HELLO = {
    "vehicle_name": "Nemo", "vehicle_type": 1,
    "jaus_id": {"subsystem": 60, "node": 1, "component": 5},
    "firmware_version": "2.4.1",
    "services": [{"uri": "urn:edge-vis:uuv:OceanEnvironmentSensor", "major_version": 1,
                  "minor_version": 0},
                 {"uri": "urn:edge-vis:uuv:AtrImageNotifier", "major_version": 1,
                  "minor_version": 0}],
    "bulk_image_port": 9000,
}


@pytest.mark.parametrize("rule", TR.report_rules, ids=[r.message for r in TR.report_rules])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


def decoded(name: str, fields: dict) -> dict:  # type: ignore[type-arg]
    return CAT.decode(CAT.encode(name, fields)).fields or {}


UUV_PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "vehicles" / "uuv.toml"


def family(**extra: object):  # type: ignore[no-untyped-def]
    """A relay profile taking the shipped UUV discovery profile."""
    return profile(vehicles=[{"file": str(UUV_PROFILE)}], **extra)


def test_hello_declares_the_vehicle_from_the_shipped_profile() -> None:
    relay = Relay(family(), [TR()])
    relay.advance(0.1)
    relay.deliver("60.1.5", "VendorHello", HELLO)
    vehicle = relay.engine.vehicle("Nemo-60")
    assert vehicle is not None and vehicle.online
    assert (vehicle.name, vehicle.vehicle_type) == ("Nemo", "AUV")
    assert list(vehicle.components) == [JausAddress(60, 1, 5)]
    assert {OCEAN, ("urn:edge-vis:uuv:AtrImageNotifier", "1.0")} <= set(
        vehicle.components[JausAddress(60, 1, 5)])
    assert relay.engine.counters["hellos_accepted"] == 1


@pytest.mark.parametrize("jaus_id", [{"subsystem": 65535, "node": 255, "component": 255},
                                     {"subsystem": 60, "node": 0, "component": 1}])
def test_hello_with_unusable_address_declares_nothing(jaus_id: dict) -> None:  # type: ignore[type-arg]
    relay = Relay(family(), [TR()])
    relay.advance(0.1)
    relay.deliver("60.1.5", "VendorHello", {**HELLO, "jaus_id": jaus_id})
    assert relay.engine.vehicles == {}
    assert relay.engine.counters["hellos_refused"] == 1


def test_ocean_environment_edges() -> None:
    fields = decoded("ReportOceanEnvironment", {
        "water_temperature": -2.0, "depth": -100.0, "current_speed": 10.0,
        "current_direction": -math.pi})
    (action,) = TR().on_message("ReportOceanEnvironment", fields, CTX)
    sample = action.sample
    assert action.topic == "EnvironmentalData"
    assert sample["water_temperature"] == pytest.approx(-2.0, abs=1e-3)  # below zero
    assert sample["depth"] == pytest.approx(-100.0, abs=1e-4)  # the lower limit
    assert sample["current_speed"] == pytest.approx(10.0, abs=1e-3)  # the upper limit
    assert sample["current_direction"] == pytest.approx(-math.pi, abs=1e-4)
    assert math.isnan(sample["salinity"])  # not reported: NaN, never 0
    converter_for(TYPES["EnvironmentalData"]).to_struct(sample, "EnvironmentalData")


def test_atr_image_announcement() -> None:
    digest = hashlib.sha256(b"sonar image").digest()
    fields = decoded("ReportAtrImageAvailable", {
        "image_id": 77, "size_bytes": 5_000_000_000, "format": 5, "sha256": digest,
        "capture_time": 1_700_000_000_000, "target_class": "mine-like", "confidence": 0.9,
        "latitude": 54.3})
    (action,) = TR().on_message("ReportAtrImageAvailable", fields, CTX)
    product = action.sample
    assert action.topic == "ImageProduct"
    assert (product["image_id"], product["file_name"], product["format"]) == (
        "atr-77", "atr-77.xtf", "xtf")
    assert product["size_bytes"] == 5_000_000_000 and product["sha256"] == digest.hex()
    assert product["capture_time_ms"] == 1_700_000_000_000
    (target,) = product["targets"]
    assert target["target_class"] == "mine-like"
    assert target["confidence"] == pytest.approx(0.9, abs=1e-4)
    assert target["latitude"] == pytest.approx(54.3, abs=1e-6)
    assert math.isnan(target["longitude"])
    converter_for(TYPES["ImageProduct"]).to_struct(product, "ImageProduct")


def profile(**extra: object):  # type: ignore[no-untyped-def]
    return from_mapping({"relay": {"jaus_id": "42.1.1"}, **extra}, file="test.toml")


def test_engine_discovers_by_hello_and_subscribes_without_identification() -> None:
    relay = Relay(family(), [TR()])
    relay.advance(0.1)
    relay.actions.clear()
    events = {"uri": "urn:jaus:jss:core:Events", "major_version": 1, "minor_version": 1}
    relay.deliver("60.1.5", "VendorHello", {**HELLO, "services": [*HELLO["services"], events]})
    relay.advance(0.5)
    creates = relay.sent("CreateEvent")
    assert creates and creates[0].destination == JausAddress(60, 1, 5)
    assert CAT.decode(creates[0].fields["query_message"]).name == "QueryOceanEnvironment"
    assert not [a for a in relay.sent("QueryIdentification")
                if a.destination == JausAddress(60, 1, 5)]
    relay.deliver("60.1.5", "ReportOceanEnvironment", {"water_temperature": 12.5})
    (sample,) = relay.published("EnvironmentalData")
    assert sample["vehicle_id"] == "Nemo-60"
    assert sample["water_temperature"] == pytest.approx(12.5, abs=1e-3)


def test_a_hello_without_events_is_polled_at_once() -> None:
    relay = Relay(family(), [TR()])
    relay.advance(0.1)
    relay.actions.clear()
    relay.deliver("60.1.5", "VendorHello", HELLO)  # no Events service listed
    assert not relay.sent("CreateEvent")
    (query,) = relay.sent("QueryOceanEnvironment")
    assert query.destination == JausAddress(60, 1, 5)


def test_static_vehicle_profile_instead_of_discovery() -> None:
    prof = profile(vehicles=[{"vehicle_id": "glider7", "name": "Glider 7", "components": [
        {"address": "61.1.1", "services": [{"uri": OCEAN[0], "version": "1.0"}]}]}])
    relay = Relay(prof, [TR()])
    relay.advance(0.5)
    relay.deliver("61.1.1", "ReportOceanEnvironment", {"salinity": 35.0})
    (sample,) = relay.published("EnvironmentalData")
    assert sample["vehicle_id"] == "glider7"
    assert sample["salinity"] == pytest.approx(35.0, abs=1e-3)


PROFILE = """\
[relay]
jaus_id = "42.1.1"

[[vehicles]]
file = "UUV_PROFILE"

[translators]
enabled = [
  "core",
  "environment",
  "generic",
  "iop",
  "manipulator",
  "mobility",
  "ugv",
  "uuv",
]
"""


def test_removed_by_deleting_one_profile_line(tmp_path: Path) -> None:
    with_uuv = tmp_path / "with.toml"
    text = PROFILE.replace("UUV_PROFILE", str(UUV_PROFILE))
    with_uuv.write_text(text)
    without = tmp_path / "without.toml"
    without.write_text("".join(line for line in text.splitlines(keepends=True)
                               if line.strip() != '"uuv",'))
    assert len(without.read_text().splitlines()) == len(text.splitlines()) - 1

    for path, has_uuv in ((with_uuv, True), (without, False)):
        relay = Relay(load_profile(path))
        names = [t.name for t in relay.engine.manager.translators]
        assert ("uuv" in names) is has_uuv and len(names) == 7 + has_uuv
        relay.advance(0.1)
        relay.deliver("60.1.5", "VendorHello", HELLO)
        relay.advance(0.5)
        # discovery is the profile's: the vehicle is declared either way; its ocean data
        # is the translator's
        assert relay.engine.vehicle("Nemo-60") is not None
        relay.deliver("60.1.5", "ReportOceanEnvironment", {"depth": 12.0})
        assert bool(relay.published("EnvironmentalData")) is has_uuv
        # every other translator still works: a standard vehicle is found and translated
        relay.deliver("77.1.1", "ReportIdentification",
                      {"query_type": 2, "type": 10001, "identification": "Husky"})
        relay.deliver("77.1.1", "ReportServices", {"node_list": [{
            "node_rec": {"node_id": 1}, "component_list": [{
                "component_rec": {"component_id": 1, "instance_id": 0},
                "service_list": [{"uri": "urn:jaus:jss:mobility:GlobalPoseSensor",
                                  "major_version_number": 1, "minor_version_number": 0}]}]}]})
        relay.deliver("77.1.1", "ReportGlobalPose", {"latitude": 1.5, "longitude": 2.5})
        relay.deliver("77.1.1", "ReportOdometry", {"odom": 1, "odometry": 42})
        assert relay.published("GlobalPose")[-1]["vehicle_id"] == "Husky-77"
        assert relay.published("Odometry")[-1]["distance"] == 42.0
        assert relay.published("VehicleIdentification")
