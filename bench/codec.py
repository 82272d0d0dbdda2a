"""Codec throughput: the generic engine against a hand-written coder and ``construct``.

Run: ``.venv/bin/python bench/codec.py [--quick]``. Prints a table; asserts nothing about
timing. Two messages, each coded three ways with the scaling included:

* ReportGlobalPose (0x4402) with all nine fields present (PV u16 = 0x01FF, 30 bytes);
* a list of 20 waypoints (u16 count; latitude/longitude/altitude scaled u32 as in
  SetGlobalWaypoint plus a u16 waypoint tolerance; 282 bytes).

``hand`` is what one would write with ``struct`` for exactly that message (no presence
vector logic beyond checking it); ``generic`` is :func:`edge_vis.codec.bodies.decode_body`
/ ``encode_body`` on the DSL definition; ``construct`` is the same layout written with
construct 2.10 and ``.compile()``-d. Each figure is the best of several timed loops of a
fixed count.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
import timeit
from collections.abc import Callable
from functools import partial
from typing import Any

import construct as cs

from edge_vis.codec.bodies import decode_body, encode_body
from edge_vis.codec.types import BitField, List, Scaled, SubField, f, message, opt, record
from edge_vis.codec.types import u16 as U16
from edge_vis.codec.types import u32 as U32

PI = math.pi
LIMITS = {
    "latitude": (-90.0, 90.0, 32),
    "longitude": (-180.0, 180.0, 32),
    "altitude": (-10000.0, 35000.0, 32),
    "position_rms": (0.0, 100.0, 32),
    "roll": (-PI, PI, 16),
    "pitch": (-PI, PI, 16),
    "yaw": (-PI, PI, 16),
    "attitude_rms": (0.0, PI, 16),
    "waypoint_tolerance": (0.0, 100.0, 16),
}
TS_BITS = (("milliseconds", 0, 9), ("seconds", 10, 15), ("minutes", 16, 21), ("hour", 22, 26),
           ("day", 27, 31))


def scaled(name: str) -> Scaled:
    lo, hi, bits = LIMITS[name]
    return Scaled(U32 if bits == 32 else U16, lo, hi)


# -- the generic engine: DSL definitions ---------------------------------------------------

TIME_STAMP = BitField(U32, tuple(SubField(n, lo, hi) for n, lo, hi in TS_BITS))
POSE_FIELDS = ("latitude", "longitude", "altitude", "position_rms", "roll", "pitch", "yaw",
               "attitude_rms")
REPORT_GLOBAL_POSE = message(
    0x4402, "ReportGlobalPose",
    *(opt(name, scaled(name)) for name in POSE_FIELDS),
    opt("time_stamp", TIME_STAMP),
    pv=U16, service_set="bench",
)
WP_FIELDS = ("latitude", "longitude", "altitude", "waypoint_tolerance")
WAYPOINTS = message(
    0xD0A0, "WaypointList",
    f("waypoints", List(U16, record(*(f(name, scaled(name)) for name in WP_FIELDS)))),
    service_set="bench",
)


# -- hand-written struct coders ------------------------------------------------------------


def _coefficients(name: str) -> tuple[float, float]:
    lo, hi, bits = LIMITS[name]
    return (hi - lo) / (2**bits - 1), lo


LAT_S, LAT_B = _coefficients("latitude")
LON_S, LON_B = _coefficients("longitude")
ALT_S, ALT_B = _coefficients("altitude")
PRMS_S, _ = _coefficients("position_rms")
ANG_S, ANG_B = _coefficients("roll")
ARMS_S, _ = _coefficients("attitude_rms")
TOL_S, _ = _coefficients("waypoint_tolerance")
POSE = struct.Struct("<H4I4HI")
COUNT = struct.Struct("<H")
WAYPOINT = struct.Struct("<3IH")


def hand_decode_pose(body: bytes) -> dict[str, Any]:
    if len(body) != POSE.size or body[0] | body[1] << 8 != 0x1FF:
        raise ValueError("this coder handles only the full pose")
    _, lat, lon, alt, prms, roll, pitch, yaw, arms, ts = POSE.unpack(body)
    return {
        "latitude": lat * LAT_S + LAT_B, "longitude": lon * LON_S + LON_B,
        "altitude": alt * ALT_S + ALT_B, "position_rms": prms * PRMS_S,
        "roll": roll * ANG_S + ANG_B, "pitch": pitch * ANG_S + ANG_B, "yaw": yaw * ANG_S + ANG_B,
        "attitude_rms": arms * ARMS_S,
        "time_stamp": {"milliseconds": ts & 1023, "seconds": (ts >> 10) & 63,
                       "minutes": (ts >> 16) & 63, "hour": (ts >> 22) & 31, "day": ts >> 27},
    }


def hand_encode_pose(v: dict[str, Any]) -> bytes:
    t = v["time_stamp"]
    return POSE.pack(
        0x1FF,
        round((v["latitude"] - LAT_B) / LAT_S), round((v["longitude"] - LON_B) / LON_S),
        round((v["altitude"] - ALT_B) / ALT_S), round(v["position_rms"] / PRMS_S),
        round((v["roll"] - ANG_B) / ANG_S), round((v["pitch"] - ANG_B) / ANG_S),
        round((v["yaw"] - ANG_B) / ANG_S), round(v["attitude_rms"] / ARMS_S),
        t["milliseconds"] | t["seconds"] << 10 | t["minutes"] << 16 | t["hour"] << 22
        | t["day"] << 27,
    )


def hand_decode_waypoints(body: bytes) -> dict[str, Any]:
    (n,) = COUNT.unpack_from(body)
    end = 2 + n * WAYPOINT.size
    if end != len(body):
        raise ValueError("bad length")
    return {"waypoints": [
        {"latitude": a * LAT_S + LAT_B, "longitude": b * LON_S + LON_B,
         "altitude": c * ALT_S + ALT_B, "waypoint_tolerance": d * TOL_S}
        for a, b, c, d in WAYPOINT.iter_unpack(body[2:end])
    ]}


def hand_encode_waypoints(v: dict[str, Any]) -> bytes:
    items = v["waypoints"]
    out = bytearray(COUNT.pack(len(items)))
    for w in items:
        out += WAYPOINT.pack(
            round((w["latitude"] - LAT_B) / LAT_S), round((w["longitude"] - LON_B) / LON_S),
            round((w["altitude"] - ALT_B) / ALT_S), round(w["waypoint_tolerance"] / TOL_S),
        )
    return bytes(out)


# -- construct -----------------------------------------------------------------------------


def cs_scaled(name: str) -> cs.Construct:
    lo, hi, bits = LIMITS[name]
    scale = (hi - lo) / (2**bits - 1)
    raw = cs.Int32ul if bits == 32 else cs.Int16ul
    return cs.ExprAdapter(
        raw,
        decoder=lambda obj, ctx: obj * scale + lo,
        encoder=lambda obj, ctx: round((obj - lo) / scale),
    )


CS_TIME_STAMP = cs.ExprAdapter(
    cs.Int32ul,
    decoder=lambda t, ctx: {n: (t >> lo) & ((1 << (hi - lo + 1)) - 1) for n, lo, hi in TS_BITS},
    encoder=lambda d, ctx: sum(d[n] << lo for n, lo, _ in TS_BITS),
)
POSE_ALL = (*POSE_FIELDS, "time_stamp")
CS_POSE = cs.Struct(
    "pv" / cs.Int16ul,  # construct cannot compile a Rebuild lambda: cs_build_pose sets it
    *(name / cs.If(cs.this.pv & (1 << i), cs_scaled(name)) for i, name in enumerate(POSE_FIELDS)),
    "time_stamp" / cs.If(cs.this.pv & 0x100, CS_TIME_STAMP),
    cs.Terminated,
).compile()


def cs_build_pose(v: dict[str, Any]) -> bytes:
    """Build with construct, deriving the presence vector from the keys present."""
    pv = sum(1 << i for i, n in enumerate(POSE_ALL) if n in v)
    return CS_POSE.build({**v, "pv": pv})


CS_WAYPOINTS = cs.Struct(
    "waypoints" / cs.PrefixedArray(
        cs.Int16ul, cs.Struct(*(name / cs_scaled(name) for name in WP_FIELDS))
    ),
    cs.Terminated,
).compile()


# -- measuring -----------------------------------------------------------------------------


def best_rate(fn: Callable[[], object], number: int, repeat: int) -> float:
    """Calls per second of the fastest of ``repeat`` loops of ``number`` calls."""
    best = min(timeit.Timer(fn).repeat(repeat=repeat, number=number))
    return number / best


def same(a: Any, b: Any) -> bool:
    """Equal up to float noise (construct returns Containers with extra keys)."""
    if isinstance(a, dict):
        return all(same(v, b[k]) for k, v in a.items())
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)
    return bool(a == b)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer iterations")
    args = parser.parse_args(argv)
    repeat = 3 if args.quick else 7
    scale = 0.1 if args.quick else 1.0

    pose = {
        "latitude": 28.538426, "longitude": -81.3792, "altitude": 29.99, "position_rms": 1.5,
        "roll": 0.01, "pitch": -0.02, "yaw": 0.499942, "attitude_rms": 0.05,
        "time_stamp": {"milliseconds": 320, "seconds": 11, "minutes": 17, "hour": 11, "day": 22},
    }
    waypoints = {"waypoints": [
        {"latitude": 28.5 + i / 1000, "longitude": -81.4 - i / 1000, "altitude": 30.0 + i,
         "waypoint_tolerance": 2.5} for i in range(20)
    ]}
    cases = [
        ("ReportGlobalPose (9 fields)", REPORT_GLOBAL_POSE, pose, hand_decode_pose,
         hand_encode_pose, CS_POSE.parse, cs_build_pose, int(50000 * scale)),
        ("20-waypoint list", WAYPOINTS, waypoints, hand_decode_waypoints,
         hand_encode_waypoints, CS_WAYPOINTS.parse, CS_WAYPOINTS.build, int(5000 * scale)),
    ]

    header = (f"{'message':<28} {'op':<7} {'hand/s':>10} {'generic/s':>10} {'construct/s':>12}"
              f" {'generic vs hand':>16} {'construct vs generic':>21}")
    print(f"Python {sys.version.split()[0]}, construct {cs.__version__}; best of {repeat} loops;"
          " ratios are time per call (x = times slower)")
    print(header)
    print("-" * len(header))
    for label, defn, value, hand_dec, hand_enc, cs_dec, cs_enc, number in cases:
        body = encode_body(defn, value)
        if not (hand_enc(value) == body == cs_enc(value)):
            print(f"{label}: the three encoders disagree", file=sys.stderr)
            return 1
        decoded = decode_body(defn, body)
        if not (same(decoded, hand_dec(body)) and same(decoded, cs_dec(body))):
            print(f"{label}: the three decoders disagree", file=sys.stderr)
            return 1
        ops = {
            "decode": (partial(hand_dec, body), partial(decode_body, defn, body),
                       partial(cs_dec, body)),
            "encode": (partial(hand_enc, value), partial(encode_body, defn, value),
                       partial(cs_enc, value)),
        }
        for op, (hand_fn, generic_fn, cs_fn) in ops.items():
            hand = best_rate(hand_fn, number, repeat)
            generic = best_rate(generic_fn, number, repeat)
            construct = best_rate(cs_fn, max(number // 10, 100), repeat)
            print(f"{label:<28} {op:<7} {hand:>10,.0f} {generic:>10,.0f} {construct:>12,.0f}"
                  f" {hand / generic:>15.2f}x {generic / construct:>20.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
