"""Scaled integers (AS5684 scale_range) at their edges.

``scale = (upper - lower) / (2**bits - 1)``; unsigned: bias = lower; signed: bias =
(upper + lower) / 2. Encoding rounds; decoding accepts every integer.
"""

from __future__ import annotations

import math

import pytest

from edge_vis.codec.bodies import compile_type, scaling
from edge_vis.codec.types import Scaled, i16, i32, u8, u16, u32
from edge_vis.errors import EncodeError

LAT = Scaled(u32, -90, 90)
LOCAL = Scaled(u32, -100000, 100000)
SIGNED = Scaled(i16, -100, 100)


def enc(ft: Scaled, value: float) -> int:
    out = bytearray()
    compile_type(ft).encode(value, out)
    return int.from_bytes(out, "little", signed=ft.raw.signed)


def dec(ft: Scaled, raw: int) -> float:
    data = raw.to_bytes(ft.raw.size, "little", signed=ft.raw.signed)
    value, end = compile_type(ft).decode(data, 0)
    assert end == ft.raw.size
    return value


def test_scale_and_bias() -> None:
    assert scaling(LAT) == (180 / 4294967295, -90.0)
    assert scaling(SIGNED) == (200 / 65535, 0.0)
    assert scaling(Scaled(i32, 0, 10)) == (10 / 4294967295, 5.0)


def test_unsigned_limits_map_to_the_integer_ends() -> None:
    assert enc(LAT, -90.0) == 0
    assert enc(LAT, 90.0) == 0xFFFFFFFF
    assert dec(LAT, 0) == -90.0
    assert dec(LAT, 0xFFFFFFFF) == 90.0


def test_negative_reals() -> None:
    assert enc(LAT, -45.0) == round(45 / (180 / 4294967295))
    assert dec(LAT, enc(LAT, -45.0)) == pytest.approx(-45.0, abs=180 / 4294967295)
    assert enc(Scaled(u16, -math.pi, math.pi), -math.pi / 2) == 16384  # 16383.75 rounds up


def test_rounding_not_truncation() -> None:
    # the JTS example sends X = 0 on [-100000, 100000] as 0x7FFFFFFF (truncated 2147483647.5)
    assert dec(LOCAL, 0x7FFFFFFF) == pytest.approx(-0.0000233, abs=1e-7)
    assert enc(LOCAL, 0.0) == 0x80000000
    # 2.5 m on u16 [0, 100] is 1638.375 -> 1638; 2.51 m is 1644.93 -> 1645 (truncation: 1644)
    assert enc(Scaled(u16, 0, 100), 2.5) == 1638
    assert enc(Scaled(u16, 0, 100), 2.51) == 1645


def test_reals_within_half_a_step_of_the_range_are_accepted() -> None:
    lsb = 180 / 4294967295
    assert enc(LAT, 90.0 + lsb / 4) == 0xFFFFFFFF
    assert enc(LAT, -90.0 - lsb / 4) == 0
    with pytest.raises(EncodeError, match="outside the scaled range"):
        enc(LAT, 90.0 + lsb)
    with pytest.raises(EncodeError, match="outside the scaled range"):
        enc(Scaled(u8, 0, 100), -1.0)


def test_signed_raw_is_centred_on_the_middle_of_the_range() -> None:
    step = 200 / 65535
    assert enc(SIGNED, 0.0) == 0
    assert dec(SIGNED, 0) == 0.0
    assert enc(SIGNED, -50.0) == round(-50 / step)
    # the upper end is 32767.5 steps above the middle: clamped to the largest integer
    assert enc(SIGNED, 100.0) == 32767
    assert dec(SIGNED, 32767) == pytest.approx(100 - step / 2)
    assert enc(SIGNED, -100.0) == -32768  # -32767.5 rounds half to even
    with pytest.raises(EncodeError):
        enc(SIGNED, 100.01)


def test_decoding_never_fails_on_any_integer() -> None:
    ft = Scaled(u8, 10, 20)
    values = [dec(ft, raw) for raw in range(256)]
    assert values[0] == 10.0 and values[255] == 20.0
    assert values == sorted(values)
    # a signed raw below the lowest real still decodes, and re-encodes to itself
    low = dec(SIGNED, -32768)
    assert low < -100.0
    assert enc(SIGNED, low) == -32768


def test_integer_reals_are_accepted() -> None:
    assert enc(Scaled(u16, 0, 100), 100) == 65535
    assert enc(Scaled(u16, 0, 100), True) == 655
