"""The environment translator: range scans, sensor descriptions and still images."""

from __future__ import annotations

import hashlib
import math

import pytest
from rulekit import (
    CAT,
    CTX,
    TYPES,
    check_command_rule,
    check_report_rule,
    command_sample,
    encode,
    same,
)

from edge_vis.dds.convert import converter_for
from edge_vis.errors import ConfigError
from edge_vis.kit.actions import Command, Publish
from translators.environment import CHUNK_BYTES, ENV, EnvironmentTranslator

RULES = EnvironmentTranslator.report_rules


#: compressed scans are decoded by hand (tests below), not by the rule's specs
PLAIN = [r for r in RULES if r.message not in ("ReportRangeSensorCompressedData",
                                                "ConfirmSensorConfiguration")]


@pytest.mark.parametrize("rule", PLAIN, ids=[r.message for r in PLAIN])
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
    (second,) = [a for a in tr.on_message("ReportRangeSensorConfiguration", conf, CTX)
                 if a.topic == "SensorInfo"]
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
    assert {"ImageData", "ImageProduct", "SensorState"} <= set(tr.publishes)
    # stills and compressed scans are asked for only when the profile says so
    assert {s.report for s in tr.reports} == {r.message for r in RULES} - {
        "ReportStillImageData", "ReportRangeSensorCompressedData", "ConfirmSensorConfiguration"}
    assert tr.subscribes == ("SensorCommand",)
    assert set(tr.controlled_services) == {ENV + s for s in (
        "VisualSensor", "DigitalVideo", "AnalogVideo", "StillImage", "RangeSensor")}
    rows = tr.describe()
    assert same(sorted({r["message"] for r in rows if r["direction"] == "jaus->dds"}),
                sorted({r.message for r in RULES}))


# -- sensing control, mounting and compressed scans ------------------------------------------

COMMANDS = EnvironmentTranslator.command_rules
#: per command rule: the SensorCommand that selects it, and the JAUS fields it must give
COMMAND_CASES = {
    "SetVisualSensorConfiguration": (
        {"action": "configure", "kind": "visual", "sensor_id": 2,
         "settings": "zoom_level=40, sensor_state=1; horizontal_field_of_view=0.5"},
        {"visual_sensor_configuration_list": [
            {"sensor_id": 2, "zoom_level": 40, "sensor_state": 1,
             "horizontal_field_of_view": 0.5}]}),
    "SetDigitalVideoSensorConfiguration": (
        {"action": "Configure", "kind": "digital_video", "sensor_id": 1,
         "settings": "frame_rate=15, frame_size=7, digital_format=6"},
        {"digital_video_sensor_list": [
            {"sensor_id": 1, "frame_rate": 15, "frame_size": 7, "digital_format": 6}]}),
    "SetAnalogVideoSensorConfiguration": (
        {"action": "configure", "kind": "analog_video", "sensor_id": 3,
         "settings": "analog_format=2"},
        {"analog_video_sensor_list": [{"sensor_id": 3, "analog_format": 2}]}),
    "SetStillImageSensorConfiguration": (
        {"action": "configure", "kind": "still_image", "sensor_id": 1,
         "settings": "frame_size=5, still_image_format=2"},
        {"still_image_sensor_list": [{"sensor_id": 1, "frame_size": 5,
                                      "still_image_format": 2}]}),
    "SetRangeSensorConfiguration": (
        {"action": "configure", "kind": "range", "sensor_id": 1,
         "settings": "update_rate=5, maximum_range=30.5"},
        {"range_sensor_configuration_list": [{"sensor_id": 1, "update_rate": 5,
                                              "maximum_range": 30.5}]}),
    "ControlDigitalVideoSensorStream": (
        {"action": "pause", "sensor_id": 4}, {"sensor_id": 4, "stream_state": 1}),
    "QueryStillImageData": (
        {"action": "capture", "sensor_id": 2},
        {"query_still_image_data_list": [{"sensor_id": 2, "report_coordinate_system": 0,
                                          "query_presence_vector": 0}]}),
}


def close(a: object, b: object) -> bool:
    """Equal, numbers within a scaled integer's resolution."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(close(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(close(a[k], b[k]) for k in a)
    if isinstance(a, int | float) and isinstance(b, int | float):
        return bool(a == pytest.approx(b, rel=1e-3, abs=1e-4))
    return a == b


@pytest.mark.parametrize("rule", COMMANDS, ids=[r.message for r in COMMANDS])
def test_every_sensor_command_gives_its_jaus_message(rule) -> None:  # type: ignore[no-untyped-def]
    values, want = COMMAND_CASES[rule.message]
    command = check_command_rule(EnvironmentTranslator(), rule, command_sample(rule, **values))
    decoded_fields = CAT.decode(encode(command)).fields or {}
    for key, value in want.items():
        assert close(decoded_fields[key], value), (key, decoded_fields[key], value)
    # the JSIDL accepts these only from the controlling client: sent behind control
    assert rule.service in EnvironmentTranslator.controlled_services


@pytest.mark.parametrize(("stream", "code", "shown"), [
    ("play", 0, "PLAY"), ("start", 0, "PLAY"), ("STOP", 2, "STOP"), ("pause", 1, "PAUSE")])
def test_stream_control_publishes_the_state_asked_for(stream: str, code: int,
                                                      shown: str) -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "sensor_id": 1, "action": stream,
              "kind": "", "settings": ""}
    actions = EnvironmentTranslator().on_sample("SensorCommand", sample, CTX)
    (command,) = [a for a in actions if isinstance(a, Command)]
    assert command.fields["stream_state"] == code
    (state,) = [a.sample for a in actions if isinstance(a, Publish)]
    assert (state["sensor_id"], state["stream"]) == (1, shown)
    converter_for(TYPES["SensorState"]).to_struct(state, "SensorState")


@pytest.mark.parametrize(("kind", "settings", "why"), [
    ("visual", "zoom=3", "'zoom' is not a visual setting"),
    ("visual", "zoom_level", "'zoom_level' is not a visual setting"),
    ("digital_video", "frame_rate=fast", "could not convert"),
    ("analog_video", "", "nothing to set for analog_video sensor"),
    ("range", " , ", "nothing to set for range sensor"),
])
def test_bad_settings_refuse_the_command(kind: str, settings: str, why: str,
                                         caplog: pytest.LogCaptureFixture) -> None:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "sensor_id": 1,
              "action": "configure", "kind": kind, "settings": settings}
    assert EnvironmentTranslator().on_sample("SensorCommand", sample, CTX) == []
    assert why in caplog.text


def test_unknown_action_or_kind_commands_nothing() -> None:
    tr = EnvironmentTranslator()
    for action, kind in (("zoom", "visual"), ("configure", "thermal")):
        sample = {"vehicle_id": "veh1", "operator_id": "op1", "sensor_id": 1,
                  "action": action, "kind": kind, "settings": "zoom_level=1"}
        assert tr.on_sample("SensorCommand", sample, CTX) == []


def test_confirmation_and_configuration_merge_into_sensor_state() -> None:
    tr = EnvironmentTranslator()
    conf = decoded("ReportVisualSensorConfiguration", {"visual_sensor_configuration_list": [
        {"sensor_id": 2, "sensor_state": 0, "zoom_level": 40.0}]})
    states = [a.sample for a in tr.on_message("ReportVisualSensorConfiguration", conf, CTX)
              if a.topic == "SensorState"]
    assert states[0]["kind"] == "visual"
    assert states[0]["configuration"].startswith("sensor_state=0, zoom_level=40")
    configure = {"vehicle_id": "veh1", "operator_id": "op1", "sensor_id": 1,
                 "action": "configure", "kind": "range", "settings": "update_rate=5"}
    assert tr.on_sample("SensorCommand", configure, CTX)  # sensor 1: range was configured
    confirm = decoded("ConfirmSensorConfiguration", {"request_id_rec": {"request_id": 0},
                                                     "confirm_sensor_list": [
        {"sensor_id_rec": {"sensor_id": 1}},
        {"visual_sensor_error_rec": {"sensor_id": 2, "visual_sensor_error_code": 3,
                                     "error_message": "zoom out of range"}}]})
    actions = tr.on_message("ConfirmSensorConfiguration", confirm, CTX)
    by_sensor = {a.sample["sensor_id"]: a.sample for a in actions}
    assert by_sensor[1]["confirmation"] == "accepted" and by_sensor[1]["kind"] == "range"
    assert by_sensor[2]["kind"] == "visual"  # from its error record
    assert by_sensor[2]["confirmation"] == ("refused: invalid parameter (code 3): "
                                            "zoom out of range")
    assert by_sensor[2]["configuration"] == states[0]["configuration"]  # merged, kept
    for sample in by_sensor.values():
        converter_for(TYPES["SensorState"]).to_struct(sample, "SensorState")


def test_geometric_properties_fill_the_mounting_of_sensor_info() -> None:
    tr = EnvironmentTranslator()
    position = {f"position_vector_element_{i}": v for i, v in enumerate((0.5, -0.25, 1.2))}
    quaternion = {f"unit_quaternion_element_{i}": v for i, v in enumerate((1.0, 0, 0, 0))}
    fields = decoded("ReportSensorGeometricProperties", {"geometric_properties_list": [
        {"sensor_id_rec": {"sensor_id": 1}, "geometric_properties_variant": {
            "static_geometric_properties_rec": {"sensor_position": position,
                                                "unit_quaternion": quaternion}}},
        {"sensor_id_rec": {"sensor_id": 2}, "geometric_properties_variant": {
            "manipulator_geometric_properties_rec": {
                "subsystem_id": 150, "node_id": 1, "component_id": 5, "joint_number": 3,
                "sensor_position": position, "unit_quaternion": quaternion}}},
        {"sensor_id_rec": {"sensor_id": 3}, "geometric_properties_variant": {
            "no_geometric_properties_variant": 0}}]})
    actions = tr.on_message("ReportSensorGeometricProperties", fields, CTX)
    by_sensor = {a.sample["sensor_id"]: a.sample for a in actions}
    assert by_sensor[1]["mounted_on"] == "vehicle"
    assert by_sensor[1]["mount_x"] == pytest.approx(0.5, abs=1e-3)
    assert by_sensor[1]["mount_z"] == pytest.approx(1.2, abs=1e-3)
    assert by_sensor[1]["mount_qw"] == pytest.approx(1.0, abs=1e-4)
    assert by_sensor[2]["mounted_on"] == "manipulator 150.1.5 joint 3"
    assert by_sensor[3]["mounted_on"] == "unknown" and math.isnan(by_sensor[3]["mount_x"])
    for sample in by_sensor.values():
        converter_for(TYPES["SensorInfo"]).to_struct(sample, "SensorInfo")


def point_list_bytes(points: list[dict]) -> bytes:  # type: ignore[type-arg]
    """A RangeSensorDataPointList as the JSIDL lays it out (u16 count, then each point's
    u16 presence vector and fields): written here from the JSIDL, not the relay's codec."""
    import struct

    out = struct.pack("<H", len(points))
    for p in points:
        # scaled unsigned 32-bit integers: range over [0, 1e6] m, angles over [-pi, pi]
        rng = round(p["range"] / 1_000_000.0 * 0xFFFFFFFF)
        scale = 2 * math.pi / 0xFFFFFFFF
        bearing = round((p["bearing"] + math.pi) / scale)
        incl = round((p["inclination"] + math.pi) / scale)
        out += struct.pack("<HIII", 0, rng, bearing, incl)
    return out


@pytest.mark.parametrize(("code", "pack"), [
    (0, lambda b: b), (1, lambda b: __import__("zlib").compress(b)),
    (1, lambda b: __import__("zlib").compress(b)[2:-4]),  # raw DEFLATE, no zlib wrapper
    (2, lambda b: __import__("bz2").compress(b)), (3, lambda b: __import__("lzma").compress(b)),
])
def test_compressed_scan_decompresses_into_range_scan(code: int, pack) -> None:  # type: ignore[no-untyped-def]
    points = [{"range": 12.5, "bearing": -0.5, "inclination": 0.1},
              {"range": 40.0, "bearing": 1.0, "inclination": 0.0}]
    stamp = {"milliseconds": 0, "seconds": 0, "minutes": 0, "hour": 0, "day": 1}
    fields = decoded("ReportRangeSensorCompressedData", {"range_sensor_compressed_data_list": [
        {"range_sensor_data_error_rec": {"sensor_id": 2, "data_error_code": 1,
                                         "error_message": "no such format"}},
        {"range_sensor_compressed_data_rec": {
            "sensor_id": 1, "report_coordinate_system": 0, "time_stamp": stamp,
            "data_compression": code, "compressed_data": pack(point_list_bytes(points))}}]})
    actions = EnvironmentTranslator().on_message("ReportRangeSensorCompressedData", fields, CTX)
    (scan,) = [a.sample for a in actions]
    assert scan["sensor_id"] == 1
    for got, want in zip(scan["points"], points, strict=True):
        assert got["range"] == pytest.approx(want["range"], abs=1e-3)
        assert got["bearing"] == pytest.approx(want["bearing"], abs=1e-4)
        assert got["inclination"] == pytest.approx(want["inclination"], abs=1e-4)
    converter_for(TYPES["RangeScan"]).to_struct(scan, "RangeScan")


def test_undecodable_compressed_scan_is_a_counted_drop_with_its_reason() -> None:
    from edge_vis.engine.manager import TranslationManager
    from edge_vis.kit import Dropped

    stamp = {"milliseconds": 0, "seconds": 0, "minutes": 0, "hour": 0, "day": 1}
    good = __import__("zlib").compress(point_list_bytes([{"range": 3.0, "bearing": 0.0,
                                                          "inclination": 0.0}]))
    fields = decoded("ReportRangeSensorCompressedData", {"range_sensor_compressed_data_list": [
        {"range_sensor_compressed_data_rec": {
            "sensor_id": sensor, "report_coordinate_system": 0, "time_stamp": stamp,
            "data_compression": code, "compressed_data": data}}
        for sensor, code, data in ((1, 2, b"not bzip2 at all"), (2, 1, good),
                                   (3, 7, b"x"), (4, 0, b"\x05\x00"))]})
    actions = EnvironmentTranslator().on_message("ReportRangeSensorCompressedData", fields, CTX)
    drops = [a for a in actions if isinstance(a, Dropped)]
    assert [d.reason for d in drops] == ["range compression bzip2: undecodable",
                                         "range compression code 7: not defined by the JSIDL",
                                         "range compression none: undecodable"]
    assert [a.sample["sensor_id"] for a in actions if isinstance(a, Publish)] == [2]
    # the manager counts them per translator and reason, and passes the scan on
    manager = TranslationManager([EnvironmentTranslator()])
    out = manager.on_message("ReportRangeSensorCompressedData", fields, CTX)
    assert [type(a).__name__ for a in out] == ["Publish"]
    assert manager.drops[("environment", "range compression bzip2: undecodable")] == 1
    assert sum(manager.drops.values()) == 3


def test_still_polling_and_compression_are_profile_options() -> None:
    tr = EnvironmentTranslator()
    tr.configure({"still_image_rate": 0.5, "range_compression": "bzip2"})
    reports = {s.report: s for s in tr.reports}
    assert reports["ReportStillImageData"].rate == 0.5
    assert "ReportRangeSensorData" not in reports
    query = reports["ReportRangeSensorCompressedData"].query_fields
    assert {q["data_compression"] for q in query["query_range_sensor_compressed_data_list"]} \
        == {2}
    assert CAT.decode(CAT.encode("QueryRangeSensorCompressedData", query)).name
    with pytest.raises(ConfigError, match="range_compression"):
        EnvironmentTranslator().configure({"range_compression": "zip"})
