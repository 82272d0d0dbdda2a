"""The compiled fast path: the shape of the generated code and its bounds."""

from __future__ import annotations

from codec_defs import REPORT_GLOBAL_POSE, WAYPOINT_LIST

from edge_vis.codec.bodies import compile_message, decode_body, encode_body
from edge_vis.codec.compiler import PV_CACHE_LIMIT
from edge_vis.codec.types import message, opt, u8

FULL_POSE = {
    "latitude": 10.0, "longitude": 20.0, "altitude": 30.0, "position_rms": 1.0, "roll": 0.1,
    "pitch": 0.2, "yaw": 0.3, "attitude_rms": 0.4,
    "time_stamp": {"milliseconds": 1, "seconds": 2, "minutes": 3, "hour": 4, "day": 5},
}


def test_a_full_pose_decodes_with_one_unpack_and_encodes_with_one_pack() -> None:
    body = encode_body(REPORT_GLOBAL_POSE, FULL_POSE)
    decode_body(REPORT_GLOBAL_POSE, body)
    sources = compile_message(REPORT_GLOBAL_POSE).compiler.sources
    (decoder,) = [s for s in sources if s.startswith("def dpv1ff_")]
    (encoder,) = [s for s in sources if s.startswith("def epv1ff_")]
    assert decoder.count("unpack_from") == 1 and "for " not in decoder
    assert encoder.count(".pack(") == 1 and "for " not in encoder
    # scaling is inlined as literals: latitude = raw * (180 / (2**32 - 1)) - 90
    assert f"* {180 / (2**32 - 1)!r} + -90.0" in decoder


def test_a_list_of_fixed_records_decodes_without_a_python_loop_per_field() -> None:
    wp = {"latitude": 1.0, "longitude": 2.0, "altitude": 3.0, "waypoint_tolerance": 4.0}
    decode_body(WAYPOINT_LIST, encode_body(WAYPOINT_LIST, {"elements": [wp] * 3}))
    (top,) = [s for s in compile_message(WAYPOINT_LIST).compiler.sources if "iter_unpack" in s]
    assert top.count("iter_unpack") == 1


def test_specialised_code_per_presence_vector_is_bounded() -> None:
    many = message(0xD0B0, "Many", *(opt(f"f{i}", u8) for i in range(8)), pv=u8,
                   service_set="t")
    for pv in range(256):
        value = {f"f{i}": i for i in range(8) if pv >> i & 1}
        body = encode_body(many, value)
        assert body[0] == pv
        assert decode_body(many, body) == value
    compiler = compile_message(many).compiler
    caches = [v for k, v in compiler.ns.items() if k.startswith(("PVC", "EPC"))]
    assert caches and all(len(cache) == PV_CACHE_LIMIT for cache in caches)
    assert len(compiler.sources) <= 2 * PV_CACHE_LIMIT + 4
    assert compile_message(many).fallbacks == 0
