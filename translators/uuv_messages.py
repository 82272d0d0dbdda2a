"""The ``uuv`` message set: what a small underwater vehicle sends that no JSS set covers. No I/O.

Written with the codec DSL and installed through the ``edge_vis.messages`` entry point
(``uuv = "translators.uuv_messages:MESSAGES"``), exactly as a user's own set would be: the
core never imports this module.

Message codes. AS5710 keeps ``0xD000-0xFFFF`` for experimental messages, split like the
standard classes: ``0xDxxx`` commands, ``0xExxx`` queries, ``0xFxxx`` informs, a query
``0xExxx`` being answered by the inform ``0xFxxx`` with the same low 12 bits. The public IOP
JSIDL already uses ``0xD7xx``, ``0xDDxx``, ``0xDExx``, ``0xE7xx``, ``0xEDxx``, ``0xF7xx``,
``0xF9xx``, ``0xFDxx`` and ``0xFFxx``; the standard JSS sets use nothing above ``0x5FFF``.
This set takes the low block ``0x?0Ax`` of each class, which nothing public claims:

======  ===========================  ==============================================
code    message                      service
======  ===========================  ==============================================
F0A0    VendorHello                  urn:edge-vis:uuv:VendorDiscovery 1.0
E0A1    QueryOceanEnvironment        urn:edge-vis:uuv:OceanEnvironmentSensor 1.0
F0A1    ReportOceanEnvironment       urn:edge-vis:uuv:OceanEnvironmentSensor 1.0
F0A2    ReportAtrImageAvailable      urn:edge-vis:uuv:AtrImageNotifier 1.0
======  ===========================  ==============================================

``VendorHello`` is broadcast by vehicles whose firmware does not implement JAUS Discovery
(so a relay still learns their name, JAUS ID, services and the port of their bulk image
channel). ``ReportAtrImageAvailable`` announces an automatic-target-recognition image that
the bulk channel can then fetch and verify against its SHA-256.
"""

from __future__ import annotations

import math

from edge_vis.codec.types import (
    BitField,
    Enum,
    FixedBytes,
    List,
    MessageDef,
    Scaled,
    SubField,
    VarString,
    f,
    message,
    opt,
    record,
    u8,
    u16,
    u32,
    u64,
)

SET = "uuv"
VERSION = "1.0"
DISCOVERY = ("urn:edge-vis:uuv:VendorDiscovery", VERSION)
ENVIRONMENT = ("urn:edge-vis:uuv:OceanEnvironmentSensor", VERSION)
ATR = ("urn:edge-vis:uuv:AtrImageNotifier", VERSION)

VEHICLE_TYPE = Enum(u8, {0: "UNKNOWN", 1: "AUV", 2: "ROV", 3: "GLIDER", 4: "USV",
                         5: "HYBRID"})

#: the JAUS ID as AS5710 lays it out in a u32 (subsystem . node . component)
JAUS_ID = BitField(u32, (SubField("component", 0, 7), SubField("node", 8, 15),
                         SubField("subsystem", 16, 31)))

#: the JSS TimeStamp bit field (UTC day of month, hour, minute, second, millisecond)
TIME_STAMP = BitField(u32, (SubField("milliseconds", 0, 9), SubField("seconds", 10, 15),
                            SubField("minutes", 16, 21), SubField("hour", 22, 26),
                            SubField("day", 27, 31)))

IMAGE_FORMAT = Enum(u8, {0: "JPEG", 1: "PNG", 2: "TIFF", 3: "GEOTIFF", 4: "RAW_SONAR",
                         5: "XTF", 6: "RAW_CAMERA"})

SERVICE = record(
    f("uri", VarString(u8)),
    f("major_version", u8),
    f("minor_version", u8),
    name="ServiceRec",
)

VENDOR_HELLO = message(
    0xF0A0, "VendorHello",
    f("vehicle_name", VarString(u8)),
    f("vehicle_type", VEHICLE_TYPE),
    f("jaus_id", JAUS_ID),
    f("firmware_version", VarString(u8)),
    f("services", List(u8, SERVICE, name="ServiceList")),
    # 0 when the vehicle offers no bulk image channel
    f("bulk_image_port", u16),
    service_set=SET, services=(DISCOVERY,),
    doc="Unsolicited announcement of a vehicle that does not implement JAUS Discovery.",
)

QUERY_OCEAN_ENVIRONMENT = message(
    0xE0A1, "QueryOceanEnvironment",
    f("presence_vector", u8),
    service_set=SET, services=(ENVIRONMENT,),
    doc="Asks for ReportOceanEnvironment; the presence vector selects the fields.",
)

REPORT_OCEAN_ENVIRONMENT = message(
    0xF0A1, "ReportOceanEnvironment",
    # 0.00076 degC resolution over the liquid-sea-water range
    opt("water_temperature", Scaled(u16, -5.0, 45.0, "degree Celsius")),
    # practical salinity; 0.00076 PSU resolution
    opt("salinity", Scaled(u16, 0.0, 50.0, "PSU")),
    # full-ocean depth to 11 km, negative above the surface; 2.6 um resolution
    opt("depth", Scaled(u32, -100.0, 11000.0, "meter")),
    opt("current_speed", Scaled(u16, 0.0, 10.0, "meter per second")),
    # direction the current flows towards, from true north, clockwise
    opt("current_direction", Scaled(u16, -math.pi, math.pi, "radian")),
    opt("time_stamp", TIME_STAMP),
    pv=u8, service_set=SET, services=(ENVIRONMENT,),
    doc="Water properties measured by the vehicle.",
)

REPORT_ATR_IMAGE_AVAILABLE = message(
    0xF0A2, "ReportAtrImageAvailable",
    f("image_id", u32),
    f("size_bytes", u64),
    f("format", IMAGE_FORMAT),
    f("sha256", FixedBytes(32)),
    # milliseconds since 1970-01-01T00:00:00Z
    f("capture_time", u64),
    f("target_class", VarString(u8)),
    f("confidence", Scaled(u16, 0.0, 1.0)),
    opt("latitude", Scaled(u32, -90.0, 90.0, "degree")),
    opt("longitude", Scaled(u32, -180.0, 180.0, "degree")),
    pv=u8, service_set=SET, services=(ATR,),
    doc="An ATR image is ready on the bulk channel.",
)

MESSAGES: tuple[MessageDef, ...] = (
    VENDOR_HELLO,
    QUERY_OCEAN_ENVIRONMENT,
    REPORT_OCEAN_ENVIRONMENT,
    REPORT_ATR_IMAGE_AVAILABLE,
)
