"""Small PNG thumbnails of verified images, with the standard library only. Pure: bytes in,
bytes out.

An operator wants to see an ATR image before opening the full file, and the relay may
have no image library. What can be decoded here with ``zlib`` and ``struct`` gets a
thumbnail of at most ``SIDE`` pixels on its long side (nearest-neighbour sampling, grey or
RGB, as an 8-bit PNG any browser shows):

* PGM and PPM (``P2``/``P5`` grey, ``P3``/``P6`` colour, up to 16 bits per sample);
* BMP, uncompressed, 8-bit palette, 24 and 32 bits per pixel;
* PNG, 8 bits per sample, not interlaced, every colour type and filter - decoding filters
  in pure Python costs about a second per ``PNG_LIMIT`` bytes, so larger ones get none.

No thumbnail (:class:`NoThumbnail` says why): JPEG, TIFF, GIF and compressed BMP (each needs
a real codec: DCT, LZW, RLE), 16-bit or interlaced PNG, sonar formats such as XTF
(no picture without a sonar model), and anything that does not parse.
"""

from __future__ import annotations

import struct
import zlib

SIDE = 96
"""Longest side of a thumbnail, in pixels."""
PNG_LIMIT = 4 << 20
"""Most decompressed PNG bytes decoded for a thumbnail."""
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class NoThumbnail(ValueError):
    """This image gets no thumbnail; the message says why."""


Picture = tuple[int, int, int, bytes]
"""``(width, height, channels, pixels)``: 8-bit samples, rows top to bottom, 1 or 3 channels."""


def thumbnail(data: bytes, side: int = SIDE) -> bytes:
    """A PNG thumbnail of the image file ``data``; :class:`NoThumbnail` when unsupported."""
    return encode_png(*shrink(decode(data), side))


HEAD = 8
"""Leading bytes of a file that say whether it can get a thumbnail (:func:`check_head`)."""


def check_head(head: bytes) -> None:
    """:class:`NoThumbnail` unless a file starting with ``head`` (its first ``HEAD`` bytes)
    is of a format decoded here: a caller need not read a large file it cannot use."""
    if head[:2] in (b"P2", b"P3", b"P5", b"P6", b"BM") or head[:8] == PNG_SIGNATURE:
        return
    kind = {b"\xff\xd8": "JPEG", b"II": "TIFF", b"MM": "TIFF", b"GI": "GIF"}.get(head[:2])
    raise NoThumbnail(f"{kind or 'this format'} needs a codec the standard library lacks")


def decode(data: bytes) -> Picture:
    """The pixels of a PGM/PPM, BMP or PNG file (see module doc)."""
    check_head(data[:HEAD])
    if data[:2] == b"BM":
        return _bmp(data)
    if data[:8] == PNG_SIGNATURE:
        return _png(data)
    return _pnm(data)


def shrink(picture: Picture, side: int = SIDE) -> Picture:
    """Nearest-neighbour downscale so the long side is at most ``side``."""
    width, height, channels, pixels = picture
    scale = max(width, height) / side
    if scale <= 1:
        return picture
    w, h = max(1, round(width / scale)), max(1, round(height / scale))
    xs = [min(width - 1, int((x + 0.5) * width / w)) * channels for x in range(w)]
    out = bytearray()
    for y in range(h):
        row = min(height - 1, int((y + 0.5) * height / h)) * width * channels
        for x in xs:
            out += pixels[row + x: row + x + channels]
    return w, h, channels, bytes(out)


def encode_png(width: int, height: int, channels: int, pixels: bytes) -> bytes:
    """An 8-bit grey (1 channel) or RGB (3 channels) PNG file."""
    stride = width * channels
    raw = b"".join(b"\x00" + pixels[y * stride:(y + 1) * stride] for y in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 0 if channels == 1 else 2, 0, 0, 0)
    return b"".join((PNG_SIGNATURE, _chunk(b"IHDR", header),
                     _chunk(b"IDAT", zlib.compress(raw, 9)), _chunk(b"IEND", b"")))


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


# --------------------------------------------------------------------------- PGM / PPM


def _pnm(data: bytes) -> Picture:
    kind = data[:2]
    fields: list[int] = []
    pos = 2
    while len(fields) < 3:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.find(b"\n", pos) + 1 or len(data)
            continue
        end = pos
        while end < len(data) and data[end:end + 1].isdigit():
            end += 1
        if end == pos:
            raise NoThumbnail("PNM header is broken")
        fields.append(int(data[pos:end]))
        pos = end
    width, height, top = fields
    if not (width and height and 0 < top < 65536):
        raise NoThumbnail("PNM header has a zero size or a bad maximum value")
    channels = 3 if kind in (b"P3", b"P6") else 1
    count = width * height * channels
    if kind in (b"P2", b"P3"):
        values = [int(v) for v in data[pos:].split()[:count]]
    else:
        body = data[pos + 1:]
        if top < 256:
            values = list(body[:count])
        else:
            values = list(struct.unpack(f">{count}H", body[:count * 2])) \
                if len(body) >= count * 2 else []
    if len(values) < count:
        raise NoThumbnail("PNM file is shorter than its header says")
    return width, height, channels, bytes(v * 255 // top for v in values)


# --------------------------------------------------------------------------- BMP


def _bmp(data: bytes) -> Picture:
    try:
        offset, = struct.unpack_from("<I", data, 10)
        width, height, _planes, bits, compression = struct.unpack_from("<iiHHI", data, 18)
        colours, = struct.unpack_from("<I", data, 46)
    except struct.error:
        raise NoThumbnail("BMP header is broken") from None
    if compression not in (0, 3) or bits not in (8, 24, 32):
        raise NoThumbnail(f"BMP with {bits} bits per pixel or compression {compression} "
                          "needs a decoder of its own")
    flip = height > 0
    height = abs(height)
    stride = (width * bits // 8 + 3) & ~3
    if width <= 0 or offset + stride * height > len(data):
        raise NoThumbnail("BMP file is shorter than its header says")
    header_size, = struct.unpack_from("<I", data, 14)
    palette = data[14 + header_size:14 + header_size + 4 * (colours or 256)]
    out = bytearray()
    for y in range(height):
        row = data[offset + (height - 1 - y if flip else y) * stride:][:stride]
        if bits == 8:
            for i in row[:width]:
                b, g, r = palette[4 * i:4 * i + 3] or b"\x00\x00\x00"
                out += bytes((r, g, b))
        else:
            step = bits // 8
            for x in range(width):
                b, g, r = row[x * step:x * step + 3]
                out += bytes((r, g, b))
    return width, height, 3, bytes(out)


# --------------------------------------------------------------------------- PNG


def _png(data: bytes) -> Picture:
    pos, idat, palette = 8, bytearray(), b""
    header: tuple[int, ...] = ()
    while pos + 8 <= len(data):
        length, kind = struct.unpack_from(">I4s", data, pos)
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body[:13])
        elif kind == b"PLTE":
            palette = body
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
        pos += 12 + length
    if not header:
        raise NoThumbnail("PNG without a header")
    width, height, depth, colour, _c, _f, interlace = header
    if depth != 8 or interlace:
        raise NoThumbnail(f"PNG with {depth}-bit samples or interlacing is not decoded here")
    samples = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(colour)
    if samples is None:
        raise NoThumbnail(f"PNG colour type {colour} is not defined")
    stride = width * samples
    if (stride + 1) * height > PNG_LIMIT:
        raise NoThumbnail(f"PNG of {width}x{height} is too large to decode without an image "
                          "library")
    try:
        raw = zlib.decompress(bytes(idat))
    except zlib.error as exc:
        raise NoThumbnail(f"PNG data is broken: {exc}") from None
    if len(raw) < (stride + 1) * height:
        raise NoThumbnail("PNG data is shorter than its header says")
    rows = _unfilter(raw, stride, height, samples)
    return _to_picture(rows, width, height, colour, palette)


def _unfilter(raw: bytes, stride: int, height: int, bpp: int) -> list[bytes]:
    rows: list[bytes] = []
    prior = bytes(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if kind == 1:
            for i in range(bpp, stride):
                line[i] = (line[i] + line[i - bpp]) & 0xFF
        elif kind == 2:
            line = bytearray((a + b) & 0xFF for a, b in zip(line, prior, strict=True))
        elif kind == 3:
            for i in range(stride):
                left = line[i - bpp] if i >= bpp else 0
                line[i] = (line[i] + ((left + prior[i]) >> 1)) & 0xFF
        elif kind == 4:
            for i in range(stride):
                a = line[i - bpp] if i >= bpp else 0
                b, c = prior[i], prior[i - bpp] if i >= bpp else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) \
                    & 0xFF
        elif kind != 0:
            raise NoThumbnail(f"PNG row filter {kind} is not defined")
        prior = bytes(line)
        rows.append(prior)
    return rows


def _to_picture(rows: list[bytes], width: int, height: int, colour: int,
                palette: bytes) -> Picture:
    if colour == 0:
        return width, height, 1, b"".join(rows)
    if colour == 4:
        return width, height, 1, b"".join(row[0::2] for row in rows)
    if colour == 3:
        if not palette:
            raise NoThumbnail("PNG with a palette colour type but no palette")
        out = bytearray()
        for row in rows:
            for i in row:
                out += palette[3 * i:3 * i + 3] or b"\x00\x00\x00"
        return width, height, 3, bytes(out)
    step = 3 if colour == 2 else 4
    out = bytearray()
    for row in rows:
        for x in range(width):
            out += row[x * step:x * step + 3]
    return width, height, 3, bytes(out)
