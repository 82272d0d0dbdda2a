"""Golden vectors worked out by hand from wire-facts d.0/d.3 (and two real captures).

Each case: the bytes a JAUS peer puts on the wire, the dict the engine must decode them
to, and - where the values are exactly representable - the reverse direction.
Scaled reals are written as the value a user means (45 degrees); the raw integer in the
hex is ``round((real - lower) / ((upper - lower) / (2**bits - 1)))``, worked out below.
"""

from __future__ import annotations

import math

import pytest
from codec_defs import (
    EVENT,
    QUERY_EVENTS,
    REJECT_EVENT_REQUEST,
    REPORT_GLOBAL_POSE,
    REPORT_IDENTIFICATION,
    REPORT_LOCAL_POSE,
    REPORT_RANGE_SENSOR_DATA,
    REPORT_TIME,
    SET_ELEMENT,
    WAYPOINT_LIST,
)

from edge_vis.codec.bodies import decode_body, encode_body

LAT_LSB = 180 / (2**32 - 1)
LON_LSB = 360 / (2**32 - 1)
ALT_LSB = 45000 / (2**32 - 1)
ANGLE_LSB = 2 * math.pi / (2**16 - 1)
LOCAL_LSB = 200000 / (2**32 - 1)

# TimeStamp bit field: ms 0-9, s 10-15, min 16-21, hour 22-26, day 27-31 ->
# day 22 11:17:11.320 = 320 | 11<<10 | 17<<16 | 11<<22 | 22<<27 = 0xB2D12D40 -> 40 2d d1 b2
TS = {"milliseconds": 320, "seconds": 11, "minutes": 17, "hour": 11, "day": 22}
TS_HEX = "402dd1b2"


def close(actual: float, expected: float, lsb: float) -> bool:
    return abs(actual - expected) <= lsb


def test_global_pose_with_fields_missing_round_trips() -> None:
    # PV 0x0041 = bit 0 (latitude) + bit 6 (yaw); nothing else on the wire.
    # latitude 0 on [-90, 90] u32: 90 / LSB = 2147483647.5 -> round -> 0x80000000
    # yaw 0 on [-pi, pi] u16: pi / LSB = 32767.5 -> round -> 0x8000
    body = bytes.fromhex("4100" "00000080" "0080")
    assert encode_body(REPORT_GLOBAL_POSE, {"latitude": 0.0, "yaw": 0.0}) == body
    fields = decode_body(REPORT_GLOBAL_POSE, body)
    assert set(fields) == {"latitude", "yaw"}
    assert fields["latitude"] == pytest.approx(90 / (2**32 - 1), rel=1e-9)  # one half LSB
    assert fields["yaw"] == pytest.approx(math.pi / 65535, rel=1e-9)


def test_global_pose_four_fields() -> None:
    # PV 0x0107 = latitude, longitude, altitude, time_stamp
    # 45 deg -> 3221225471.25 -> 0xBFFFFFFF; -45.5 deg -> 0x5FA4FA4F; 100 m -> 0x397530EC
    body = bytes.fromhex("0701" "ffffffbf" "4ffaa45f" "ec307539" + TS_HEX)
    value = {"latitude": 45.0, "longitude": -45.5, "altitude": 100.0, "time_stamp": TS}
    assert encode_body(REPORT_GLOBAL_POSE, value) == body
    fields = decode_body(REPORT_GLOBAL_POSE, body)
    assert list(fields) == ["latitude", "longitude", "altitude", "time_stamp"]
    assert close(fields["latitude"], 45.0, LAT_LSB)
    assert close(fields["longitude"], -45.5, LON_LSB)
    assert close(fields["altitude"], 100.0, ALT_LSB)
    assert fields["time_stamp"] == TS


def test_global_pose_range_ends() -> None:
    body = encode_body(
        REPORT_GLOBAL_POSE, {"latitude": -90.0, "longitude": 180.0, "altitude": 35000.0}
    )
    assert body == bytes.fromhex("0700" "00000000" "ffffffff" "ffffffff")
    fields = decode_body(REPORT_GLOBAL_POSE, body)
    assert fields == {"latitude": -90.0, "longitude": 180.0, "altitude": 35000.0}


def test_global_pose_from_a_jaus_plus_plus_event() -> None:
    # captures-jauspp.md, t=5.053: Event(EventID 0, seq 0) carrying ReportGlobalPose,
    # annotated lat=28.538426 lon=-81.379200 alt=29.999998 yaw=0.499942, day 22 11:17:11.320
    body = bytes.fromhex("0000" "16000000" "0244" "4701178696a8655e2146083f0f395e94" + TS_HEX)
    event = decode_body(EVENT, body)
    assert event["event_id"] == 0 and event["sequence_number"] == 0
    inner = event["report_message"]
    assert inner[:2] == bytes.fromhex("0244")  # 0x4402 little-endian
    pose = decode_body(REPORT_GLOBAL_POSE, inner[2:])
    assert set(pose) == {"latitude", "longitude", "altitude", "yaw", "time_stamp"}
    assert pose["latitude"] == pytest.approx(28.538426, abs=1e-6)
    assert pose["longitude"] == pytest.approx(-81.379200, abs=1e-6)
    assert pose["altitude"] == pytest.approx(29.999998, abs=1e-6)
    assert pose["yaw"] == pytest.approx(0.499942, abs=1e-6)
    assert pose["time_stamp"] == TS
    assert encode_body(REPORT_GLOBAL_POSE, pose) == inner[2:]
    assert encode_body(EVENT, event) == body


def test_local_pose_of_the_jts_example_truncates_but_we_round() -> None:
    # captures.md: the JTS example sends X = Y = 0 as 0x7FFFFFFF (C cast truncates
    # 2147483647.5) and yaw 0 as 0x7FFF. Decoding gives the value those integers mean.
    jts = bytes.fromhex("4300" "ffffff7f" "ffffff7f" "ff7f")
    fields = decode_body(REPORT_LOCAL_POSE, jts)
    assert fields["x"] == pytest.approx(-0.0000233, abs=1e-7)
    assert fields["x"] == pytest.approx(2147483647 * LOCAL_LSB - 100000, rel=1e-12)
    assert fields["y"] == fields["x"]
    assert fields["yaw"] == pytest.approx(-math.pi / 65535, rel=1e-9)
    # the decoded values re-encode to the same integers ...
    assert encode_body(REPORT_LOCAL_POSE, fields) == jts
    # ... while 0.0 itself rounds up, as JSIDL's integer_function="round" asks
    ours = encode_body(REPORT_LOCAL_POSE, {"x": 0.0, "y": 0.0, "yaw": 0.0})
    assert ours == bytes.fromhex("4300" "00000080" "00000080" "0080")


def test_waypoint_list() -> None:
    # count u16 = 2, then two 14-byte records; tolerance 2.5 m on u16 [0, 100] -> 1638 = 0x0666
    body = bytes.fromhex(
        "0200"
        "ffffffbf" "4ffaa45f" "ec307539" "6606"
        "00000000" "ffffffff" "ffffffff" "0000"
    )
    value = {
        "elements": [
            {"latitude": 45.0, "longitude": -45.5, "altitude": 100.0, "waypoint_tolerance": 2.5},
            {"latitude": -90.0, "longitude": 180.0, "altitude": 35000.0, "waypoint_tolerance": 0},
        ]
    }
    assert encode_body(WAYPOINT_LIST, value) == body
    decoded = decode_body(WAYPOINT_LIST, body)["elements"]
    assert len(decoded) == 2
    assert close(decoded[0]["waypoint_tolerance"], 2.5, 100 / 65535)
    assert decoded[1] == {
        "latitude": -90.0, "longitude": 180.0, "altitude": 35000.0, "waypoint_tolerance": 0.0
    }
    assert decode_body(WAYPOINT_LIST, bytes.fromhex("0000")) == {"elements": []}


@pytest.mark.parametrize(
    ("hex_body", "value"),
    [
        ("0300", {"all_events": 0}),  # captures-jauspp.md t=8.071: QueryEvents vtag 3
        ("000244", {"message_id": 0x4402}),
        ("0101", {"event_type": 1}),
        ("0207", {"event_id": 7}),
    ],
)
def test_variant(hex_body: str, value: dict[str, int]) -> None:
    body = bytes.fromhex(hex_body)
    assert decode_body(QUERY_EVENTS, body) == {"query_events_variant": value}
    assert encode_body(QUERY_EVENTS, {"query_events_variant": value}) == body


def test_counted_string_from_the_worked_example() -> None:
    # wire-facts g): ReportIdentification 02 | 11 27 | 10 "SimulatedVehicle"
    body = bytes.fromhex("02" "1127" "10") + b"SimulatedVehicle"
    value = {"query_type": 2, "type": 10001, "identification": "SimulatedVehicle"}
    assert decode_body(REPORT_IDENTIFICATION, body) == value
    assert encode_body(REPORT_IDENTIFICATION, value) == body
    latin = {"query_type": 3, "type": 20001, "identification": "Größe"}
    assert encode_body(REPORT_IDENTIFICATION, latin) == bytes.fromhex("03" "214e" "05") + (
        "Größe".encode("latin-1")
    )


def test_fixed_string_is_nul_padded_and_stripped() -> None:
    # PV 0x02: only the second optional field (error_message, char[80]) is present
    body = bytes.fromhex("02" "07") + b"no such event".ljust(80, b"\x00")
    value = {"request_id": 7, "error_message": "no such event"}
    assert encode_body(REJECT_EVENT_REQUEST, value) == body
    assert decode_body(REJECT_EVENT_REQUEST, body) == value
    both = bytes.fromhex("03" "07" "01") + b"x".ljust(80, b"\x00")
    assert decode_body(REJECT_EVENT_REQUEST, both) == {
        "request_id": 7, "response_code": 1, "error_message": "x"
    }


def test_bit_fields() -> None:
    # DateStamp: day 0-4, month 5-8, year 9-15 (0 = 2000): 2026-11-22 ->
    # 22 | 11<<5 | 26<<9 = 0x3576 -> 76 35
    body = bytes.fromhex("03" + TS_HEX + "7635")
    value = {"time_stamp": TS, "date_stamp": {"day": 22, "month": 11, "year": 26}}
    assert decode_body(REPORT_TIME, body) == value
    assert encode_body(REPORT_TIME, value) == body
    # missing sub-fields encode as 0
    assert encode_body(REPORT_TIME, {"date_stamp": {"year": 1}}) == bytes.fromhex("02" "0002")


def test_variable_format_field_in_a_list() -> None:
    # SetElement: RequestID 1, one element UID 1, prev 0, next 0, format 0 (JAUS message),
    # size u16 4, data = a SetTravelSpeed (0x040A) of raw speed 0x1234
    body = bytes.fromhex("01" "01" "0100" "0000" "0000" "00" "0400" "0a043412")
    value = {
        "request_id": 1,
        "element_list": [
            {
                "element_uid": 1,
                "previous_uid": 0,
                "next_uid": 0,
                "element_data": {"format": 0, "data": bytes.fromhex("0a043412")},
            }
        ],
    }
    assert decode_body(SET_ELEMENT, body) == value
    assert encode_body(SET_ELEMENT, value) == body


def test_nested_records_in_a_list_of_variants() -> None:
    body = bytes.fromhex(
        "0200"  # two list entries
        "00" "0100" "00" "03" "6f6666"  # tag 0: error record, sensor 1, code 0, "off"
        "01" "0200" "01" + TS_HEX  # tag 1: sequence -> record: sensor 2, coords 1, time
        + "0100"  # one point
        "0100" "07000000" "00000000" "00000080" "00000000"  # PV bit0: point_id 7
    )
    decoded = decode_body(REPORT_RANGE_SENSOR_DATA, body)
    entries = decoded["range_sensor_data_list"]
    error = {"sensor_id": 1, "data_error_code": 0, "error_message": "off"}
    assert entries[0] == {"range_sensor_data_error_rec": error}
    seq = entries[1]["range_sensor_data_seq"]
    assert seq["range_sensor_data_rec"] == {
        "sensor_id": 2, "report_coordinate_system": 1, "time_stamp": TS
    }
    (point,) = seq["range_sensor_data_point_list"]
    assert set(point) == {"point_id", "range", "bearing", "inclination"}
    assert point["point_id"] == 7 and point["range"] == 0.0
    assert point["bearing"] == pytest.approx(math.pi / (2**32 - 1), rel=1e-6)
    assert point["inclination"] == -math.pi
    assert encode_body(REPORT_RANGE_SENSOR_DATA, decoded) == body
