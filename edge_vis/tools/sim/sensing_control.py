"""Environment sensing control on a simulated vehicle: what an operator can change. No I/O.

The sensor component of a simulated UGV keeps its sensors' configurations here, so that
Set{Visual,DigitalVideo,StillImage,Range}SensorConfiguration change what the
configuration queries report, and the digital video stream's state. As the JSIDL
protocol says, the Set messages and ControlDigitalVideoSensorStream are obeyed only from
the client controlling the component (anyone else is ignored and counted); each Set is
answered with ConfirmSensorConfiguration, one entry per sensor: accepted, or the error
record of its kind (an unknown sensor; a range update rate above the lidar's 20 Hz). It
also reports the sensors' mounting (QuerySensorGeometricProperties) and range scans
compressed as asked (QueryRangeSensorCompressedData: none, DEFLATE, bzip2 or LZMA).
"""

from __future__ import annotations

import bz2
import lzma
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from edge_vis.codec.bodies import compile_type
from edge_vis.kit.rules import named_type
from edge_vis.tools.sim import components as svc
from edge_vis.tools.sim.outputs import Action, Send

if TYPE_CHECKING:
    from edge_vis.tools.sim.subsystem import Component, SimVehicle

#: the only sensor of each kind on the simulated sensor component
SENSOR = 1
#: the lidar's highest update rate (Hz), as its capabilities say
MAX_UPDATE_RATE = 20.0
STOPPED = 2
#: DataCompressionEnum -> compressor (DEFLATE is a raw RFC 1951 stream)
COMPRESSORS: dict[int, Callable[[bytes], bytes]] = {
    0: bytes,
    1: lambda data: _deflate(data),
    2: bz2.compress,
    3: lzma.compress,
}


def _deflate(data: bytes) -> bytes:
    packer = zlib.compressobj(wbits=-15)
    return packer.compress(data) + packer.flush()


@dataclass
class SensingState:
    """The sensors' current configurations (JAUS fields by kind) and the video stream."""

    configurations: dict[str, dict[str, Any]] = field(default_factory=lambda: {
        "visual": {"sensor_state": 0, "zoom_level": 0.0, "imaging_mode": 1,
                   "horizontal_field_of_view": 1.0, "vertical_field_of_view": 0.75},
        "digital_video": {"frame_rate": 15, "frame_size": 6, "digital_format": 1},
        "still_image": {"frame_size": 5, "still_image_format": 2},
        "range": {"horizontal_field_of_view_start_angle": -1.5707963,
                  "horizontal_field_of_view_stop_angle": 1.5707963, "update_rate": 10.0,
                  "minimum_range": 0.1, "maximum_range": 80.0, "sensor_state": 0},
    })
    #: ControlDigitalVideoSensorStream.stream_state: 0 play, 1 pause, 2 stop
    stream: int = STOPPED


#: Set message -> (kind, its list field, the error record and code field of its kind)
SETTERS: dict[str, tuple[str, str, str, str]] = {
    "SetVisualSensorConfiguration": ("visual", "visual_sensor_configuration_list",
                                     "visual_sensor_error_rec", "visual_sensor_error_code"),
    "SetDigitalVideoSensorConfiguration": ("digital_video", "digital_video_sensor_list",
                                           "digital_video_sensor_error_rec",
                                           "digital_video_error_code"),
    "SetStillImageSensorConfiguration": ("still_image", "still_image_sensor_list",
                                         "still_image_sensor_error_rec",
                                         "still_image_error_code"),
    "SetRangeSensorConfiguration": ("range", "range_sensor_configuration_list",
                                    "range_sensor_error_rec", "range_sensor_error_code"),
}


def _error(kind: str, sensor_id: int, code: int, text: str) -> dict[str, Any]:
    _set, _list, rec, code_field = next(v for v in SETTERS.values() if v[0] == kind)
    return {rec: {"sensor_id": sensor_id, code_field: code, "error_message": text}}


def set_configuration(name: str) -> Callable[..., list[Action]]:
    """The handler of Set...SensorConfiguration ``name``."""
    kind, list_name, _rec, _code = SETTERS[name]

    def handle(vehicle: SimVehicle, comp: Component, source: Any, fields: dict[str, Any],
               now: float) -> list[Action]:
        if not vehicle._commanding(comp, source, name):
            return []
        confirms = []
        for element in fields.get(list_name) or []:
            sensor_id = int(element["sensor_id"])
            if sensor_id != SENSOR:
                confirms.append(_error(kind, sensor_id, 0, "no such sensor"))
            elif kind == "range" and float(element.get("update_rate", 0)) > MAX_UPDATE_RATE:
                confirms.append(_error(kind, sensor_id, 3,
                                       f"update rate above {MAX_UPDATE_RATE:g} Hz"))
            else:
                vehicle.sensing.configurations[kind].update(
                    {k: v for k, v in element.items() if k != "sensor_id"})
                confirms.append({"sensor_id_rec": {"sensor_id": sensor_id}})
        vehicle.counters["sensor_configurations"] += 1
        return [Send(comp.address, source, "ConfirmSensorConfiguration", {
            "request_id_rec": dict(fields["request_id_rec"]), "confirm_sensor_list": confirms})]

    return handle


def control_stream(vehicle: SimVehicle, comp: Component, source: Any, fields: dict[str, Any],
                   now: float) -> list[Action]:
    """ControlDigitalVideoSensorStream: play, pause or stop the camera's stream."""
    if vehicle._commanding(comp, source, "ControlDigitalVideoSensorStream") and \
            int(fields["sensor_id"]) == SENSOR:
        vehicle.sensing.stream = int(fields["stream_state"])
        vehicle.counters["stream_changes"] += 1
    return []


def _configuration(kind: str, list_name: str) -> Callable[..., dict[str, Any]]:
    def build(vehicle: SimVehicle, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {list_name: [{"sensor_id": SENSOR, **vehicle.sensing.configurations[kind]}]}
    return build


def _digital_video_capabilities(vehicle: SimVehicle, comp: Component,
                                fields: dict[str, Any]) -> dict[str, Any]:
    return {"digital_video_sensor_list": [{
        "sensor_id": SENSOR, "minimum_frame_rate": 1, "maximum_frame_rate": 30,
        "supported_frame_sizes": {"qvga_320x240": 1, "vga_640x480": 1},
        "supported_digital_formats": {"mjpeg": 1, "mpeg4_avc_h264": 1}}]}


#: where each sensor sits on the vehicle (m, vehicle frame; unit quaternion w, x, y, z)
MOUNTS = {SENSOR: ((0.0, 0.0, 1.2), (1.0, 0.0, 0.0, 0.0))}


def _geometry(vehicle: SimVehicle, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
    out = []
    for entry in fields.get("sensor_id_list") or [{"sensor_id": SENSOR}]:
        sensor_id = int(entry["sensor_id"])
        mount = MOUNTS.get(sensor_id)
        if mount is None:
            variant: dict[str, Any] = {"no_geometric_properties_variant": 0}
        else:
            variant = {"static_geometric_properties_rec": {
                "sensor_position": {f"position_vector_element_{i}": v
                                    for i, v in enumerate(mount[0])},
                "unit_quaternion": {f"unit_quaternion_element_{i}": v
                                    for i, v in enumerate(mount[1])}}}
        out.append({"sensor_id_rec": {"sensor_id": sensor_id},
                    "geometric_properties_variant": variant})
    return {"geometric_properties_list": out}


def _compressed_scan(vehicle: SimVehicle, comp: Component,
                     fields: dict[str, Any]) -> dict[str, Any]:
    points_type = named_type(vehicle.catalogue.by_name("ReportRangeSensorData").body,
                             "RangeSensorDataPointList")
    out = []
    for query in fields.get("query_range_sensor_compressed_data_list") or []:
        sensor_id, code = int(query["sensor_id"]), int(query["data_compression"])
        if sensor_id != SENSOR or code not in COMPRESSORS:
            out.append({"range_sensor_data_error_rec": {
                "sensor_id": sensor_id, "data_error_code": 255 if sensor_id != SENSOR else 1,
                "error_message": "no such sensor" if sensor_id != SENSOR
                else "unsupported compression"}})
            continue
        encoded = bytearray()
        compile_type(points_type).encode(vehicle.sensors.scan(), encoded)
        out.append({"range_sensor_compressed_data_rec": {
            "sensor_id": sensor_id, "report_coordinate_system": 0,
            "time_stamp": vehicle.sensors.time_stamp(), "data_compression": code,
            "compressed_data": COMPRESSORS[code](bytes(encoded))}})
    return {"range_sensor_compressed_data_list": out}


#: message -> (service, handler), merged into the simulator's command handlers
HANDLERS: dict[str, tuple[str, Callable[..., list[Action]]]] = {
    "SetVisualSensorConfiguration": (svc.VISUAL_SENSOR,
                                     set_configuration("SetVisualSensorConfiguration")),
    "SetDigitalVideoSensorConfiguration": (
        svc.DIGITAL_VIDEO, set_configuration("SetDigitalVideoSensorConfiguration")),
    "SetStillImageSensorConfiguration": (svc.STILL_IMAGE,
                                         set_configuration("SetStillImageSensorConfiguration")),
    "SetRangeSensorConfiguration": (svc.RANGE_SENSOR,
                                    set_configuration("SetRangeSensorConfiguration")),
    "ControlDigitalVideoSensorStream": (svc.DIGITAL_VIDEO, control_stream),
}

#: query -> (service, report, builder), merged into the simulator's queries (the
#: configuration queries replace the fixed ones: they report what was set)
QUERIES: dict[str, tuple[str, str, Callable[..., dict[str, Any] | None]]] = {
    "QueryVisualSensorConfiguration": (svc.VISUAL_SENSOR, "ReportVisualSensorConfiguration",
                                       _configuration("visual",
                                                      "visual_sensor_configuration_list")),
    "QueryDigitalVideoSensorConfiguration": (
        svc.DIGITAL_VIDEO, "ReportDigitalVideoSensorConfiguration",
        _configuration("digital_video", "digital_video_sensor_configuration_list")),
    "QueryDigitalVideoSensorCapabilities": (svc.DIGITAL_VIDEO,
                                            "ReportDigitalVideoSensorCapabilities",
                                            _digital_video_capabilities),
    "QueryStillImageSensorConfiguration": (
        svc.STILL_IMAGE, "ReportStillImageSensorConfiguration",
        _configuration("still_image", "still_image_sensor_configuration_list")),
    "QueryRangeSensorConfiguration": (svc.RANGE_SENSOR, "ReportRangeSensorConfiguration",
                                      _configuration("range",
                                                     "range_sensor_configuration_list")),
    "QuerySensorGeometricProperties": (svc.VISUAL_SENSOR, "ReportSensorGeometricProperties",
                                       _geometry),
    "QueryRangeSensorCompressedData": (svc.RANGE_SENSOR, "ReportRangeSensorCompressedData",
                                       _compressed_scan),
}
