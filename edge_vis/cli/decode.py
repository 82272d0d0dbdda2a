"""``edge-vis decode``: JAUS traffic (hex, pcap/pcapng, or a raw serial dump) as JSON lines.

Input is hex datagrams (arguments, or lines of a file or stdin, one datagram per line),
or a pcap/pcapng file of UDP datagrams (port 3794 by default). With ``--serial`` the
input is a hex dump of a raw serial byte stream (plain hex, ``xxd`` or ``hexdump -C``),
noise and all: frames are found, checked and decoded, and bad checksums and skipped bytes
are reported.

Every JAUS message becomes one JSON object on stdout: ``transport`` (the header fields),
``source``/``destination`` (``S.N.C``), ``message_code`` (``0x....``), ``message`` (the
name, ``null`` when unknown), ``fields`` (snake_case JSIDL names, scaled values in their
units; absent optional fields are left out) or ``body`` (hex) for unknown codes. An Event
also carries its decoded ``report``. ``--dialect`` reads a vehicle's messages in the
definitions it speaks (manipulator v1.0, IOP; see :class:`Speech`); a message so read
carries ``dialect`` (and ``dialect_name``, its name there). Problems become objects with an
``error`` key, in order with the rest; the exit status is 1 when any input could not be
decoded.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from edge_vis.catalogue import Catalogue, Message, default_catalogue, unwrap_event
from edge_vis.codec.jsonform import record_to_json
from edge_vis.errors import DecodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import Reassembler
from edge_vis.jaus.pcap import is_capture, read_udp
from edge_vis.jaus.serial_framing import SerialDeframer, SerialError, SerialFrame
from edge_vis.jaus.transport import Packet, unpack_datagram

NAME = "decode"
HELP = "decode JAUS datagrams (hex, pcap/pcapng) or a serial byte dump to JSON lines"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument(
        "inputs", nargs="*", metavar="HEX|FILE",
        help="hex datagrams, or files (pcap/pcapng or text with one hex datagram per "
        "line); '-' or nothing reads stdin",
    )
    parser.add_argument("--serial", action="store_true",
                        help="input is a hex dump of a raw JAUS serial byte stream")
    parser.add_argument("--port", type=int, default=3794,
                        help="UDP port to select from captures (default 3794)")
    parser.add_argument("--all-ports", action="store_true",
                        help="decode UDP datagrams on every port of a capture")
    parser.add_argument("--jsidl", action="extend", nargs=1, default=[], metavar="FILE",
                        help="a JSIDL file or folder whose messages decode too (repeatable)")
    parser.add_argument("--dialect", action="extend", nargs=1, default=[],
                        metavar="[S=]NAME|auto",
                        help="read messages in a dialect (manipulator-1.0, iop): all, or those "
                        "from/to subsystem S; 'auto': as each vehicle's reported services "
                        "show (repeatable)")


class _Output:
    def __init__(self) -> None:
        self.errors = 0
        self.messages = 0

    def emit(self, obj: dict[str, Any]) -> None:
        if "error" in obj:
            self.errors += 1
        else:
            self.messages += 1
        sys.stdout.write(json.dumps(obj) + "\n")


def run(args: argparse.Namespace) -> int:
    """Decode every input and print JSON lines."""
    catalogue = default_catalogue()
    if args.jsidl:
        from edge_vis.catalogue.jsidl import load_jsidl

        catalogue = catalogue.copy()
        catalogue.add(load_jsidl([Path(p) for p in args.jsidl]), source="jsidl")
    speech = Speech.parse(args.dialect, catalogue)
    out = _Output()
    port = None if args.all_ports else args.port
    for label, blob in _read_inputs(args.inputs):
        if args.serial:
            _decode_serial(label, _hex_dump_bytes(blob.decode("latin-1")), catalogue, out,
                           speech)
        elif is_capture(blob):
            _decode_capture(label, blob, port, catalogue, out, speech)
        else:
            _decode_hex_lines(label, blob.decode("latin-1").splitlines(), catalogue, out,
                              speech)
    return 1 if out.errors else 0


def _read_inputs(inputs: list[str]) -> Iterator[tuple[str, bytes]]:
    if not inputs or inputs == ["-"]:
        yield "stdin", sys.stdin.buffer.read()
        return
    hex_args = [item for item in inputs if _HEX_RE.fullmatch(item.replace(" ", ""))]
    if hex_args:  # one block, so that the fragments of a large message reassemble
        yield "argument", "\n".join(hex_args).encode()
    for item in inputs:
        if item == "-":
            yield "stdin", sys.stdin.buffer.read()
        elif item not in hex_args:
            path = Path(item)
            if not path.exists():
                raise DecodeError(f"{item!r} is neither hex nor an existing file")
            yield str(path), path.read_bytes()


_HEX_RE = re.compile(r"(?:[0-9a-fA-F]{2})+")


def _decode_hex_lines(label: str, lines: Iterable[str], catalogue: Catalogue,
                      out: _Output, speech: Speech) -> None:
    reassembler = Reassembler()
    for number, raw in enumerate(lines, 1):
        text = raw.split("#", 1)[0].strip().replace(" ", "").replace(":", "")
        if not text:
            continue
        where = {"input": label, "line": number}
        try:
            data = bytes.fromhex(text)
        except ValueError:
            out.emit({"error": "not hex", **where})
            continue
        _decode_datagram(data, float(number), where, reassembler, catalogue, out, speech)


def _decode_capture(label: str, blob: bytes, port: int | None, catalogue: Catalogue,
                    out: _Output, speech: Speech) -> None:
    reassembler = Reassembler()
    try:
        for index, datagram in enumerate(read_udp(blob, port)):
            where = {
                "input": label, "frame": index, "time": round(datagram.timestamp, 6),
                "udp_source": f"{datagram.source[0]}:{datagram.source[1]}",
                "udp_destination": f"{datagram.destination[0]}:{datagram.destination[1]}",
            }
            _decode_datagram(datagram.payload, datagram.timestamp, where, reassembler,
                             catalogue, out, speech)
    except DecodeError as exc:
        out.emit({"error": str(exc), "input": label})


def _decode_datagram(data: bytes, now: float, where: dict[str, Any], reassembler: Reassembler,
                     catalogue: Catalogue, out: _Output, speech: Speech) -> None:
    try:
        packets = unpack_datagram(data)
    except DecodeError as exc:
        out.emit({"error": str(exc), "offset": exc.offset, **where})
        return
    for packet in packets:
        _decode_packet(packet, now, where, reassembler, catalogue, out, speech)


def _decode_packet(packet: Packet, now: float, where: dict[str, Any], reassembler: Reassembler,
                   catalogue: Catalogue, out: _Output, speech: Speech) -> None:
    whole = reassembler.feed(packet, now)
    if whole is None:
        return  # a fragment; the set's last piece prints the whole message
    obj: dict[str, Any] = {
        **where,
        "transport": whole.header_dict(),
        "source": str(whole.source),
        "destination": str(whole.destination),
    }
    code = whole.message_code
    if code is None:  # an ACK/NAK carries no payload
        obj.update(message_code=None, message=None)
        out.emit(obj)
        return
    obj["message_code"] = f"0x{code:04X}"
    dialects = speech.of(whole.source, whole.destination)
    try:
        message = catalogue.decode(whole.payload, dialects)
    except DecodeError as exc:
        obj.update(error=str(exc), offset=exc.offset, body=whole.payload[2:].hex())
        out.emit(obj)
        return
    obj.update(message_json(message, catalogue, dialects))
    speech.learn(whole.source, message)
    out.emit(obj)


def message_json(message: Message, catalogue: Catalogue,
                 dialects: tuple[str, ...] = ()) -> dict[str, Any]:
    """The ``message``/``fields`` (or ``body``) part of a decoded message, Events unwrapped
    (read in ``dialects``; ``dialect`` names the one that decoded it, if any)."""
    if message.definition is None or message.fields is None:
        return {"message": None, "body": message.body.hex()}
    obj: dict[str, Any] = {
        "message": message.name,
        "fields": record_to_json(message.fields, message.definition.body),
    }
    if message.dialect:
        obj["dialect"] = message.dialect
        if message.definition.name != message.name:
            obj["dialect_name"] = message.definition.name
    if message.name == "Event":
        try:
            inner = catalogue.unwrap_event(message, dialects) if dialects \
                else unwrap_event(message, catalogue)
            obj["report"] = {"message_code": f"0x{inner.code:04X}",
                             **message_json(inner, catalogue, dialects)}
        except DecodeError as exc:
            obj["report"] = {"error": str(exc)}
    return obj


class Speech:
    """Which message dialects each message of the input is read in (``--dialect``).

    ``NAME`` reads every message in that dialect; ``S=NAME`` only those from or to
    subsystem S; ``auto`` recognises each subsystem's dialects from the ReportServices /
    ReportServiceList it sends earlier in the input, as the relay does. A message from a
    subsystem with dialects of its own is read in those, else one sent to such a subsystem
    in the receiver's, else in the ones given for all.
    """

    def __init__(self, catalogue: Catalogue, every: tuple[str, ...] = (),
                 by_subsystem: dict[int, tuple[str, ...]] | None = None,
                 auto: bool = False) -> None:
        self.catalogue = catalogue
        self.every = every
        self.by_subsystem = dict(by_subsystem or {})
        self.auto = auto

    @classmethod
    def parse(cls, options: Iterable[str], catalogue: Catalogue) -> Speech:
        """From ``--dialect`` values; DecodeError naming the known dialects on a bad one."""
        known = catalogue.dialects()
        every: list[str] = []
        by_subsystem: dict[int, tuple[str, ...]] = {}
        auto = False
        for option in options:
            if option == "auto":
                auto = True
                continue
            subsystem, _, name = option.rpartition("=")
            if name not in known:
                raise DecodeError(f"--dialect {option!r}: no dialect {name!r} (dialects: "
                                  f"{', '.join(sorted(known))}, or auto)")
            if not subsystem:
                every.append(name)
            elif subsystem.isdigit() and 1 <= int(subsystem) <= 65534:
                by_subsystem[int(subsystem)] = (*by_subsystem.get(int(subsystem), ()), name)
            else:
                raise DecodeError(f"--dialect {option!r}: {subsystem!r} is not a subsystem "
                                  "id (1..65534)")
        return cls(catalogue, tuple(every), by_subsystem, auto)

    def of(self, source: JausAddress, destination: JausAddress) -> tuple[str, ...]:
        """The dialects to read a message from ``source`` to ``destination`` in."""
        for subsystem in (source.subsystem, destination.subsystem):
            found = self.by_subsystem.get(subsystem)
            if found:
                return found
        return self.every

    def learn(self, source: JausAddress, message: Message) -> None:
        """With ``auto``: the dialects a subsystem's reported services show."""
        if not self.auto or message.fields is None or message.name not in (
                "ReportServices", "ReportServiceList"):
            return
        found: dict[int, list[tuple[str, str]]] = {}
        subsystems = message.fields.get("subsystem_list") or [
            {"subsystem_rec": {"subsystem_id": source.subsystem},
             "node_list": message.fields.get("node_list") or []}]
        for sub in subsystems:
            services = found.setdefault(sub["subsystem_rec"]["subsystem_id"], [])
            for node in sub.get("node_list") or []:
                for comp in node.get("component_list") or []:
                    services += [(s["uri"], f"{s['major_version_number']}."
                                            f"{s['minor_version_number']}")
                                 for s in comp.get("service_list") or []]
        for subsystem, services in found.items():
            dialects = self.catalogue.recognise(services)
            if dialects:
                self.by_subsystem[subsystem] = dialects


def _hex_dump_bytes(text: str) -> bytes:
    """Bytes from plain hex, ``xxd`` or ``hexdump -C`` output."""
    chunks = []
    for line in text.splitlines():
        line = line.split("#", 1)[0]
        xxd = re.match(r"^\s*[0-9a-fA-F]+:\s+(.*)$", line)
        if xxd:  # xxd: "00000000: 1001 0211 ...  ascii"
            line = re.split(r"\s{2,}", xxd.group(1).strip())[0]
        else:
            hexdump = re.match(r"^([0-9a-fA-F]{7,8})\s+(.*)$", line)
            if hexdump:  # hexdump -C: "00000000  10 01 02 ...  |....|"
                line = hexdump.group(2).split("|", 1)[0]
        chunks.append(re.sub(r"[^0-9a-fA-F]", "", line))
    digits = "".join(chunks)
    if len(digits) % 2:
        digits = digits[:-1]
    return bytes.fromhex(digits)


def _decode_serial(label: str, stream: bytes, catalogue: Catalogue, out: _Output,
                   speech: Speech) -> None:
    deframer = SerialDeframer()
    reassembler = Reassembler()
    offset = 0
    for item in deframer.feed(stream):
        if isinstance(item, SerialError):
            out.emit({"error": item.reason, "skipped": item.data.hex(), "input": label})
            continue
        assert isinstance(item, SerialFrame)
        offset += 1
        _decode_packet(item.packet, 0.0, {"input": label, "frame": offset}, reassembler,
                       catalogue, out, speech)
    if deframer.buffered:
        out.emit({"error": "incomplete frame at end of input",
                  "skipped_bytes": deframer.buffered, "input": label})
