"""The ``uuv`` message set is JSIDL shipped in the package, no Python: JSIDL in, decoded out.

It is read from ``edge_vis/data/jsidl/uuv/`` into ``default_catalogue()``; it must claim no
code any public JSIDL uses, round-trip, lay its bytes out as its JSIDL says, and decode
through ``edge-vis decode``.
"""

from __future__ import annotations

import hashlib
import json
import struct
import sys
from pathlib import Path
from typing import Any

import pytest

from edge_vis import plugins
from edge_vis.catalogue import default_catalogue, shipped_jsidl_sets
from edge_vis.catalogue.jsidl import load_jsidl
from edge_vis.cli import main
from edge_vis.codec.types import MessageDef
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram

TESTS = Path(__file__).resolve().parents[1]
if str(TESTS) not in sys.path:
    sys.path.append(str(TESTS))
from jsidl_walk import load_all  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"

HELLO = {
    "vehicle_name": "Nautilus-3",
    "vehicle_type": 1,
    "jaus_id": {"component": 1, "node": 1, "subsystem": 210},
    "firmware_version": "4.2.0",
    "services": [
        {"uri": "urn:jaus:jss:core:Liveness", "major_version": 1, "minor_version": 1},
        {"uri": "urn:edge-vis:uuv:AtrImageNotifier", "major_version": 1, "minor_version": 0},
    ],
    "bulk_image_port": 9000,
}
IMAGE = b"\xff\xd8 a sonar contact \xff\xd9"
ATR = {
    "image_id": 77,
    "size_bytes": 5_000_000_000,
    "format": 4,
    "sha256": hashlib.sha256(IMAGE).digest(),
    "capture_time": 1_795_000_000_123,
    "target_class": "mine-like",
    "confidence": 0.875,
    "latitude": 36.8508,
    "longitude": -75.9779,
}
OCEAN = {
    "water_temperature": 12.5,
    "salinity": 35.1,
    "depth": 4200.75,
    "current_speed": 0.8,
    "current_direction": -1.2,
    "time_stamp": {"milliseconds": 250, "seconds": 7, "minutes": 3, "hour": 14, "day": 22},
}


def uuv_defs() -> tuple[MessageDef, ...]:
    return tuple(load_jsidl(shipped_jsidl_sets()["uuv"], service_set="uuv"))


def test_shipped_as_jsidl_in_the_package_only() -> None:
    folder = shipped_jsidl_sets()["uuv"]
    assert folder.parent.parent.name == "data" and folder.parent.parent.parent.name == \
        "edge_vis"
    assert not [e for e in plugins.entries(plugins.MESSAGES) if e.name == "uuv"]
    catalogue = default_catalogue()
    for defn in uuv_defs():
        assert catalogue.get(defn.code) == defn
        assert catalogue.source(defn.code) == "shipped JSIDL uuv"
        assert defn.service_set == "uuv"
        assert all(uri.startswith("urn:edge-vis:uuv:") and version == "1.0"
                   for uri, version in defn.services)
    assert {d.name for d in uuv_defs()} == {
        "VendorHello", "QueryOceanEnvironment", "ReportOceanEnvironment",
        "ReportAtrImageAvailable"}


@pytest.mark.skipif(not (SHARED / "jsidl").is_dir(), reason="JSIDL reference not found")
def test_codes_collide_with_no_public_message() -> None:
    public = load_all(((SHARED / "jsidl", "JTS"), (SHARED / "jsidl-iop", "IOP")))
    for defn in uuv_defs():
        assert defn.code not in public, f"0x{defn.code:04X} is also {public[defn.code][0].name}"
        assert 0xD000 <= defn.code <= 0xFFFF, "experimental range"
    codes = {d.name: d.code for d in uuv_defs()}
    # the experimental classes mirror the standard ones: query 0xExxx -> report 0xFxxx
    assert codes["ReportOceanEnvironment"] == codes["QueryOceanEnvironment"] + 0x1000


@pytest.mark.parametrize(("name", "fields"), [
    ("VendorHello", HELLO),
    ("ReportOceanEnvironment", OCEAN),
    ("ReportOceanEnvironment", {"depth": 10.0}),
    ("ReportOceanEnvironment", {}),
    ("ReportAtrImageAvailable", ATR),
    ("ReportAtrImageAvailable", {k: v for k, v in ATR.items()
                                 if k not in ("latitude", "longitude")}),
    ("QueryOceanEnvironment", {"presence_vector": 0x3F}),
])
def test_round_trip(name: str, fields: dict[str, Any]) -> None:
    catalogue = default_catalogue()
    payload = catalogue.encode(name, fields)
    message = catalogue.decode(payload)
    assert message.name == name
    assert list(message.fields) == list(fields)
    for key, value in fields.items():
        if isinstance(value, float):
            assert message.fields[key] == pytest.approx(value, abs=1e-3), key
        else:
            assert message.fields[key] == value, key
    assert catalogue.encode(name, message.fields) == payload


def test_wire_layout_of_vendor_hello() -> None:
    """Byte for byte, as the module documents: a vendor's firmware can be written from it."""
    payload = default_catalogue().encode("VendorHello", HELLO)
    expected = b"".join([
        struct.pack("<H", 0xF0A0),
        b"\x0aNautilus-3", b"\x01",
        bytes([1, 1, 210, 0]),  # JAUS ID 210.1.1 as a little-endian u32
        b"\x054.2.0",
        b"\x02", b"\x1aurn:jaus:jss:core:Liveness\x01\x01",
        b"\x21urn:edge-vis:uuv:AtrImageNotifier\x01\x00",
        struct.pack("<H", 9000),
    ])
    assert payload == expected


def test_wire_layout_of_atr_notice() -> None:
    payload = default_catalogue().encode("ReportAtrImageAvailable", ATR)
    assert payload[:3] == b"\xa2\xf0\x03"  # code, presence vector: latitude and longitude
    assert struct.unpack_from("<IQB", payload, 3) == (77, 5_000_000_000, 4)
    assert payload[16] == 32  # the SHA-256 is a variable_length_field: count, then digest
    assert payload[17:49] == hashlib.sha256(IMAGE).digest()
    assert struct.unpack_from("<Q", payload, 49) == (1_795_000_000_123,)


def test_scaled_fields_keep_a_useful_resolution() -> None:
    """The chosen limits resolve what an oceanographer reads off the instruments."""
    catalogue = default_catalogue()
    fine = {"water_temperature": 3.1415, "salinity": 34.9876, "depth": 10994.123,
            "current_speed": 2.345, "current_direction": 3.0}
    decoded = catalogue.decode(catalogue.encode("ReportOceanEnvironment", fine)).fields
    assert decoded["water_temperature"] == pytest.approx(3.1415, abs=0.001)
    assert decoded["salinity"] == pytest.approx(34.9876, abs=0.001)
    assert decoded["depth"] == pytest.approx(10994.123, abs=1e-5)
    assert decoded["current_speed"] == pytest.approx(2.345, abs=0.001)
    assert decoded["current_direction"] == pytest.approx(3.0, abs=1e-4)


def test_out_of_range_values_are_refused_with_the_field_named() -> None:
    from edge_vis.errors import EncodeError

    with pytest.raises(EncodeError) as caught:
        default_catalogue().encode("ReportOceanEnvironment", {"depth": 12000.0})
    assert "depth" in str(caught.value)


def test_edge_vis_decode_reads_a_datagram_carrying_one(
        capsys: pytest.CaptureFixture[str]) -> None:
    payload = default_catalogue().encode("ReportAtrImageAvailable", ATR)
    datagram = pack_datagram([Packet(destination=JausAddress(42, 1, 1),
                                     source=JausAddress(210, 1, 1), payload=payload,
                                     sequence=9)])
    assert main(["decode", datagram.hex()]) == 0
    (line,) = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.strip()]
    assert line["message_code"] == "0xF0A2"
    assert line["message"] == "ReportAtrImageAvailable"
    assert line["source"] == "210.1.1"
    fields = line["fields"]
    assert fields["sha256"] == hashlib.sha256(IMAGE).hexdigest()
    assert fields["size_bytes"] == 5_000_000_000 and fields["target_class"] == "mine-like"
    assert fields["latitude"] == pytest.approx(36.8508, abs=1e-5)
    assert fields["longitude"] == pytest.approx(-75.9779, abs=1e-5)


def test_generated_bodies_round_trip() -> None:
    """Random bodies from ``tests/strategies.py`` (when it has a per-definition strategy)."""
    try:
        from strategies import fields_for
    except ImportError:
        pytest.skip("tests/strategies.py offers no fields_for")
    from hypothesis import given, settings
    from hypothesis import strategies as st

    catalogue = default_catalogue()
    defs = uuv_defs()

    @settings(max_examples=200, deadline=None)
    @given(st.data())
    def run(data: Any) -> None:
        defn = data.draw(st.sampled_from(defs))
        fields = data.draw(fields_for(defn))
        payload = catalogue.encode(defn.code, fields)
        assert catalogue.decode(payload).fields == fields

    run()
