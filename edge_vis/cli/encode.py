"""``edge-vis encode``: one JAUS message from JSON to the hex of a whole JUDP datagram.

``edge-vis encode ReportGlobalPose --json '{"latitude": 28.5, "longitude": -81.4}'
--source 126.1.199 --destination 42.1.1`` prints one line of hex per datagram (more than
one when the message exceeds ``--mtu`` and travels as a large data set). Bytes fields take
hex strings, as ``edge-vis decode`` prints them, so the two commands round-trip.
``--jsidl FILE`` (repeatable) adds a user's JSIDL (files or folders), so custom messages encode too:
``edge-vis encode ReportBatteryPack --jsidl BatteryPack.xml --json '{...}' ...``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from edge_vis.catalogue import Catalogue
from edge_vis.catalogue.jsidl import profile_catalogue
from edge_vis.codec.jsonform import record_from_json
from edge_vis.codec.types import MessageDef
from edge_vis.errors import EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import fragment
from edge_vis.jaus.transport import JTS_MAX_PAYLOAD, Broadcast, Packet, pack_datagram

NAME = "encode"
HELP = "encode one JAUS message from JSON fields into a JUDP datagram (hex)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("message", help="message name (e.g. ReportGlobalPose) or code (0x4402)")
    parser.add_argument("--json", default="{}", help="the message fields as a JSON object")
    parser.add_argument("--source", required=True, help="source JAUS id S.N.C")
    parser.add_argument("--destination", required=True, help="destination JAUS id S.N.C")
    parser.add_argument("--sequence", type=int, default=0, help="sequence number (default 0)")
    parser.add_argument("--priority", type=int, default=1, choices=range(4),
                        help="transport priority 0-3 (default 1)")
    parser.add_argument("--ack", action="store_true", help="request an acknowledgement")
    parser.add_argument("--mtu", type=int, default=JTS_MAX_PAYLOAD,
                        help=f"largest payload per packet (default {JTS_MAX_PAYLOAD})")
    parser.add_argument("--jsidl", action="extend", nargs=1, default=[], metavar="FILE",
                        help="a JSIDL file or folder whose messages encode too (repeatable; as a "
                             "profile's catalogue.jsidl)")
    parser.add_argument("--dialect", action="extend", nargs=1, default=[], metavar="NAME",
                        help="write the message as a speaker of this dialect reads it "
                        "(manipulator-1.0, iop; repeatable)")


def run(args: argparse.Namespace) -> int:
    """Encode and print the datagram(s)."""
    catalogue = profile_catalogue([Path(p) for p in args.jsidl])
    key: str | int = args.message
    if args.message.lower().startswith("0x"):
        key = int(args.message, 16)
    definition = catalogue.get(key) if isinstance(key, int) else _by_name(catalogue, key)
    if definition is None:
        hint = "" if args.jsidl else "; a message of your own needs --jsidl FILE"
        raise EncodeError(f"unknown message {args.message!r} (see 'edge-vis messages'"
                          f"{hint})")
    try:
        fields = json.loads(args.json)
    except json.JSONDecodeError as exc:
        raise EncodeError(f"--json is not valid JSON: {exc}") from None
    dialects = tuple(args.dialect)
    for name in dialects:
        if name not in catalogue.dialects():
            raise EncodeError(f"--dialect {name!r}: no such dialect (dialects: "
                              f"{', '.join(sorted(catalogue.dialects()))})")
    definition = catalogue.definition(definition.code, dialects) or definition
    payload = catalogue.encode(definition.name, record_from_json(fields, definition.body),
                               dialects)
    try:
        source = JausAddress.parse(args.source)
        destination = JausAddress.parse(args.destination)
    except ValueError as exc:
        raise EncodeError(str(exc)) from None
    packet = Packet(
        destination, source, payload, sequence=args.sequence, priority=args.priority,
        broadcast=Broadcast.GLOBAL if destination.is_broadcast else Broadcast.NONE,
        ack_nak=1 if args.ack else 0,
    )
    for part in fragment(packet, args.mtu):
        sys.stdout.write(pack_datagram([part]).hex() + "\n")
    return 0


def _by_name(catalogue: Catalogue, name: str) -> MessageDef | None:
    try:
        return catalogue.by_name(name)
    except KeyError:
        return None
