"""Fuzz targets: every parser that reads bytes from a radio, a socket or a file.

Each target takes arbitrary bytes and must either succeed or raise one of the errors the
parser documents; anything else (an IndexError, a struct.error, a hang) is a bug. The
targets are plain functions so the test suite replays stored inputs without atheris, and
``fuzz/run.py`` drives them coverage-guided.
"""

from __future__ import annotations

import contextlib
import tomllib
from collections.abc import Callable

from edge_vis.catalogue import default_catalogue
from edge_vis.config import default_profile_path, from_mapping
from edge_vis.errors import ConfigError, DecodeError, EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import Reassembler
from edge_vis.jaus.serial_framing import SerialDeframer
from edge_vis.jaus.transport import DataFlags, Packet, unpack_datagram

_CATALOGUE = default_catalogue()
_CODES = sorted(d.code for d in _CATALOGUE)


def judp_datagram(data: bytes) -> None:
    """A JUDP datagram as it arrives on UDP port 3794."""
    with contextlib.suppress(DecodeError):
        unpack_datagram(data)


def message_body(data: bytes) -> None:
    """A message body for any catalogue message: the first two bytes pick the message."""
    if len(data) < 2:
        return
    code = _CODES[int.from_bytes(data[:2], "little") % len(_CODES)]
    payload = code.to_bytes(2, "little") + data[2:]
    try:
        message = _CATALOGUE.decode(payload)
    except DecodeError:
        return
    # whatever decodes must encode, and one encode/decode cycle must be stable (bytes are
    # compared, not values: NaN != NaN, and NUL padding of fixed strings is not kept)
    try:
        again = _CATALOGUE.encode(code, message.fields or {})
    except EncodeError as exc:
        # the one documented asymmetry: decoding tolerates a string longer than the
        # JSIDL maximum (peers send them), encoding refuses to produce one
        assert "exceeds the maximum" in exc.reason, exc
        return
    assert _CATALOGUE.encode(code, _CATALOGUE.decode(again).fields or {}) == again, hex(code)


def serial_stream(data: bytes) -> None:
    """Bytes from a serial radio, noise and all, fed in two pieces."""
    deframer = SerialDeframer()
    cut = len(data) // 2
    deframer.feed(data[:cut], 0.0)
    deframer.feed(data[cut:], 0.5)
    deframer.feed(b"", 10.0)
    assert deframer.buffered <= len(data)


def reassembly(data: bytes) -> None:
    """A sequence of fragments: 4 header bytes each (source, seq, flags, length)."""
    reassembler = Reassembler(max_sets_per_source=3, max_bytes=4096, timeout=1.0)
    offset = 0
    now = 0.0
    while offset + 4 <= len(data):
        source, seq, flags, length = data[offset : offset + 4]
        offset += 4
        chunk = data[offset : offset + length]
        offset += length
        now += 0.1
        packet = Packet(JausAddress(1, 1, 1), JausAddress(source % 4 + 1, 1, 1), chunk,
                        sequence=seq % 16, data_flags=DataFlags(flags % 4))
        reassembler.feed(packet, now)
        reassembler.expire(now)
        assert reassembler.bytes_held <= 4096


def profile_toml(data: bytes) -> None:
    """A deployment profile: the shipped default with values swapped by the fuzzer's bytes.

    Random bytes are rarely TOML, so most of the input mutates a valid profile (any key
    may get a value of any type) and the rest is tried as TOML text as it stands.
    """
    with contextlib.suppress(tomllib.TOMLDecodeError), contextlib.suppress(ConfigError):
        from_mapping(tomllib.loads(data.decode("utf-8", "replace")), file="fuzz.toml")
    mapping = tomllib.loads(default_profile_path().read_text())
    values: list[object] = [-1, 0, 1, 10**12, -0.5, 1e308, "", "x" * 300, "200.1.1",
                            "udp://", "serial:///dev/null?baud=1", True, [], [1, "a"], {},
                            {"url": 5}, float("nan"), "65535.255.255"]
    for i in range(0, len(data) - 2, 3):
        tables = [mapping, *(v for v in mapping.values() if isinstance(v, dict))]
        table = tables[data[i] % len(tables)]
        keys = list(table) or ["extra"]
        key = keys[data[i + 1] % len(keys)]
        table[key] = values[data[i + 2] % len(values)]
    with contextlib.suppress(ConfigError):
        from_mapping(mapping, file="fuzz.toml")


def udt_stream(data: bytes) -> None:
    """Bytes arriving on a UDT bulk connection at the receiver, in three pieces."""
    from links.udt.protocol import ManifestReceived, ReceiverConnection

    connection = ReceiverConnection()
    third = max(1, len(data) // 3)
    for i, start in enumerate(range(0, len(data), third)):
        for event in connection.receive_data(data[start : start + third], now=float(i)):
            if isinstance(event, ManifestReceived):
                connection.accept(0)
    connection.handle_timer(100.0)


TARGETS: dict[str, Callable[[bytes], None]] = {
    "judp": judp_datagram,
    "message": message_body,
    "serial": serial_stream,
    "reassembly": reassembly,
    "profile": profile_toml,
    "udt": udt_stream,
}
