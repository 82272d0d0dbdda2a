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

* ReportSensorGeometricProperties -> the mounting members of ``SensorInfo``;
* ReportRangeSensorCompressedData -> ``RangeScan``, decompressed (None, DEFLATE, bzip2,
  LZMA: the JSIDL's DataCompressionEnum); a sensor whose data cannot be decompressed or
  decoded is a counted drop with its reason (``Dropped``), the other sensors still go out.
  Asked for instead of ReportRangeSensorData when the profile sets ``range_compression``;
* Report{Visual,DigitalVideo,AnalogVideo,StillImage,Range}SensorConfiguration and
  ConfirmSensorConfiguration -> ``SensorState`` per sensor (configuration as
  ``name=value`` text, the answer to the last Set...SensorConfiguration).

DDS -> JAUS, ``SensorCommand`` by ``action`` (behind control, throttled, as the JSIDL
protocol says: the Set messages and the stream control are accepted only from the client
controlling the service):

* configure -> Set{Visual,DigitalVideo,AnalogVideo,StillImage,Range}SensorConfiguration
  by ``kind``, from ``settings`` (``zoom_level=40, sensor_state=0``: JAUS field names and
  values; an unknown name refuses the command);
* play / pause / stop -> ControlDigitalVideoSensorStream (the stream state asked for is
  published in ``SensorState.stream``: JAUS has no report of it);
* capture -> QueryStillImageData for that sensor: one still image now. The JSIDL lets any
  client query; the relay still sends it as a command, so only the operator holding the
  vehicle triggers (large) images and they are throttled. Periodic stills are the
  profile's ``still_image_rate`` (Hz), off by default.

Which sensors: the JSS queries name sensor IDs and offer no "all sensors" value, so the
relay asks for the IDs in :data:`SENSOR_IDS`; a vehicle answers an unknown ID with an error
record, which is skipped.
"""

from __future__ import annotations

import bz2
import hashlib
import lzma
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from edge_vis.kit import (
    CHUNK_BYTES,
    NAN,
    Action,
    Build,
    Command,
    CommandRule,
    Computed,
    Const,
    Dropped,
    Each,
    From,
    Publish,
    ReportRule,
    ReportSpec,
    RuleTranslator,
    TranslatorContext,
    code_of,
    decode_as,
    describe_rules,
    extract,
    get_path,
    publish_image,
    setting,
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


#: DataCompressionEnum (ReportRangeSensorCompressedData) -> name, decompressor
COMPRESSIONS: dict[int, tuple[str, Callable[[bytes], bytes]]] = {
    0: ("none", bytes),
    1: ("deflate", lambda data: _inflate(data)),
    2: ("bzip2", bz2.decompress),
    3: ("lzma", lzma.decompress),
}
#: what CompressedData holds once decompressed (its JSIDL field_format)
_POINTS = "RangeSensorDataPointList"
_SCAN_POINTS = Each("points", {
    "range": From("range", note="m"), "bearing": From("bearing", note="rad"),
    "inclination": From("inclination", default=0.0, note="rad")})


def _inflate(data: bytes) -> bytes:
    """DEFLATE: a raw stream (RFC 1951), or one in a zlib wrapper (RFC 1950)."""
    try:
        return zlib.decompress(data, -15)
    except zlib.error:
        return zlib.decompress(data)


@dataclass(frozen=True, slots=True)
class EnvironmentOptions:
    """``[translators.environment]``."""

    still_image_rate: float = setting(0.0, ge=0, unit="Hz", doc=(
        "poll every camera for a still image this often; 0 = only when an operator sends "
        "SensorCommand capture"))
    range_compression: str = setting("none", choices=("none", "deflate", "bzip2", "lzma"),
                                     doc=("ask for range scans compressed so "
                                          "(ReportRangeSensorCompressedData); none = plain "
                                          "ReportRangeSensorData"))


# -- configuration: SensorCommand settings <-> Set/Report...SensorConfiguration fields ------

#: kind -> (Set message, service, list field, settings it takes)
CONFIGURABLE: dict[str, tuple[str, str, str, tuple[str, ...]]] = {
    "visual": ("SetVisualSensorConfiguration", VISUAL_SENSOR,
               "visual_sensor_configuration_list",
               ("sensor_state", "zoom_mode", "zoom_level", "focal_length",
                "horizontal_field_of_view", "vertical_field_of_view", "focus_mode",
                "focus_value", "white_balance", "imaging_mode", "exposure_mode",
                "metering_mode", "shutter_speed", "aperture", "light_sensitivity",
                "image_stablization")),
    "digital_video": ("SetDigitalVideoSensorConfiguration", DIGITAL_VIDEO,
                      "digital_video_sensor_list",
                      ("minimum_bit_rate", "maximum_bit_rate", "frame_rate", "frame_size",
                       "digital_format")),
    "analog_video": ("SetAnalogVideoSensorConfiguration", ANALOG_VIDEO,
                     "analog_video_sensor_list", ("analog_format",)),
    "still_image": ("SetStillImageSensorConfiguration", STILL_IMAGE,
                    "still_image_sensor_list", ("frame_size", "still_image_format")),
    "range": ("SetRangeSensorConfiguration", RANGE_SENSOR, "range_sensor_configuration_list",
              ("horizontal_field_of_view_start_angle", "horizontal_field_of_view_stop_angle",
               "vertical_field_of_view_start_angle", "vertical_field_of_view_stop_angle",
               "update_rate", "minimum_range", "maximum_range", "sensor_state")),
}
#: the analog format is not optional in SetAnalogVideoSensorConfiguration
_REQUIRED = {"analog_video": ("analog_format",)}


def parse_settings(kind: str) -> Callable[[Mapping[str, Any]], list[dict[str, Any]]]:
    """Builder: ``settings`` (``"zoom_level=40, sensor_state=0"``) -> the one-sensor list of
    a Set...SensorConfiguration; a name the message does not have, a value that is not a
    number, or nothing to set is a ValueError (the command is refused)."""
    allowed = CONFIGURABLE[kind][3]

    def build(sample: Mapping[str, Any]) -> list[dict[str, Any]]:
        element: dict[str, Any] = {"sensor_id": int(sample.get("sensor_id") or 0)}
        for part in str(sample.get("settings") or "").replace(";", ",").split(","):
            if not part.strip():
                continue
            name, sep, text = (x.strip() for x in part.partition("="))
            if name not in allowed or not sep:
                raise ValueError(f"{name!r} is not a {kind} setting "
                                 f"(settings: {', '.join(allowed)}; write name=value)")
            number = float(text)
            element[name] = int(number) if number.is_integer() else number
        missing = [n for n in _REQUIRED.get(kind, ()) if n not in element]
        if missing or len(element) == 1:
            raise ValueError(f"nothing to set for {kind} sensor (settings: "
                             f"{', '.join(missing or allowed)})")
        return [element]

    return build


def _settings_text(element: Mapping[str, Any]) -> str:
    """A configuration record as ``name=value`` pairs (what SensorCommand takes back)."""
    return ", ".join(f"{k}={_plain(v)}" for k, v in element.items() if k != "sensor_id")


def _plain(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _configuration(kind: str) -> Mapping[str, Any]:
    return {"sensor_id": From("sensor_id"), "kind": Const(kind),
            "configuration": Computed(_settings_text, "every field as name=value")}


def _state(message: str, list_name: str, kind: str, query: str, service: str,
           query_list: str, pv: int | None = 0xFFFF) -> ReportRule:
    rule = _info(message, list_name, _configuration(kind), query, service, query_list, pv)
    return ReportRule(message, "SensorState", rule.fields, query=query, service=service,
                      query_fields=rule.query_fields, rate=rule.rate, on_change=True,
                      split=list_name, keys=("sensor_id", "kind"), merge=True,
                      doc="one sample per sensor and kind; merged with its confirmations")


#: ConfirmSensorConfiguration error record -> the kind of sensor it answers for
ERROR_KINDS = {"range_sensor_error_rec": "range", "visual_sensor_error_rec": "visual",
               "digital_video_sensor_error_rec": "digital_video",
               "analog_video_sensor_error_rec": "analog_video",
               "still_image_sensor_error_rec": "still_image"}


def _confirmation(element: Mapping[str, Any]) -> str:
    """``accepted``, or the error the sensor gave (code and message)."""
    if "sensor_id_rec" in element:
        return "accepted"
    (error,) = element.values()
    code = next((v for k, v in error.items() if k.endswith("error_code")), None)
    text = CONFIRM_ERRORS.get(int(code), f"invalid parameter (code {code})") \
        if code is not None else "error"
    return f"refused: {text}" + (f": {error['error_message']}" if error.get("error_message")
                                 else "")


#: ConfirmSensorConfiguration error codes every sensor kind shares (the others name the
#: parameter: the sensor's error message says which)
CONFIRM_ERRORS = {0: "unknown sensor ID", 255: "unknown error"}
STREAM_STATES = {0: "PLAY", 1: "PAUSE", 2: "STOP"}
_stream_code = code_of(STREAM_STATES)


def _stream(sample: Mapping[str, Any]) -> int:
    action = str(sample.get("action") or "").strip().upper()
    return _stream_code("PLAY" if action == "START" else action)


def _sensor_id(sample: Mapping[str, Any]) -> int:
    return int(sample.get("sensor_id") or 0)


COMMAND_RULES: tuple[CommandRule, ...] = (
    CommandRule("SensorCommand", "ControlDigitalVideoSensorStream", DIGITAL_VIDEO,
                "video_stream",
                {"sensor_id": Build("sensor_id", _sensor_id),
                 "stream_state": Build("action", _stream, "play (start) 0, pause 1, stop 2")},
                when={"action": ("play", "start", "pause", "stop")},
                doc="the state asked for is published in SensorState.stream (JAUS reports "
                    "no stream state)"),
    CommandRule("SensorCommand", "QueryStillImageData", STILL_IMAGE, "still_capture",
                {"query_still_image_data_list": Build(
                    "sensor_id", lambda s: [{"sensor_id": _sensor_id(s),
                                             "report_coordinate_system": 0,
                                             "query_presence_vector": 0}],
                    "one sensor, native coordinates")},
                when={"action": "capture"},
                doc="answered by ReportStillImageData (ImageProduct + ImageData)"),
    *(CommandRule("SensorCommand", message, service, f"sensor_configuration_{kind}",
                  {"request_id_rec.request_id": Build("sensor_id", lambda s: 0,
                                                      "0: confirms are matched by sensor"),
                   list_name: Build("sensor_id, settings", parse_settings(kind),
                                    "one sensor: sensor_id and the name=value settings")},
                  when={"action": "configure", "kind": kind},
                  doc="answered by ConfirmSensorConfiguration")
      for kind, (message, service, list_name, _names) in CONFIGURABLE.items()),
)

_MOUNT = "geometric_properties_variant.*."
GEOMETRY_RULE = ReportRule(
    "ReportSensorGeometricProperties", "SensorInfo",
    {"sensor_id": From("sensor_id_rec.sensor_id"),
     **{f"mount_{axis}": From(f"{_MOUNT}sensor_position.position_vector_element_{i}", note="m")
        for i, axis in enumerate("xyz")},
     **{f"mount_q{axis}": From(f"{_MOUNT}unit_quaternion.unit_quaternion_element_{i}")
        for i, axis in enumerate("wxyz")},
     "mounted_on": Computed(lambda e: _mounted_on(e.get("geometric_properties_variant") or {}),
                            "vehicle | manipulator S.N.C joint n | unknown")},
    query="QuerySensorGeometricProperties", service=VISUAL_SENSOR,
    query_fields={"sensor_id_list": [{"sensor_id": i} for i in SENSOR_IDS]},
    rate=0.2, on_change=True, split="geometric_properties_list", keys=("sensor_id",),
    merge=True, stamp=False, doc="one sample per sensor; merged with its capabilities")


def _mounted_on(variant: Mapping[str, Any]) -> str:
    if "static_geometric_properties_rec" in variant:
        return "vehicle"
    arm = variant.get("manipulator_geometric_properties_rec")
    if arm:
        return (f"manipulator {arm['subsystem_id']}.{arm['node_id']}.{arm['component_id']} "
                f"joint {arm['joint_number']}")
    return "unknown"


COMPRESSED_RULE = ReportRule(
    "ReportRangeSensorCompressedData", "RangeScan",
    {"sensor_id": From("sensor_id"),
     "points": Computed(lambda e: [], "compressed_data decompressed by data_compression, "
                                      "decoded as range_sensor_data_point_list[] (range m, "
                                      "bearing and inclination rad)")},
    query="QueryRangeSensorCompressedData", service=RANGE_SENSOR,
    query_fields={"query_range_sensor_compressed_data_list": [
        {"sensor_id": i, "report_coordinate_system": 0, "data_compression": 1,
         "query_presence_vector": 0} for i in SENSOR_IDS]},
    rate=2.0, doc="instead of ReportRangeSensorData when the profile sets range_compression; "
                  "one sample per sensor; error records skipped; an undecodable one is a "
                  "counted drop")


class EnvironmentTranslator(RuleTranslator):
    """Environment sensing service set -> RangeScan, SensorInfo and image products."""

    name = "environment"
    options_type = EnvironmentOptions
    command_rules = COMMAND_RULES
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
            doc=f"plus ImageData chunks of <= {CHUNK_BYTES} bytes; periodic only with "
                f"still_image_rate, else on SensorCommand capture",
        ),
        GEOMETRY_RULE,
        COMPRESSED_RULE,
        _state("ReportVisualSensorConfiguration", "visual_sensor_configuration_list", "visual",
               "QueryVisualSensorConfiguration", VISUAL_SENSOR,
               "query_visual_sensor_configuration_list"),
        _state("ReportDigitalVideoSensorConfiguration",
               "digital_video_sensor_configuration_list", "digital_video",
               "QueryDigitalVideoSensorConfiguration", DIGITAL_VIDEO,
               "query_digital_video_configuration_list", 0xFF),
        _state("ReportAnalogVideoSensorConfiguration", "analog_video_sensor_configuration_list",
               "analog_video", "QueryAnalogVideoSensorConfiguration", ANALOG_VIDEO, "", None),
        _state("ReportStillImageSensorConfiguration", "still_image_sensor_configuration_list",
               "still_image", "QueryStillImageSensorConfiguration", STILL_IMAGE,
               "query_still_image_sensor_configuration_list", 0xFF),
        _state("ReportRangeSensorConfiguration", "range_sensor_configuration_list", "range",
               "QueryRangeSensorConfiguration", RANGE_SENSOR,
               "range_sensor_configuration_list"),
        ReportRule(
            "ConfirmSensorConfiguration", "SensorState",
            {"sensor_id": From("*.sensor_id"),
             "kind": Computed(lambda e: ERROR_KINDS.get(next(iter(e)), ""),
                              "the error record's kind; accepted: the kind last configured"),
             "confirmation": Computed(_confirmation, "accepted | refused: <error>: "
                                                     "<error_message>")},
            split="confirm_sensor_list", keys=("sensor_id", "kind"), merge=True,
            doc="the answer to the last Set...SensorConfiguration, per sensor"),
    )
    extra_publishes = ("ImageData",)
    not_translated = ()

    @classmethod
    def _derive(cls) -> None:
        super()._derive()
        # mounting of range sensors too; stills and compressed scans only when the
        # profile asks (apply_options)
        geometry = next(s for s in cls.reports if s.report == GEOMETRY_RULE.message)
        cls.reports = (*(s for s in cls.reports
                         if s.report not in ("ReportStillImageData", COMPRESSED_RULE.message)),
                       ReportSpec(geometry.report, geometry.query, RANGE_SENSOR,
                                  dict(geometry.query_fields), geometry.rate,
                                  geometry.on_change))

    def __init__(self) -> None:
        super().__init__()
        #: (vehicle, sensor) -> the kind the last configuration sent to it was for
        self._configured: dict[tuple[str, int], str] = {}

    def apply_options(self, options: EnvironmentOptions) -> None:
        """Poll still images, and ask for compressed scans, as the profile says."""
        reports = list(type(self).reports)
        if options.still_image_rate > 0:
            rule = self._by_message["ReportStillImageData"][0]
            reports.append(ReportSpec(rule.message, rule.query, rule.service,
                                      dict(rule.query_fields), options.still_image_rate))
        if options.range_compression != "none":
            code = next(c for c, (n, _) in COMPRESSIONS.items()
                        if n == options.range_compression)
            plain = next(r for r in reports if r.report == "ReportRangeSensorData")
            reports.remove(plain)
            query = {"query_range_sensor_compressed_data_list": [
                {**q, "data_compression": code}
                for q in COMPRESSED_RULE.query_fields["query_range_sensor_compressed_data_list"]]}
            reports.append(ReportSpec(COMPRESSED_RULE.message, COMPRESSED_RULE.query,
                                      RANGE_SENSOR, query, plain.rate))
        self.reports = tuple(reports)  # type: ignore[misc] - this deployment's choice

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if name == COMPRESSED_RULE.message and ctx.vehicle is not None:
            return self._compressed_scans(fields, ctx)
        if name == "ConfirmSensorConfiguration" and ctx.vehicle is not None:
            return self._confirmations(fields, ctx)
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

    def _compressed_scans(self, fields: Mapping[str, Any],
                          ctx: TranslatorContext) -> list[Action]:
        """One RangeScan per sensor whose data decompresses and decodes; a Dropped (with
        its reason) per one that does not."""
        assert ctx.vehicle is not None
        actions: list[Action] = []
        for element in fields.get("range_sensor_compressed_data_list") or []:
            data = element.get("range_sensor_compressed_data_rec")
            if data is None:  # an error record: the sensor is not active
                continue
            code = int(data["data_compression"])
            name, decompress = COMPRESSIONS.get(code, (f"code {code}", None))
            if decompress is None:
                actions.append(Dropped(f"range compression {name}: not defined by the JSIDL",
                                       f"sensor {data['sensor_id']}"))
                continue
            try:
                points = decode_as(ctx.catalogue, "ReportRangeSensorData", _POINTS,
                                   decompress(bytes(data["compressed_data"])))
            except (ValueError, OSError, EOFError, lzma.LZMAError, zlib.error) as exc:
                actions.append(Dropped(f"range compression {name}: undecodable",
                                       f"sensor {data['sensor_id']}: {exc}"))
                continue
            actions.append(Publish("RangeScan", {
                "vehicle_id": ctx.vehicle.vehicle_id, "sensor_id": data["sensor_id"],
                "points": extract(_SCAN_POINTS, {"points": points}),
                "timestamp_ms": ctx.timestamp_ms}))
        return actions

    def _confirmations(self, fields: Mapping[str, Any],
                       ctx: TranslatorContext) -> list[Action]:
        """SensorState per confirmed sensor: an accepted one carries no kind, so it is the
        kind this relay last configured for that sensor."""
        assert ctx.vehicle is not None
        vehicle = ctx.vehicle.vehicle_id
        actions: list[Action] = []
        for element in fields.get("confirm_sensor_list") or []:
            (record, values), = element.items()
            sensor_id = int(values["sensor_id"])
            kind = ERROR_KINDS.get(record) or self._configured.get((vehicle, sensor_id), "")
            actions.append(Publish("SensorState", self._merged("SensorState", {
                "vehicle_id": vehicle, "sensor_id": sensor_id, "kind": kind,
                "confirmation": _confirmation(element), "timestamp_ms": ctx.timestamp_ms})))
        return actions

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        actions = super().on_sample(topic, sample, ctx)
        for command in actions:  # a confirmation names no kind: remember what was set
            if isinstance(command, Command) and command.kind.startswith("sensor_configuration"):
                kind = str(sample.get("kind", "")).strip().lower()
                self._configured[(command.vehicle_id, _sensor_id(sample))] = kind
        streams = [a for a in actions if isinstance(a, Command)
                   and a.name == "ControlDigitalVideoSensorStream"]
        for command in streams:  # JAUS reports no stream state: say what was asked for
            state = {"vehicle_id": command.vehicle_id,
                     "sensor_id": int(command.fields["sensor_id"]), "kind": "digital_video",
                     "stream": STREAM_STATES[int(command.fields["stream_state"])],
                     "timestamp_ms": ctx.timestamp_ms}
            actions.append(Publish("SensorState", self._merged("SensorState", state)))
        return actions

    def _merged(self, topic: str, sample: dict[str, Any]) -> dict[str, Any]:
        """``sample`` merged into what this topic's instance said before (as ``merge``)."""
        key = (topic, (sample["vehicle_id"], sample["sensor_id"], sample["kind"]))
        merged = self._latest.setdefault(key, {})
        merged.update(sample)
        return dict(merged)

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

