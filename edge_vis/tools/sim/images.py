"""Synthetic camera frames as real image files (PNG and PGM bytes). No I/O.

Frames are deterministic for a (seed, frame number) pair and carry sensor-like noise, so
a PNG of a modest size still compresses poorly and needs JAUS fragmentation (more than
one 4079-byte packet) - which is what the simulator wants to exercise.
"""

from __future__ import annotations

import random
import struct
import zlib

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def frame_pixels(width: int, height: int, seed: int, number: int) -> bytes:
    """8-bit grey pixels: a moving gradient with a bright square and per-pixel noise."""
    rng = random.Random(seed * 1_000_003 + number)
    noise = rng.randbytes(width * height)
    box = (number * 7) % max(1, width - width // 4)
    rows = []
    for y in range(height):
        base = bytearray(((x + y + number * 3) * 255 // (width + height)) & 0xFF
                         for x in range(width))
        if height // 3 <= y < height // 3 + height // 4:
            base[box : box + width // 4] = b"\xf0" * len(base[box : box + width // 4])
        row = noise[y * width : (y + 1) * width]
        rows.append(bytes((b + (n & 0x3F)) & 0xFF for b, n in zip(base, row, strict=True)))
    return b"".join(rows)


def _chunk(kind: bytes, data: bytes) -> bytes:
    crc = zlib.crc32(kind + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def png_grey(width: int, height: int, pixels: bytes) -> bytes:
    """An 8-bit greyscale PNG file of ``pixels`` (row-major, one byte per pixel)."""
    if len(pixels) != width * height:
        raise ValueError(f"{len(pixels)} pixels for a {width}x{height} image")
    raw = b"".join(b"\x00" + pixels[y * width : (y + 1) * width] for y in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"".join((PNG_SIGNATURE, _chunk(b"IHDR", header),
                     _chunk(b"IDAT", zlib.compress(raw, 6)), _chunk(b"IEND", b"")))


def pgm(width: int, height: int, pixels: bytes) -> bytes:
    """A binary (P5) PGM file of ``pixels``."""
    return b"P5\n%d %d\n255\n" % (width, height) + pixels


def camera_frame(width: int, height: int, seed: int, number: int) -> bytes:
    """A PNG camera frame."""
    return png_grey(width, height, frame_pixels(width, height, seed, number))
