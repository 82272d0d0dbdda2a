"""Message definitions written for the codec tests with the DSL, following wire-facts d.3.

They are independent of the generated built-in sets on purpose: the golden vectors test the
engine against layouts typed in by hand from the fact sheet.
"""

from __future__ import annotations

import logging
import math

from edge_vis.catalogue import default_catalogue
from edge_vis.codec.types import (
    BitField,
    Enum,
    FixedBytes,
    FixedString,
    JausMessage,
    List,
    MessageDef,
    Scaled,
    SubField,
    VarBytes,
    VarFormat,
    Variant,
    VarString,
    f,
    f32,
    f64,
    i8,
    i16,
    i32,
    i64,
    message,
    opt,
    record,
    u8,
    u16,
    u32,
    u64,
)

log = logging.getLogger(__name__)

TEST = "codec-test"
PI = math.pi

TIME_STAMP = BitField(
    u32,
    (
        SubField("milliseconds", 0, 9),
        SubField("seconds", 10, 15),
        SubField("minutes", 16, 21),
        SubField("hour", 22, 26),
        SubField("day", 27, 31),
    ),
)
DATE_STAMP = BitField(
    u16, (SubField("day", 0, 4), SubField("month", 5, 8), SubField("year", 9, 15))
)

LATITUDE = Scaled(u32, -90, 90, "degree")
LONGITUDE = Scaled(u32, -180, 180, "degree")
ALTITUDE = Scaled(u32, -10000, 35000, "meter")
ANGLE = Scaled(u16, -PI, PI, "radian")

#: mobility ReportGlobalPose 0x4402: PV u16 over nine optional fields
REPORT_GLOBAL_POSE = message(
    0x4402,
    "ReportGlobalPose",
    opt("latitude", LATITUDE),
    opt("longitude", LONGITUDE),
    opt("altitude", ALTITUDE),
    opt("position_rms", Scaled(u32, 0, 100, "meter")),
    opt("roll", ANGLE),
    opt("pitch", ANGLE),
    opt("yaw", ANGLE),
    opt("attitude_rms", Scaled(u16, 0, PI, "radian")),
    opt("time_stamp", TIME_STAMP),
    pv=u16,
    service_set=TEST,
)

LOCAL = Scaled(u32, -100000, 100000, "meter")
#: mobility ReportLocalPose 0x4403: same PV and order as ReportGlobalPose, X/Y/Z for lat/lon/alt
REPORT_LOCAL_POSE = message(
    0x4403,
    "ReportLocalPose",
    opt("x", LOCAL),
    opt("y", LOCAL),
    opt("z", LOCAL),
    opt("position_rms", Scaled(u32, 0, 100, "meter")),
    opt("roll", ANGLE),
    opt("pitch", ANGLE),
    opt("yaw", ANGLE),
    opt("attitude_rms", Scaled(u16, 0, PI, "radian")),
    opt("time_stamp", TIME_STAMP),
    pv=u16,
    service_set=TEST,
)

WAYPOINT = record(
    f("latitude", LATITUDE),
    f("longitude", LONGITUDE),
    f("altitude", ALTITUDE),
    f("waypoint_tolerance", Scaled(u16, 0, 100, "meter")),
    name="WaypointRec",
)
#: a list of fixed-size records (experimental code)
WAYPOINT_LIST = message(
    0xD0A0,
    "WaypointList",
    f("elements", List(u16, WAYPOINT)),
    service_set=TEST,
)

#: core QueryEvents 0x21F0: a variant chosen by a u8 tag
QUERY_EVENTS = message(
    0x21F0,
    "QueryEvents",
    f(
        "query_events_variant",
        Variant(
            u8,
            (
                f("message_id", u16),
                f("event_type", Enum(u8, {0: "Periodic", 1: "Every change"})),
                f("event_id", u8),
                f("all_events", u8),
            ),
        ),
    ),
    service_set=TEST,
)

#: core ReportIdentification 0x4B00: enum, enum, counted string
REPORT_IDENTIFICATION = message(
    0x4B00,
    "ReportIdentification",
    f("query_type", Enum(u8, {1: "System", 2: "Subsystem", 3: "Node", 4: "Component"})),
    f("type", Enum(u16, {10001: "VEHICLE", 20001: "OCU"})),
    f("identification", VarString(u8, 255)),
    service_set=TEST,
)

#: core RejectEventRequest 0x01F4: PV u8, a fixed string as the second optional field
REJECT_EVENT_REQUEST = message(
    0x01F4,
    "RejectEventRequest",
    f("request_id", u8),
    opt("response_code", Enum(u8, {1: "Periodic events not supported"})),
    opt("error_message", FixedString(80)),
    pv=u8,
    service_set=TEST,
)

#: core ReportTime 0x4011: two optional bit fields
REPORT_TIME = message(
    0x4011,
    "ReportTime",
    opt("time_stamp", TIME_STAMP),
    opt("date_stamp", DATE_STAMP),
    pv=u8,
    service_set=TEST,
)

#: core Event 0x41F1: the report is a counted complete message
EVENT = message(
    0x41F1,
    "Event",
    f("event_id", u8),
    f("sequence_number", u8),
    f("report_message", JausMessage(u32)),
    service_set=TEST,
)

#: core SetElement 0x041A: a list of records ending in a variable-format field
SET_ELEMENT = message(
    0x041A,
    "SetElement",
    f("request_id", u8),
    f(
        "element_list",
        List(
            u8,
            record(
                f("element_uid", u16),
                f("previous_uid", u16),
                f("next_uid", u16),
                f("element_data", VarFormat(Enum(u8, {0: "JAUS MESSAGE"}), u16)),
            ),
        ),
    ),
    service_set=TEST,
)

POINT = record(
    opt("point_id", u32),
    f("range", Scaled(u32, 0, 1000000, "meter")),
    opt("range_validity", Enum(u8, {0: "False", 1: "True"})),
    f("bearing", Scaled(u32, -PI, PI, "radian")),
    f("inclination", Scaled(u32, -PI, PI, "radian")),
    pv=u16,
)
#: environment ReportRangeSensorData 0x4803 (cut down): list of variants of nested records
REPORT_RANGE_SENSOR_DATA = message(
    0x4803,
    "ReportRangeSensorData",
    f(
        "range_sensor_data_list",
        List(
            u16,
            Variant(
                u8,
                (
                    f(
                        "range_sensor_data_error_rec",
                        record(
                            f("sensor_id", u16),
                            f("data_error_code", Enum(u8, {0: "Sensor is not Active"})),
                            f("error_message", VarString(u8)),
                        ),
                    ),
                    f(
                        "range_sensor_data_seq",
                        record(
                            f(
                                "range_sensor_data_rec",
                                record(
                                    f("sensor_id", u16),
                                    f("report_coordinate_system", u8),
                                    f("time_stamp", TIME_STAMP),
                                ),
                            ),
                            f("range_sensor_data_point_list", List(u16, POINT)),
                        ),
                    ),
                ),
            ),
        ),
    ),
    service_set=TEST,
)

#: every other primitive, a u32 presence vector and explicit variant tag values
EVERYTHING = message(
    0xD0F0,
    "Everything",
    f("a_u8", u8),
    f("a_u64", u64),
    f("an_i8", i8),
    f("an_i16", i16),
    f("an_i32", i32),
    f("an_i64", i64),
    f("an_f32", f32),
    f("an_f64", f64),
    f("signed_scaled", Scaled(i16, -100, 100)),
    f("raw", FixedBytes(4)),
    opt("blob", VarBytes(u16, "PNG")),
    opt("label", FixedString(6)),
    opt("choice", Variant(u16, (f("small", u8), f("big", u32)), tag_values=(5, 9))),
    opt("nested", record(opt("deep", i8), f("name", VarString(u8, 10)), pv=u8)),
    pv=u32,
    service_set=TEST,
)

ALL: tuple[MessageDef, ...] = (
    REPORT_GLOBAL_POSE,
    REPORT_LOCAL_POSE,
    WAYPOINT_LIST,
    QUERY_EVENTS,
    REPORT_IDENTIFICATION,
    REJECT_EVENT_REQUEST,
    REPORT_TIME,
    EVENT,
    SET_ELEMENT,
    REPORT_RANGE_SENSOR_DATA,
    EVERYTHING,
)


def catalogue_defs() -> list[MessageDef]:
    """Every definition of the default catalogue; [] if it cannot load (tested elsewhere)."""
    try:
        return list(default_catalogue())
    except Exception as exc:  # the catalogue tests report the failure itself
        log.warning("default catalogue did not load: %s", exc)
        return []


def ident(defn: MessageDef) -> str:
    return f"{defn.service_set}-{defn.name}-{defn.code:04X}"
