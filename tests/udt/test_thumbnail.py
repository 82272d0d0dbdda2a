"""Thumbnails with the standard library: every supported format decodes to the right
pixels and shrinks to a PNG a browser shows; the others are refused with a reason."""

from __future__ import annotations

import struct
import zlib

import pytest

from links.udt.thumbnail import (
    HEAD,
    SIDE,
    NoThumbnail,
    check_head,
    decode,
    encode_png,
    shrink,
    thumbnail,
)


def grey(width: int, height: int) -> bytes:
    return bytes((x * 7 + y * 13) & 0xFF for y in range(height) for x in range(width))


def rgb(width: int, height: int) -> bytes:
    return bytes(v for y in range(height) for x in range(width)
                 for v in ((x * 5) & 0xFF, (y * 3) & 0xFF, (x + y) & 0xFF))


def png(width: int, height: int, colour: int, pixels: bytes, filters: bytes = b"\x00",
        depth: int = 8, interlace: int = 0, palette: bytes = b"") -> bytes:
    """A PNG written independently of the module under test, with the given row filters."""
    samples = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[colour]
    stride = width * samples
    raw, prior = bytearray(), bytes(stride)
    for y in range(height):
        kind = filters[y % len(filters)]
        row = pixels[y * stride:(y + 1) * stride]
        out = bytearray()
        for i, v in enumerate(row):
            a = row[i - samples] if i >= samples else 0
            b = prior[i]
            c = prior[i - samples] if i >= samples else 0
            pred = [0, a, b, (a + b) // 2,
                    min((a, b, c), key=lambda q: (abs(a + b - c - q), [a, b, c].index(q)))
                    ][kind]
            out.append((v - pred) & 0xFF)
        raw += bytes([kind]) + out
        prior = row

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0,
                                         interlace))
            + (chunk(b"PLTE", palette) if palette else b"")
            + chunk(b"IDAT", zlib.compress(bytes(raw))) + chunk(b"IEND", b""))


def bmp24(width: int, height: int, pixels: bytes) -> bytes:
    stride = (width * 3 + 3) & ~3
    rows = []
    for y in range(height - 1, -1, -1):  # bottom-up
        row = bytearray()
        for x in range(width):
            r, g, b = pixels[(y * width + x) * 3:(y * width + x) * 3 + 3]
            row += bytes((b, g, r))
        rows.append(bytes(row) + bytes(stride - len(row)))
    body = b"".join(rows)
    info = struct.pack("<IiiHHIIiiII", 40, width, height, 1, 24, 0, len(body), 0, 0, 0, 0)
    return b"BM" + struct.pack("<IHHI", 54 + len(body), 0, 0, 54) + info + body


@pytest.mark.parametrize(("data", "expected"), [
    (b"P5\n# comment\n7 5\n255\n" + grey(7, 5), (7, 5, 1, grey(7, 5))),
    (b"P2 3 2 15\n0 15 5\n10 0 15\n", (3, 2, 1, bytes([0, 255, 85, 170, 0, 255]))),
    (b"P6 4 3 255\n" + rgb(4, 3), (4, 3, 3, rgb(4, 3))),
    (bmp24(5, 3, rgb(5, 3)), (5, 3, 3, rgb(5, 3))),
    (png(9, 6, 0, grey(9, 6), filters=bytes([0, 1, 2, 3, 4])), (9, 6, 1, grey(9, 6))),
    (png(6, 4, 2, rgb(6, 4), filters=bytes([4, 3, 2, 1])), (6, 4, 3, rgb(6, 4))),
    (png(2, 1, 3, bytes([1, 0]), palette=b"\x00\x00\x00\xff\x10\x20"),
     (2, 1, 3, b"\xff\x10\x20\x00\x00\x00")),
])
def test_supported_formats_decode_to_their_pixels(data, expected):
    assert decode(data) == expected


@pytest.mark.parametrize(("data", "why"), [
    (b"\xff\xd8\xff\xe0" + bytes(100), "JPEG needs a codec"),
    (b"II*\x00" + bytes(100), "TIFF needs a codec"),
    (png(4, 4, 0, grey(4, 4), depth=16), "16-bit"),
    (png(4, 4, 0, grey(4, 4), interlace=1), "interlacing"),
    (b"P5 10 10 255\n" + bytes(20), "shorter than its header"),
    (b"XTF sonar data", "this format"),
])
def test_unsupported_images_get_no_thumbnail_and_a_reason(data, why):
    with pytest.raises(NoThumbnail, match=why):
        thumbnail(data)


def test_thumbnail_is_a_small_png_of_the_picture():
    picture = (300, 150, 1, grey(300, 150))
    small = shrink(picture)
    assert small[:3] == (SIDE, SIDE // 2, 1)
    # nearest neighbour: each thumbnail pixel is the source pixel under its centre
    x, y = 10, 20
    sx, sy = int((x + 0.5) * 300 / SIDE), int((y + 0.5) * 150 / (SIDE // 2))
    assert small[3][y * SIDE + x] == picture[3][sy * 300 + sx]
    out = thumbnail(png(300, 150, 0, grey(300, 150)))
    assert out.startswith(b"\x89PNG") and decode(out) == small
    assert decode(encode_png(*small)) == small


def test_receiver_keeps_a_thumbnail_next_to_each_verified_image(tmp_path):
    pytest.importorskip("udt4py")
    from links.udt import UdtBulkChannel

    published: list[tuple[str, dict]] = []
    src = tmp_path / "src"
    src.mkdir()
    (src / "sonar.pgm").write_bytes(b"P5 200 100 255\n" + grey(200, 100))
    (src / "photo.jpg").write_bytes(b"\xff\xd8\xff\xe0" + bytes(5000))
    with UdtBulkChannel.ImageService(tmp_path / "ops", publish=lambda t, s: published.append(
            (t, s)), publish_data=False) as ops:
        for name in ("sonar.pgm", "photo.jpg"):
            assert UdtBulkChannel.send_image(src / name, ops.address, vehicle_id="uuv1").ok
    products = {s["file_name"]: s for t, s in published if t == "ImageProduct"}
    thumb = bytes(products["sonar.pgm"]["thumbnail_png"])
    assert decode(thumb) == shrink((200, 100, 1, grey(200, 100)))
    assert (tmp_path / "ops" / "uuv1" / "sonar.pgm.thumb.png").read_bytes() == thumb
    assert not products["photo.jpg"].get("thumbnail_png")
    assert not (tmp_path / "ops" / "uuv1" / "photo.jpg.thumb.png").exists()


@pytest.mark.parametrize("head, supported", [
    (b"\x89PNG\r\n\x1a\n", True), (b"P5 200 1", True), (b"P3\n2 2 2", True), (b"BM\x00\x00", True),
    (b"\xff\xd8\xff\xe0\x00\x10JF", False), (b"II*\x00\x08\x00\x00\x00", False),
    (b"GIF89a\x01\x00", False), (b"XTF sona", False), (b"", False),
])
def test_the_first_bytes_say_whether_a_file_can_get_a_thumbnail(head, supported):
    # a relay reads a 64 MiB JPEG's first bytes, not the whole file, to learn it gets none
    if supported:
        check_head(head[:HEAD])
    else:
        with pytest.raises(NoThumbnail, match="codec"):
            check_head(head[:HEAD])
