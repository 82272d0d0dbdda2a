"""The environment translator: range scans, sensor descriptions and still images."""

from __future__ import annotations

import hashlib
import math

import pytest
from rulekit import CAT, CTX, TYPES, check_report_rule, same

from edge_vis.dds.convert import converter_for
from edge_vis.kit.actions import Publish
from translators.environment import CHUNK_BYTES, EnvironmentTranslator

RULES = EnvironmentTranslator.report_rules


@pytest.mark.parametrize("rule", RULES, ids=[r.message for r in RULES])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(EnvironmentTranslator(), rule) > 0


def decoded(name: str, fields: dict) -> dict:  # type: ignore[type-arg]
    message = CAT.decode(CAT.encode(name, fields))
    return message.fields or {}


def test_range_data_one_scan_per_sensor_errors_skipped() -> None:
    fields = decoded("ReportRangeSensorData", {"range_sensor_data_list": [
        {"range_sensor_data_error_rec": {"sensor_id": 1, "data_error_code": 0,
                                         "error_message": "off"}},
        {"range_sensor_data_seq": {
            "range_sensor_data_rec": {"sensor_id": 2, "report_coordinate_system": 0,
                                      "time_stamp": {"milliseconds": 0, "seconds": 0,
                                                     "minutes": 0, "hour": 0, "day": 1}},
            "range_sensor_data_point_list": [
                {"range": 12.5, "bearing": -0.5, "inclination": 0.1},
                # the JSIDL limits: 1000 km range, bearing -pi
                {"range": 1_000_000.0, "bearing": -math.pi, "inclination": math.pi},
            ]}},
    ]})
    actions = EnvironmentTranslator().on_message("ReportRangeSensorData", fields, CTX)
    assert [a.topic for a in actions] == ["RangeScan"]
    scan = actions[0].sample
    assert scan["sensor_id"] == 2 and scan["timestamp_ms"] == CTX.timestamp_ms
    want = [(12.5, -0.5, 0.1), (1_000_000.0, -math.pi, math.pi)]
    for point, (r, b, i) in zip(scan["points"], want, strict=True):
        assert point["range"] == pytest.approx(r, abs=1e-3)
        assert point["bearing"] == pytest.approx(b, abs=1e-6)
        assert point["inclination"] == pytest.approx(i, abs=1e-6)
    converter_for(TYPES["RangeScan"]).to_struct(scan, "RangeScan")


def test_sensor_info_merges_capabilities_and_configuration() -> None:
    tr = EnvironmentTranslator()
    caps = decoded("ReportRangeSensorCapabilities", {"range_sensor_capabilities_list": [{
        "sensor_id": 3, "sensor_name": "front lidar",
        "minimum_horizontal_field_of_view_start_angle": -1.5,
        "maximum_horizontal_field_of_view_stop_angle": 1.5,
        "maximum_update_rate": 20.0, "minimum_range": 0.1, "maximum_range": 80.0}]})
    (first,) = tr.on_message("ReportRangeSensorCapabilities", caps, CTX)
    assert first.sample["name"] == "front lidar" and first.sample["kind"] == "range"
    assert first.sample["horizontal_fov"] == pytest.approx(3.0, abs=1e-6)
    assert math.isnan(first.sample["vertical_fov"])  # not reported: NaN, never 0
    conf = decoded("ReportRangeSensorConfiguration", {"range_sensor_configuration_list": [{
        "sensor_id": 3, "horizontal_field_of_view_start_angle": -0.5,
        "horizontal_field_of_view_stop_angle": 0.5}]})
    (second,) = tr.on_message("ReportRangeSensorConfiguration", conf, CTX)
    merged = second.sample
    assert merged["name"] == "front lidar"  # kept from the capabilities
    assert merged["horizontal_fov"] == pytest.approx(1.0, abs=1e-6)
    assert merged["max_range"] == pytest.approx(80.0, abs=1e-3)
    converter_for(TYPES["SensorInfo"]).to_struct(merged, "SensorInfo")


def test_still_image_becomes_a_product_and_bus_sized_chunks() -> None:
    data = bytes(range(256)) * 300  # 76800 bytes: three chunks
    fields = decoded("ReportStillImageData", {"still_image_data_list": [
        {"sensor_id": 4, "report_coordinate_system": 0,
         "image_frame": {"format": 2, "data": data}}]})
    actions = EnvironmentTranslator().on_message("ReportStillImageData", fields, CTX)
    products = [a.sample for a in actions if a.topic == "ImageProduct"]
    chunks = [a.sample for a in actions if a.topic == "ImageData"]
    assert len(products) == 1 and all(isinstance(a, Publish) for a in actions)
    product = products[0]
    digest = hashlib.sha256(data).hexdigest()
    assert product["sha256"] == digest and product["size_bytes"] == len(data)
    assert product["format"] == "png" and product["file_name"].endswith(".png")
    assert product["image_id"] == f"still-4-{digest[:16]}"
    assert product["capture_time_ms"] == CTX.timestamp_ms
    assert [c["chunk_index"] for c in chunks] == [0, 1, 2]
    assert {c["chunk_count"] for c in chunks} == {3}
    assert all(len(c["data"]) <= CHUNK_BYTES for c in chunks)
    assert b"".join(c["data"] for c in chunks) == data
    converter_for(TYPES["ImageProduct"]).to_struct(product, "ImageProduct")
    for chunk in chunks:
        converter_for(TYPES["ImageData"]).to_struct(chunk, "ImageData")


def test_empty_image_is_one_empty_chunk() -> None:
    fields = decoded("ReportStillImageData", {"still_image_data_list": [
        {"sensor_id": 1, "report_coordinate_system": 0,
         "image_frame": {"format": 0, "data": b""}}]})
    actions = EnvironmentTranslator().on_message("ReportStillImageData", fields, CTX)
    chunks = [a.sample for a in actions if a.topic == "ImageData"]
    assert [(c["chunk_index"], c["chunk_count"], c["data"]) for c in chunks] == [(0, 1, b"")]


def test_no_vehicle_no_samples() -> None:
    from dataclasses import replace

    fields = decoded("ReportRangeSensorCapabilities", {"range_sensor_capabilities_list": [
        {"sensor_id": 1, "sensor_name": "x"}]})
    assert EnvironmentTranslator().on_message(
        "ReportRangeSensorCapabilities", fields, replace(CTX, vehicle=None)) == []


def test_declarations() -> None:
    tr = EnvironmentTranslator()
    assert {"ImageData", "ImageProduct"} <= set(tr.publishes)
    assert {s.report for s in tr.reports} == {r.message for r in RULES}
    assert tr.subscribes == () and tr.controlled_services == ()
    rows = tr.describe()
    assert same(sorted({r["message"] for r in rows if r["direction"] == "jaus->dds"}),
                sorted({r.message for r in RULES}))
