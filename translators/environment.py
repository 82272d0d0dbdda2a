"""The ``environment`` translator (AS6060 environment sensing): scans, sensors, still images.

No I/O. JAUS -> DDS:

* ReportRangeSensorData -> one ``RangeScan`` per sensor (range m, bearing and inclination
  rad); a sensor's error record is skipped;
* Report{Range,Visual,StillImage,DigitalVideo,AnalogVideo}Sensor{Capabilities,Configuration}
  -> ``SensorInfo`` per sensor, merged: capabilities give name, ranges and rates, the
  configuration the current field of view;
* ReportStillImageData -> an image product: one ``ImageProduct`` (metadata, SHA-256) and
  the image bytes as ``ImageData`` chunks of at most :data:`CHUNK_BYTES` (an image is a
  large JAUS message, reassembled by the router before it gets here).

DDS -> JAUS: none (these services only report).

Which sensors: the JSS queries name sensor IDs and offer no "all sensors" value, so the
relay asks for the IDs in :data:`SENSOR_IDS`; a vehicle answers an unknown ID with an error
record, which is skipped.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    CHUNK_BYTES,
    NAN,
    Action,
    Computed,
    Const,
    Each,
    From,
    ReportRule,
    RuleTranslator,
    TranslatorContext,
    describe_rules,
    get_path,
    publish_image,
)

ENV = "urn:jaus:jss:environmentSensing:"
RANGE_SENSOR = ENV + "RangeSensor"
VISUAL_SENSOR = ENV + "VisualSensor"
STILL_IMAGE = ENV + "StillImage"
DIGITAL_VIDEO = ENV + "DigitalVideo"
ANALOG_VIDEO = ENV + "AnalogVideo"

#: sensor IDs the relay asks every sensing component about
SENSOR_IDS: tuple[int, ...] = (1, 2, 3, 4)

#: StillImage formats (ReportStillImageData.image_frame format) -> file extension
IMAGE_FORMATS = {0: "jpeg", 1: "gif", 2: "png", 3: "bmp", 4: "tiff", 5: "ppm", 6: "pgm",
                 7: "pnm", 8: "nef", 9: "cr2", 10: "dng"}


def _span(start: str, stop: str) -> Computed:
    """Field of view = stop angle - start angle (NaN when either is absent)."""

    def fov(e: Mapping[str, Any]) -> float:
        a, b = e.get(start), e.get(stop)
        return NAN if a is None or b is None else abs(float(b) - float(a))

    return Computed(fov, f"{stop} - {start}")


def _sensors(list_name: str, pv: int = 0xFFFF) -> dict[str, Any]:
    return {list_name: [{"sensor_id": i, "query_presence_vector": pv} for i in SENSOR_IDS]}


def _sha(e: Mapping[str, Any]) -> str:
    data = get_path(e, "image_frame.data") or b""
    return hashlib.sha256(data).hexdigest()


def _image_id(e: Mapping[str, Any]) -> str:
    return f"still-{e.get('sensor_id', 0)}-{_sha(e)[:16]}"


def _extension(e: Mapping[str, Any]) -> str:
    return IMAGE_FORMATS.get(int(get_path(e, "image_frame.format", -1)), "bin")


_RANGE_CAPS = {
    "sensor_id": From("sensor_id"), "name": From("sensor_name", default=""),
    "kind": Const("range"),
    "min_range": From("minimum_range", note="m"), "max_range": From("maximum_range", note="m"),
    "horizontal_fov": _span("minimum_horizontal_field_of_view_start_angle",
                            "maximum_horizontal_field_of_view_stop_angle"),
    "vertical_fov": _span("minimum_vertical_field_of_view_start_angle",
                          "maximum_vertical_field_of_view_stop_angle"),
    "update_rate_hz": From("maximum_update_rate", note="Hz"),
}
_RANGE_CONF = {
    "sensor_id": From("sensor_id"),
    "min_range": From("minimum_range", note="m"), "max_range": From("maximum_range", note="m"),
    "horizontal_fov": _span("horizontal_field_of_view_start_angle",
                            "horizontal_field_of_view_stop_angle"),
    "vertical_fov": _span("vertical_field_of_view_start_angle",
                          "vertical_field_of_view_stop_angle"),
    "update_rate_hz": From("update_rate", note="Hz"),
}


def _info(message: str, list_name: str, fields: Mapping[str, Any], query: str, service: str,
          query_list: str, pv: int | None = 0xFFFF) -> ReportRule:
    query_fields = ({"sensor_id_list": [{"sensor_id": i} for i in SENSOR_IDS]} if pv is None
                    else _sensors(query_list, pv))
    return ReportRule(message, "SensorInfo", fields, query=query, service=service,
                      query_fields=query_fields, rate=0.2, on_change=True, split=list_name,
                      keys=("sensor_id",), merge=True, stamp=False,
                      doc="one sample per sensor; merged with the sensor's other reports")


class EnvironmentTranslator(RuleTranslator):
    """Environment sensing service set -> RangeScan, SensorInfo and image products."""

    name = "environment"
    report_rules = (
        ReportRule(
            "ReportRangeSensorData", "RangeScan",
            {"sensor_id": From("range_sensor_data_seq.range_sensor_data_rec.sensor_id"),
             "points": Each("range_sensor_data_seq.range_sensor_data_point_list", {
                 "range": From("range", note="m"), "bearing": From("bearing", note="rad"),
                 "inclination": From("inclination", default=0.0, note="rad")})},
            query="QueryRangeSensorData", service=RANGE_SENSOR,
            query_fields={"query_range_sensor_data_list": [
                {"sensor_id": i, "report_coordinate_system": 0, "query_presence_vector": 0}
                for i in SENSOR_IDS]},
            rate=2.0, split="range_sensor_data_list", require="range_sensor_data_seq",
            doc="one sample per sensor; error records skipped",
        ),
        _info("ReportRangeSensorCapabilities", "range_sensor_capabilities_list", _RANGE_CAPS,
              "QueryRangeSensorCapabilities", RANGE_SENSOR, "range_sensor_capabilities_list"),
        _info("ReportRangeSensorConfiguration", "range_sensor_configuration_list", _RANGE_CONF,
              "QueryRangeSensorConfiguration", RANGE_SENSOR, "range_sensor_configuration_list"),
        _info("ReportVisualSensorCapabilities", "visual_sensor_capabilities_list",
              {"sensor_id": From("sensor_id"), "name": From("sensor_name", default=""),
               "kind": Const("visual")},
              "QueryVisualSensorCapabilities", VISUAL_SENSOR,
              "query_visual_sensor_capabilities_list"),
        _info("ReportVisualSensorConfiguration", "visual_sensor_configuration_list",
              {"sensor_id": From("sensor_id"),
               "horizontal_fov": From("horizontal_field_of_view", convert=abs, note="rad"),
               "vertical_fov": From("vertical_field_of_view", convert=abs, note="rad")},
              "QueryVisualSensorConfiguration", VISUAL_SENSOR,
              "query_visual_sensor_configuration_list"),
        _info("ReportStillImageSensorCapabilities", "still_image_sensor_list",
              {"sensor_id": From("sensor_id"), "kind": Const("still_image")},
              "QueryStillImageSensorCapabilities", STILL_IMAGE,
              "query_still_image_sensor_capabilities_list", 0xFF),
        _info("ReportDigitalVideoSensorCapabilities", "digital_video_sensor_list",
              {"sensor_id": From("sensor_id"), "kind": Const("digital_video"),
               "update_rate_hz": From("maximum_frame_rate", convert=float, note="frames/s")},
              "QueryDigitalVideoSensorCapabilities", DIGITAL_VIDEO,
              "query_digital_video_sensor_capabilities_list", 0xFF),
        _info("ReportDigitalVideoSensorConfiguration", "digital_video_sensor_configuration_list",
              {"sensor_id": From("sensor_id"),
               "update_rate_hz": From("frame_rate", convert=float, note="frames/s")},
              "QueryDigitalVideoSensorConfiguration", DIGITAL_VIDEO,
              "query_digital_video_configuration_list", 0xFF),
        _info("ReportAnalogVideoSensorCapabilities", "analog_video_sensor_capabilities_list",
              {"sensor_id": From("sensor_id"), "kind": Const("analog_video")},
              "QueryAnalogVideoSensorCapabilities", ANALOG_VIDEO, "", None),
        ReportRule(
            "ReportStillImageData", "ImageProduct",
            {"image_id": Computed(_image_id, "still-<sensor_id>-<sha256 prefix>"),
             "file_name": Computed(lambda e: f"{_image_id(e)}.{_extension(e)}",
                                   "<image_id>.<format>"),
             "size_bytes": Computed(lambda e: len(get_path(e, "image_frame.data") or b""),
                                    "len(image_frame.data)"),
             "sha256": Computed(_sha, "sha256(image_frame.data)"),
             "format": Computed(_extension, "image_frame.format"),
             "capture_time_ms": Computed(lambda e: 0, "relay reception time (the JAUS "
                                                      "TimeStamp has no date)")},
            query="QueryStillImageData", service=STILL_IMAGE,
            query_fields={"query_still_image_data_list": [
                {"sensor_id": i, "report_coordinate_system": 0, "query_presence_vector": 0}
                for i in SENSOR_IDS]},
            rate=0.05, split="still_image_data_list", require="image_frame", stamp=False,
            doc=f"plus ImageData chunks of <= {CHUNK_BYTES} bytes",
        ),
    )
    extra_publishes = ("ImageData",)
    not_translated = (
        ("ReportRangeSensorCompressedData", "compressed scans: decompression not implemented"),
        ("ReportSensorGeometricProperties", "sensor mounting has no topic in the data model"),
        ("ReportAnalogVideoSensorConfiguration", "analog video formats only; no DDS meaning"),
        ("ReportStillImageSensorConfiguration", "frame size and format: in ImageProduct"),
        ("ControlDigitalVideoSensorStream", "video streams are not carried over DDS"),
        ("SetRangeSensorConfiguration", "sensor configuration is not commanded over DDS"),
        ("SetVisualSensorConfiguration", "sensor configuration is not commanded over DDS"),
    )

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if name != "ReportStillImageData" or ctx.vehicle is None:
            return super().on_message(name, fields, ctx)
        (rule,) = self._by_message[name]
        actions: list[Action] = []
        elements = [e for e in fields.get("still_image_data_list") or []
                    if get_path(e, "image_frame.data") is not None]
        for element, product in zip(elements, self.samples(rule, fields, ctx), strict=True):
            actions.extend(publish_image(product,
                                         bytes(get_path(element, "image_frame.data"))))
        return actions

    def samples(self, rule: ReportRule, fields: Mapping[str, Any],
                ctx: TranslatorContext) -> list[dict[str, Any]]:
        out = super().samples(rule, fields, ctx)
        if rule.message == "ReportStillImageData":  # stamped on arrival: TimeStamp has no date
            for product in out:
                product["capture_time_ms"] = ctx.timestamp_ms
        return out

    def describe(self) -> list[dict[str, Any]]:
        rows = super().describe()
        rule = ReportRule(
            "ReportStillImageData", "ImageData",
            {"image_id": Computed(_image_id, "as ImageProduct"),
             "chunk_index": Computed(lambda e: 0, "0 .. chunk_count-1"),
             "chunk_count": Computed(lambda e: 0, f"ceil(size / {CHUNK_BYTES})"),
             "data": From("image_frame.data", note=f"<= {CHUNK_BYTES} bytes per chunk")})
        return rows + describe_rules(self.name, (rule,), ())

