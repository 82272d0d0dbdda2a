"""Errors a user can act on: which message, which field, which byte.

Decoding errors are the remote's fault and name the message code, the field path and
the body offset; encoding errors are ours and name the code and the field path.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from codec_defs import (
    EVENT,
    EVERYTHING,
    QUERY_EVENTS,
    REJECT_EVENT_REQUEST,
    REPORT_GLOBAL_POSE,
    REPORT_IDENTIFICATION,
    REPORT_RANGE_SENSOR_DATA,
    REPORT_TIME,
    SET_ELEMENT,
    TIME_STAMP,
    WAYPOINT,
    WAYPOINT_LIST,
)

from edge_vis.codec.bodies import compile_message, compile_type, decode_body, encode_body
from edge_vis.codec.types import List, MessageDef, Record, f, message, opt, u8, u16
from edge_vis.errors import DecodeError, EncodeError

WP = {"latitude": 1.0, "longitude": 2.0, "altitude": 3.0, "waypoint_tolerance": 4.0}
FULL_POSE = {
    "latitude": 10.0, "longitude": 20.0, "altitude": 30.0, "position_rms": 1.0, "roll": 0.1,
    "pitch": 0.2, "yaw": 0.3, "attitude_rms": 0.4,
    "time_stamp": {"milliseconds": 1, "seconds": 2, "minutes": 3, "hour": 4, "day": 5},
}


def decode_error(defn: MessageDef, body: bytes) -> DecodeError:
    with pytest.raises(DecodeError) as info:
        decode_body(defn, body)
    assert info.value.code == defn.code
    return info.value


def encode_error(defn: MessageDef, value: Any) -> EncodeError:
    with pytest.raises(EncodeError) as info:
        encode_body(defn, value)
    assert info.value.code == defn.code
    return info.value


# -- decoding ------------------------------------------------------------------------------


def test_truncated_field_deep_inside_lists_and_variants() -> None:
    # first point: PV 0x0003 -> point_id, range, range_validity, bearing, inclination
    first = "0300" "07000000" "00000000" "01" "00000000" "00000000"
    body = bytes.fromhex(
        "0100" "01" "0200" "01" "00000000"  # one entry, tag 1, sensor 2, coords, time stamp
        "0200" + first + "0000" "00000000" "000000"  # second point cut inside its bearing
    )
    err = decode_error(REPORT_RANGE_SENSOR_DATA, body)
    assert err.path == (
        "range_sensor_data_list[0].range_sensor_data_seq.range_sensor_data_point_list[1].bearing"
    )
    assert err.offset == 12 + 19 + 2 + 4
    assert "0x4803" in str(err) and "point_list[1].bearing" in str(err)
    assert "needs 4 bytes, 3 left" in err.reason


def test_counted_field_of_the_fourth_list_element() -> None:
    element = "0100" "0000" "0000" "00" "0200" "abcd"
    body = bytes.fromhex("07" "04" + element * 3 + "0400" "0000" "0000" "00" "0900" "ab")
    err = decode_error(SET_ELEMENT, body)
    assert err.path == "element_list[3].element_data"
    assert err.offset == 2 + 3 * 11 + 9
    assert "needs 9 bytes, 1 left" in err.reason


def test_list_count_larger_than_the_body_fails_before_reading_elements() -> None:
    err = decode_error(WAYPOINT_LIST, bytes.fromhex("ffff") + bytes(14 * 3))
    assert err.path == "elements" and err.offset == 0
    assert "65535" in err.reason


def test_trailing_bytes() -> None:
    body = encode_body(REPORT_GLOBAL_POSE, FULL_POSE)
    err = decode_error(REPORT_GLOBAL_POSE, body + b"\x00\x01")
    assert err.offset == len(body) == 30 and err.path == ""
    assert "2 bytes left over" in err.reason


def test_presence_vector_bit_without_a_field() -> None:
    # ReportGlobalPose has 9 optional fields: bit 9 announces a field nobody defined
    err = decode_error(REPORT_GLOBAL_POSE, bytes.fromhex("0002") + bytes(4))
    assert err.offset == 0 and "0x200" in err.reason
    # the same inside a list element's record
    body = bytes.fromhex("0100" "01" "0200" "01" "00000000" "0100" "0400") + bytes(12)
    err = decode_error(REPORT_RANGE_SENSOR_DATA, body)
    assert err.path.endswith("range_sensor_data_point_list[0]") and err.offset == 12


def test_unknown_variant_tag() -> None:
    err = decode_error(QUERY_EVENTS, bytes.fromhex("0400"))
    assert err.path == "query_events_variant" and err.offset == 0
    assert "tag 4" in err.reason


def test_embedded_message_too_short_for_a_code() -> None:
    err = decode_error(EVENT, bytes.fromhex("0000" "01000000" "ff"))
    assert err.path == "report_message"


@pytest.mark.parametrize("body", [b"", b"\x02", b"\x02\x11\x27"])
def test_truncated_counted_string(body: bytes) -> None:
    err = decode_error(REPORT_IDENTIFICATION, body)
    assert err.offset == len(body)


def test_decoding_accepts_any_bytes_like_and_returns_bytes() -> None:
    body = bytes.fromhex("0000" "04000000" "0244" "0000")
    for form in (body, bytearray(body), memoryview(body)):
        value = decode_body(EVENT, form)
        assert type(value["report_message"]) is bytes


def test_failed_decodes_are_replayed_by_the_reference_walker() -> None:
    codec = compile_message(REPORT_TIME)
    before = codec.fallbacks
    decode_body(REPORT_TIME, bytes.fromhex("01" "00000000"))
    assert codec.fallbacks == before
    with pytest.raises(DecodeError):
        decode_body(REPORT_TIME, bytes.fromhex("01" "000000"))
    assert codec.fallbacks == before + 1


# -- encoding ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("defn", "value", "path", "words"),
    [
        (REPORT_GLOBAL_POSE, {"latitude": 1.0, "lattitude": 2.0}, "", "unknown fields"),
        (REPORT_GLOBAL_POSE, {**{k: v for k, v in FULL_POSE.items() if k != "roll"},
                              "rol": 0.0}, "", "unknown fields ['rol']"),
        (REJECT_EVENT_REQUEST, {"response_code": 1}, "", "missing mandatory"),
        (WAYPOINT_LIST, {"elements": [WP, {**WP, "latitude": 91.0}]}, "elements[1].latitude",
         "outside the scaled range"),
        (WAYPOINT_LIST, {"elements": [WP, {**WP, "latitude": math.nan}]}, "elements[1].latitude",
         "finite"),
        (REPORT_GLOBAL_POSE, {"yaw": math.inf}, "yaw", "finite"),
        (REPORT_GLOBAL_POSE, {"yaw": "north"}, "yaw", "expected a number"),
        (REPORT_GLOBAL_POSE, {"altitude": None}, "altitude", "expected a number"),
        (REPORT_TIME, {"time_stamp": {"day": 32}}, "time_stamp.day", "bits 27-31"),
        (REPORT_TIME, {"time_stamp": {"days": 3}}, "time_stamp", "unknown sub-fields"),
        (REPORT_TIME, {"time_stamp": {"day": 1.5}}, "time_stamp.day", "expected an integer"),
        (REJECT_EVENT_REQUEST, {"request_id": 1, "error_message": "x" * 81}, "error_message",
         "exceeds 80"),
        (REPORT_IDENTIFICATION, {"query_type": 1, "type": 1, "identification": "a→b"},
         "identification", "latin-1"),
        (REPORT_IDENTIFICATION, {"query_type": 256, "type": 1, "identification": ""},
         "query_type", "outside u8"),
        (REPORT_IDENTIFICATION, {"query_type": 1.0, "type": 1, "identification": ""},
         "query_type", "expected an integer"),
        (REPORT_IDENTIFICATION, {"query_type": 1, "type": 1, "identification": b"x"},
         "identification", "expected a str"),
        (WAYPOINT_LIST, {"elements": "abc"}, "elements", "expected a list"),
        (WAYPOINT_LIST, {"elements": [WP, [1, 2]]}, "elements[1]", "expected a dict"),
        (QUERY_EVENTS, {"query_events_variant": {"event_id": 1, "all_events": 0}},
         "query_events_variant", "exactly one"),
        (QUERY_EVENTS, {"query_events_variant": {"everything": 0}}, "query_events_variant",
         "unknown alternative"),
        (EVENT, {"event_id": 0, "sequence_number": 0, "report_message": b"\x02"},
         "report_message", "2-byte code"),
        (EVENT, {"event_id": 0, "sequence_number": 0, "report_message": "0244"},
         "report_message", "expected bytes"),
        (SET_ELEMENT, {"request_id": 1, "element_list": [
            {"element_uid": 1, "previous_uid": 0, "next_uid": 0,
             "element_data": {"format": 0, "data": b"", "extra": 1}}]},
         "element_list[0].element_data", "unknown keys"),
        (EVERYTHING, {"a_u8": 0, "a_u64": 0, "an_i8": 0, "an_i16": 0, "an_i32": 0, "an_i64": 0,
                      "an_f32": 1e39, "an_f64": 0.0, "signed_scaled": 0.0, "raw": b"1234"},
         "an_f32", "f32"),
        (EVERYTHING, {"a_u8": 0, "a_u64": 0, "an_i8": 0, "an_i16": 0, "an_i32": 0, "an_i64": 0,
                      "an_f32": 0.0, "an_f64": 0.0, "signed_scaled": 0.0, "raw": b"123"},
         "raw", "exactly 4 bytes"),
        (EVERYTHING, {"a_u8": 0, "a_u64": 0, "an_i8": 0, "an_i16": 0, "an_i32": 0, "an_i64": 0,
                      "an_f32": 0.0, "an_f64": 0.0, "signed_scaled": 0.0, "raw": b"1234",
                      "nested": {"name": "x" * 11}}, "nested.name", "maximum 10"),
    ],
)
def test_encode_errors_name_the_field(
    defn: MessageDef, value: dict[str, Any], path: str, words: str
) -> None:
    err = encode_error(defn, value)
    assert err.path == path
    assert words in err.reason
    assert f"0x{defn.code:04X}" in str(err)


def test_list_longer_than_its_count_allows() -> None:
    short_list = message(0xD0A9, "ShortList", f("items", List(u8, u8)), service_set="t")
    assert encode_body(short_list, {"items": [1] * 255})[0] == 255
    err = encode_error(short_list, {"items": [1] * 256})
    assert err.path == "items" and "256" in err.reason


def test_a_field_set_to_none_is_not_absent() -> None:
    err = encode_error(REPORT_TIME, {"time_stamp": None})
    assert err.path == "time_stamp"


# -- definitions ---------------------------------------------------------------------------


def test_broken_definitions_are_refused_when_compiled() -> None:
    nine = tuple(opt(f"f{i}", u8) for i in range(9))
    too_many = message(0xD0AA, "TooMany", *nine, pv=u8, service_set="t")
    with pytest.raises(ValueError, match="9 optional fields do not fit a 8-bit"):
        compile_message(too_many)
    no_pv = message(0xD0AB, "NoPv", opt("a", u8), service_set="t")
    with pytest.raises(ValueError, match="no presence vector"):
        decode_body(no_pv, b"")


# -- the per-type codec --------------------------------------------------------------------


def test_type_codec_decodes_at_an_offset_and_appends() -> None:
    codec = compile_type(List(u16, WAYPOINT))
    out = bytearray(b"head")
    codec.encode([WP, WP], out)
    assert out[:4] == b"head" and len(out) == 4 + 2 + 2 * 14
    value, end = codec.decode(bytes(out) + b"tail", 4)
    assert end == len(out) and len(value) == 2
    assert value[0]["waypoint_tolerance"] == pytest.approx(4.0, abs=100 / 65535)


def test_type_codec_errors_use_absolute_offsets_and_leave_out_untouched() -> None:
    codec = compile_type(Record((f("id", u16), f("stamp", TIME_STAMP))))
    with pytest.raises(DecodeError) as info:
        codec.decode(b"xx" + bytes.fromhex("0100" "0000"), 2)
    assert info.value.path == "stamp" and info.value.offset == 4
    with pytest.raises(DecodeError):
        codec.decode(b"", 5)
    with pytest.raises(DecodeError, match="offset -2"):
        codec.decode(bytes(12), -2)
    out = bytearray(b"keep")
    with pytest.raises(EncodeError) as err:
        codec.encode({"id": 1, "stamp": {"hour": 99}}, out)
    assert err.value.path == "stamp.hour"
    assert out == b"keep"
