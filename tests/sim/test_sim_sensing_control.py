"""Sensing control on the simulated vehicle: configurations, the video stream, mounting and
compressed scans, obeyed only from the controlling client (sans-I/O, fake clock)."""

from __future__ import annotations

import bz2
import lzma
import zlib

import pytest
from conftest import OTHER, SENSORS, Wire

VISUAL = {"request_id_rec": {"request_id": 9}, "visual_sensor_configuration_list": [
    {"sensor_id": 1, "zoom_level": 40.0, "sensor_state": 1}]}


def test_configuration_is_changed_only_by_the_controller_and_confirmed(wire: Wire) -> None:
    wire.advance(1.0)
    before = wire.query("QueryVisualSensorConfiguration", {
        "query_visual_sensor_configuration_list": [{"sensor_id": 1,
                                                    "query_presence_vector": 0xFFFF}]},
        to=SENSORS).fields["visual_sensor_configuration_list"][0]
    assert before["zoom_level"] == pytest.approx(0.0, abs=0.01)
    # not in control: ignored, nothing confirmed, nothing changed
    assert wire.send("SetVisualSensorConfiguration", VISUAL, to=SENSORS, source=OTHER) == []
    wire.take_control(to=SENSORS)
    confirm = wire.query("SetVisualSensorConfiguration", VISUAL, to=SENSORS)
    assert confirm.name == "ConfirmSensorConfiguration"
    assert confirm.fields["request_id_rec"] == {"request_id": 9}
    assert confirm.fields["confirm_sensor_list"] == [{"sensor_id_rec": {"sensor_id": 1}}]
    after = wire.query("QueryVisualSensorConfiguration", {
        "query_visual_sensor_configuration_list": [{"sensor_id": 1,
                                                    "query_presence_vector": 0xFFFF}]},
        to=SENSORS).fields["visual_sensor_configuration_list"][0]
    assert after["zoom_level"] == pytest.approx(40.0, abs=0.01) and after["sensor_state"] == 1


def test_bad_configurations_are_refused_with_the_error_of_their_kind(wire: Wire) -> None:
    wire.advance(1.0)
    wire.take_control(to=SENSORS)
    confirm = wire.query("SetRangeSensorConfiguration", {
        "request_id_rec": {"request_id": 1}, "range_sensor_configuration_list": [
            {"sensor_id": 1, "update_rate": 50.0}, {"sensor_id": 7, "update_rate": 1.0}]},
        to=SENSORS)
    errors = [e["range_sensor_error_rec"] for e in confirm.fields["confirm_sensor_list"]]
    assert [(e["sensor_id"], e["range_sensor_error_code"]) for e in errors] == [(1, 3), (7, 0)]


def test_stream_control_needs_control(wire: Wire) -> None:
    wire.advance(1.0)
    play = {"sensor_id": 1, "stream_state": 0}
    wire.send("ControlDigitalVideoSensorStream", play, to=SENSORS, source=OTHER)
    assert wire.vehicle.sensing.stream == 2  # stopped: the stranger was ignored
    wire.take_control(to=SENSORS)
    assert wire.send("ControlDigitalVideoSensorStream", play, to=SENSORS) == []
    assert wire.vehicle.sensing.stream == 0


def test_mounting_is_reported(wire: Wire) -> None:
    report = wire.query("QuerySensorGeometricProperties",
                        {"sensor_id_list": [{"sensor_id": 1}, {"sensor_id": 2}]},
                        to=SENSORS).fields["geometric_properties_list"]
    mount = report[0]["geometric_properties_variant"]["static_geometric_properties_rec"]
    assert mount["sensor_position"]["position_vector_element_2"] == pytest.approx(1.2,
                                                                                 abs=1e-3)
    assert "no_geometric_properties_variant" in report[1]["geometric_properties_variant"]


@pytest.mark.parametrize(("code", "unpack"), [
    (0, bytes), (1, lambda b: zlib.decompress(b, -15)), (2, bz2.decompress),
    (3, lzma.decompress)])
def test_compressed_scans_hold_the_plain_scan(wire: Wire, code: int, unpack) -> None:  # type: ignore[no-untyped-def]
    plain = wire.query("QueryRangeSensorData", {"query_range_sensor_data_list": [
        {"sensor_id": 1, "report_coordinate_system": 0, "query_presence_vector": 0}]},
        to=SENSORS).fields["range_sensor_data_list"][0]["range_sensor_data_seq"]
    packed = wire.query("QueryRangeSensorCompressedData", {
        "query_range_sensor_compressed_data_list": [
            {"sensor_id": 1, "report_coordinate_system": 0, "data_compression": code,
             "query_presence_vector": 0}]}, to=SENSORS).fields
    (entry,) = packed["range_sensor_compressed_data_list"]
    data = unpack(entry["range_sensor_compressed_data_rec"]["compressed_data"])
    # the plain report's point list, as it is on the wire, without its message framing
    body = wire.payload("ReportRangeSensorData", {"range_sensor_data_list": [
        {"range_sensor_data_seq": plain}]})
    assert body.endswith(data) and len(data) == 2 + 181 * (2 + 12)
    unsupported = wire.query("QueryRangeSensorCompressedData", {
        "query_range_sensor_compressed_data_list": [
            {"sensor_id": 1, "report_coordinate_system": 0, "data_compression": 9,
             "query_presence_vector": 0}]}, to=SENSORS).fields
    error = unsupported["range_sensor_compressed_data_list"][0]["range_sensor_data_error_rec"]
    assert error["data_error_code"] == 1  # Invalid compression format
