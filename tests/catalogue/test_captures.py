"""Every real datagram in the reference captures decodes to the values annotated beside it.

The tables of ``captures.md`` (sections 1-3: JAUS Toolset, SAE management pcap, JAUS++) and
``captures-jauspp.md`` are parsed as they are written; each row's datagram goes through
``unpack_datagram`` and ``default_catalogue().decode`` and must give the annotated header
(version, size, flags, addresses, sequence number, message code/name) and body values.
``captures.md`` annotates bodies only as hex plus prose notes, so its values are restated
below (``MD_VALUES``) in the same notation ``captures-jauspp.md`` uses per row.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import unpack_datagram

catalogue_module = pytest.importorskip("edge_vis.catalogue")

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"
CAPTURES = SHARED / "captures.md"
JAUSPP = SHARED / "captures-jauspp.md"

pytestmark = pytest.mark.skipif(not CAPTURES.is_file(),
                                reason=f"JAUS reference captures not found at {SHARED}")


@dataclass(frozen=True)
class Row:
    """One table row: where it is, the datagram and its annotation."""

    where: str
    data: bytes
    note: str


def _rows(path: Path, sections: tuple[str, ...]) -> Iterator[Row]:
    section = ""
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("## "):
            section = line[3:].strip()
            continue
        if not line.startswith("|") or not any(section.startswith(s) for s in sections):
            continue
        match = re.search(r"`([0-9a-fA-F]+)`", line)
        if not match:
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        where = f"{path.name}:{number} [{section.split()[0]} {cells[0]}]"
        yield Row(where, bytes.fromhex(match.group(1)), cells[-1])


def all_rows() -> list[Row]:
    if not CAPTURES.is_file():
        return []
    return [*_rows(CAPTURES, ("1.", "2.", "3.")), *_rows(JAUSPP, ("Datagrams",))]


ROWS = all_rows()


# -- header annotations ---------------------------------------------------------------------

@dataclass(frozen=True)
class Header:
    version: int
    size: int
    flags: int
    flag_parts: tuple[int, int, int, int]
    dst: str
    src: str
    seq: int
    code: int | None  # None: not written in the annotation
    name: str | None  # None: no payload (ACK/NAK)
    body: str | None  # hex of the body, when annotated
    rest: str  # body annotation in the captures-jauspp.md notation


FLAGS = r"flags=0x([0-9a-fA-F]{2})\(prio (\d) bcast (\d) ack (\d) df (\d)\)"
MD_HEADER = re.compile(
    rf"ver=(\d+) type/hc=0x00 size=(\d+) {FLAGS} dst=([\d.]+) src=([\d.]+) seq=(\d+) "
    r"msg=(?:0x([0-9A-F]{4}) (\w+)|\(none: ACK/NAK\)) body=([0-9a-f]+|-)")
PP_HEADER = re.compile(
    rf"v(\d+) size=(\d+) {FLAGS} ([\d.]+)->([\d.]+) seq=(\d+) · \*\*(.+?)\*\*\s*(.*)")


def header_of(row: Row) -> Header:
    if m := MD_HEADER.search(row.note):
        flag_parts = tuple(int(m.group(i)) for i in range(4, 8))
        code = int(m.group(11), 16) if m.group(11) else None
        body = None if m.group(13) == "-" else m.group(13)
        name = m.group(12)
        rest = MD_VALUES.get((row.data.hex(), name), "")
        return Header(int(m.group(1)), int(m.group(2)), int(m.group(3), 16), flag_parts,
                      m.group(8), m.group(9), int(m.group(10)), code, name, body or "", rest)
    if m := PP_HEADER.search(row.note):
        flag_parts = tuple(int(m.group(i)) for i in range(4, 8))
        name = None if m.group(11).startswith("(none") else m.group(11)
        rest = m.group(12)
        body = None
        if b := re.search(r"body=([0-9a-f]+)", rest):
            body = b.group(1)
        if "(no body)" in rest:
            body = ""
        # this notation writes ``source->destination``
        return Header(int(m.group(1)), int(m.group(2)), int(m.group(3), 16), flag_parts,
                      m.group(9), m.group(8), int(m.group(10)), None, name, body, rest)
    raise AssertionError(f"{row.where}: annotation not understood: {row.note}")


#: ``captures.md`` body values (from its notes), keyed by (datagram hex, message name)
MD_VALUES: dict[tuple[str, str], str] = {}


def _md(datagram: str, name: str, values: str) -> None:
    MD_VALUES[(datagram, name)] = values


# section 1: JTS node manager and example component 126.1.199
_md("0200110001c7017e0001012a00002b020000", "QueryIdentification", "QueryType=2")
_md("020024000101012a00c7017e00004b0211271053696d756c6174656456656869636c650100",
    "ReportIdentification", 'QueryType=2 Type=10001 Name[16]="SimulatedVehicle"')
_md("0200110001c7017e0001012a00002b040100", "QueryIdentification", "QueryType=4")
_md("020024000101012a00c7017e00004b0211271053696d756c6174656456656869636c650200",
    "ReportIdentification", 'QueryType=2 Type=10001 Name[16]="SimulatedVehicle"')
_md("0200140001c7017e0001012a00032b010101c70200", "QueryServices",
    "nodes=1 node=1 comps=1 comp=199")
_md("020073000101012a00c7017e00034b020101c700012575726e3a6a6175733a6a73733a6d6f62696c6974793a4c"
    "6f63616c506f736553656e736f7201000101c700012d75726e3a6a6175733a6a73733a6d6f62696c6974793a4c"
    "6f63616c576179706f696e744c69737444726976657201000300", "ReportServices",
    "nodes=2 node 1 comps=1 comp 199 inst 0 services=2: urn:jaus:jss:mobility:LocalPoseSensor "
    "v1.0 urn:jaus:jss:mobility:LocalWaypointListDriver v1.0")
_md("0200110001c7017e0001012a00012b020300", "QueryConfiguration", "QueryType=2")
# the prose note beside this capture reads "Status 0 = INITIALIZE"; its bytes say 2 (STANDBY)
_md("020015000101012a00c7017e00024002000000000400", "ReportStatus", "Status=2")
_md("0200120001c7017e0001012a000324ff010700", "QueryLocalPose", "PV=0x01FF")
_md("02001c000101012a00c7017e0003444300ffffff7fffffff7fff7f0500", "ReportLocalPose",
    "PV=0x0043 x=-0.0000233 y=-0.0000233 yaw=-0.0000479")
_md("0200110001c7017e0001012a000d00640800", "RequestControl", "Authority=100")
_md("020011000101012a00c7017e000f00000600", "ConfirmControl", "ResponseCode=0")
_md("02001c0001c7017e0001012a00f00107002c01040000000324ff010a00", "CreateEvent",
    "RequestID=7 EventType=0(periodic) rate=300(5.00 Hz) size=4 query=QueryLocalPose ff01")
_md("0200120001c7017e0001012a00f02103000b00", "QueryEvents", "vtag=3 value=0")
_md("0200110009ffffffff01012a00002b020c00", "QueryIdentification", "QueryType=2")
_md("020024000101012a00c7017e00004b0211271053696d756c6174656456656869636c650700",
    "ReportIdentification", 'QueryType=2 Type=10001 Name[16]="SimulatedVehicle"')
_md("020011000101012a00c7017e001000000800", "RejectControl", "ResponseCode=0")
_md("020015000101012a00c7017e00024002000000000900", "ReportStatus", "Status=2")
# section 2: SAE management pcap (126.1.20 -> 126.1.10)
for _hex, _status in (("020015000114017e000a017e00024002000000000200", 2),
                      ("020015000114017e000a017e00024001000000000300", 1),
                      ("020015000114017e000a017e00024005000000000400", 5),
                      ("020015000114017e000a017e00024001000000000500", 1),
                      ("020015000114017e000a017e00024002000000000800", 2)):
    _md(_hex, "ReportStatus", f"Status={_status}")
_md("02001100190a017e0014017e000d00c80100", "RequestControl", "Authority=200")
_md("02001100010a017e0014017e000d00c80c00", "RequestControl", "Authority=200")
_md("020011000114017e000a017e000f00000100", "ConfirmControl", "ResponseCode=0")
_md("020011000114017e000a017e000f00000700", "ConfirmControl", "ResponseCode=0")
_md("020011000114017e000a017e001000000600", "RejectControl", "ResponseCode=0")
_md("02001200010a017e0014017e00060000000500", "SetEmergency", "EmergencyCode=0")
_md("02001200010a017e0014017e00070000000700", "ClearEmergency", "EmergencyCode=0")
# section 3: JAUS++ robot 3.1.1 polled by OCU 90.1.1
_md("020011000101015a0001010300002b020100", "QueryIdentification", "QueryType=2")
_md("02002200010101030001015a00004b02214e0e434f505f53756273797374656d31ee60",
    "ReportIdentification", 'QueryType=2 Type=20001 Name[14]="COP_Subsystem1"')
_md("02001100010101030001015a00002b02f060", "QueryIdentification", "QueryType=2")
_md("02001100010101030001015a00002b02fc60", "QueryIdentification", "QueryType=2")
_md("02001200010101030001015a0003244701f160", "QueryLocalPose", "PV=0x0147")
_md("02001200010101030001015a0003244701fd60", "QueryLocalPose", "PV=0x0147")
_md("02001200010101030001015a0004240100f460", "QueryVelocityState", "PV=0x0001")
_md("02001200010101030001015a00042401000061", "QueryVelocityState", "PV=0x0001")
_md("02001b000101015a0001010300004b02214e07526f626f7420330200", "ReportIdentification",
    'QueryType=2 Type=20001 Name[7]="Robot 3"')
_md("02001b000101015a0001010300004b02214e07526f626f7420330800", "ReportIdentification",
    'QueryType=2 Type=20001 Name[7]="Robot 3"')
_md("020024000101015a000101030003444701ffffff7fffffff7fffffff7fff7f42c254080300",
    "ReportLocalPose", "PV=0x0147 x=-0.0000233 y=-0.0000233 z=-0.0000233 yaw=-0.0000479 "
    "TS(day 1 01:20:48.578)")
_md("020024000101015a000101030003444701cefbff7fbe530080a649038012849fc654080900",
    "ReportLocalPose", "PV=0x0147 x=-0.049989 y=0.998308 z=10.033255 yaw=0.099950 "
    "TS(day 1 01:20:49.671)")
_md("020015000101015a0001010300024002000000000400", "ReportStatus", "Status=2")
_md("020015000101015a0001010300024002000000000a00", "ReportStatus", "Status=2")
_md("020015000101015a00010103000d4000000000000500", "ReportControl",
    "controller=0.0.0 authority=0")
_md("020015000101015a00010103000d405a000101ff0b00", "ReportControl",
    "controller=90.1.1 authority=255")
_md("020016000101015a000101030004440100008000800600", "ReportVelocityState",
    "PV=0x0001 vx=0.0000")
_md("020016000101015a000101030004440100f9de5b800c00", "ReportVelocityState",
    "PV=0x0001 vx=0.913696")
_md("02001100010101030001015a000d00fffa60", "RequestControl", "Authority=255")
_md("020011000101015a00010103000f00000700", "ConfirmControl", "ResponseCode=0")


# -- body annotations -----------------------------------------------------------------------

def leaves(value: Any, key: str = "") -> Iterator[tuple[str, Any]]:
    """Scalar values in wire order, however the definition nests records and lists."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from leaves(v, k)
    elif isinstance(value, list):
        for v in value:
            yield from leaves(v, key)
    else:
        yield key, value


def _int(note: str, label: str) -> int:
    m = re.search(rf"\b{label}=(0x[0-9A-Fa-f]+|\d+)", note)
    assert m, f"annotation has no {label}: {note}"
    return int(m.group(1), 0)


POSE_KEYS = {
    "ReportGlobalPose": ["latitude", "longitude", "altitude", "position_rms", "roll", "pitch",
                         "yaw", "attitude_rms", "time_stamp"],
    "ReportLocalPose": ["x", "y", "z", "position_rms", "roll", "pitch", "yaw", "attitude_rms",
                        "time_stamp"],
    "ReportVelocityState": ["velocity_x", "velocity_y", "velocity_z", "velocity_rms",
                            "roll_rate", "pitch_rate", "yaw_rate", "rate_rms", "time_stamp"],
}
#: annotation label -> field name
SHORT = {"lat": "latitude", "lon": "longitude", "alt": "altitude", "yaw": "yaw", "x": "x",
         "y": "y", "z": "z", "vx": "velocity_x", "yawRate": "yaw_rate"}


def check_time_stamp(value: dict[str, int], note: str) -> None:
    m = re.search(r"TS\(day (\d+) (\d+):(\d+):(\d+)\.(\d+)\)", note)
    if m:
        day, hour, minute, second, ms = map(int, m.groups())
        assert value == {"milliseconds": ms, "seconds": second, "minutes": minute,
                         "hour": hour, "day": day}


def check_body(name: str, fields: dict[str, Any], note: str, catalogue: Any) -> int:
    """Assert the annotated values of one message; return how many values were checked."""
    checked = 0

    def same(actual: Any, expected: Any, what: str) -> None:
        nonlocal checked
        assert actual == expected, f"{name} {what}: expected {expected!r}, decoded {actual!r}"
        checked += 1

    if note.strip() == "(no body)" or (not note and not fields):
        same(fields, {}, "body")
    elif name in ("QueryIdentification", "QueryConfiguration"):
        same(fields["query_type"], _int(note, "QueryType"), "query_type")
    elif name == "ReportIdentification":
        m = re.search(r'QueryType=(\d+) Type=(\d+) Name\[(\d+)\]="([^"]*)"', note)
        assert m, note
        same(fields["query_type"], int(m.group(1)), "query_type")
        same(fields["type"], int(m.group(2)), "type")
        same(fields["identification"], m.group(4), "identification")
        same(len(fields["identification"]), int(m.group(3)), "identification length")
    elif name == "ReportConfiguration":
        values = list(leaves(fields))
        same(len(fields["node_list"]), _int(note, "nodes"), "node count")
        same(values, [("node_id", _int(note, "node")), ("component_id", _int(note, "comp")),
                      ("instance_id", _int(note, "inst"))], "nodes")
    elif name == "QueryServices":
        same(len(fields["node_list"]), _int(note, "nodes"), "node count")
        same(list(leaves(fields)), [("node_id", _int(note, "node")),
                                    ("component_id", _int(note, "comp"))], "nodes")
    elif name == "ReportServices":
        same(len(fields["node_list"]), _int(note, "nodes"), "node count")
        services = re.findall(r"(urn:\S+) v(\d+)\.(\d+)", note)
        same(len(services), _int(note, "services"), "annotation service count")
        values = [v for k, v in leaves(fields)
                  if k in ("uri", "major_version_number", "minor_version_number")]
        same(values, [x for uri, major, minor in services
                      for x in (uri, int(major), int(minor))], "services")
        same({v for k, v in leaves(fields) if k == "component_id"},
             {int(re.search(r"comp (\d+)", note).group(1))}, "component ids")
    elif name == "ReportStatus":
        same(fields["status"], _int(note, "Status"), "status")
        same(fields["reserved"], 0, "reserved")
    elif name == "ReportTimeout":
        same(fields["timeout"], _int(note, "Timeout"), "timeout")
    elif name in ("ReportAuthority", "RequestControl"):
        same(fields["authority_code"], _int(note, "Authority"), "authority_code")
    elif name in ("ConfirmControl", "RejectControl"):
        same(fields["response_code"], _int(note, "ResponseCode"), "response_code")
    elif name in ("SetEmergency", "ClearEmergency"):
        same(fields["emergency_code"], _int(note, "EmergencyCode"), "emergency_code")
    elif name == "ReportControl":
        m = re.search(r"controller=(\d+)\.(\d+)\.(\d+) authority=(\d+)", note)
        assert m, note
        same((fields["subsystem_id"], fields["node_id"], fields["component_id"],
              fields["authority_code"]), tuple(map(int, m.groups())), "controller")
    elif name in ("QueryGlobalPose", "QueryLocalPose", "QueryVelocityState"):
        same(fields["presence_vector"], _int(note, "PV"), "presence_vector")
    elif name in POSE_KEYS:
        pv = _int(note, "PV")
        present = [k for bit, k in enumerate(POSE_KEYS[name]) if pv >> bit & 1]
        same(list(fields), present, f"fields present for PV 0x{pv:04X}")
        for label, value in re.findall(r"\b(\w+)=(-?\d+\.\d+)", note):
            key = SHORT[label]
            assert math.isclose(fields[key], float(value), abs_tol=1e-5), (
                f"{name} {key}: expected {value}, decoded {fields[key]!r}")
            checked += 1
        if "time_stamp" in fields and "TS(" in note:
            check_time_stamp(fields["time_stamp"], note)
            checked += 1
    elif name == "ReportTime":
        pv = _int(note, "PV")
        same(sorted(fields), sorted(k for bit, k in enumerate(["time_stamp", "date_stamp"])
                                    if pv >> bit & 1), "fields present")
        raw = int.from_bytes(bytes.fromhex(note.split()[-1]), "little")
        same(fields["time_stamp"], {"milliseconds": raw & 0x3FF, "seconds": raw >> 10 & 63,
                                    "minutes": raw >> 16 & 63, "hour": raw >> 22 & 31,
                                    "day": raw >> 27}, "time_stamp")
    elif name == "CreateEvent":
        same(fields["request_id"], _int(note, "RequestID"), "request_id")
        same(fields["event_type"], _int(note, "EventType"), "event_type")
        m = re.search(r"rate=(\d+)\((\d+\.\d\d) Hz\)", note)
        assert m, note
        same(f"{fields['requested_periodic_rate']:.2f}", m.group(2), "rate in Hz")
        same(round(fields["requested_periodic_rate"] * 65535 / 1092), int(m.group(1)),
             "rate on the wire")
        checked += check_inner_query(fields["query_message"], note, catalogue)
    elif name == "ConfirmEventRequest":
        same(fields["request_id"], _int(note, "RequestID"), "request_id")
        same(fields["event_id"], _int(note, "EventID"), "event_id")
        m = re.search(r"ConfirmedRate=(\d+)\((\d+\.\d\d) Hz\)", note)
        assert m, note
        same(f"{fields['confirmed_periodic_rate']:.2f}", m.group(2), "rate in Hz")
    elif name == "CancelEvent":
        same(fields["request_id"], _int(note, "RequestID"), "request_id")
        same(fields["event_id"], _int(note, "EventID"), "event_id")
    elif name == "QueryEvents":
        (choice,) = fields["query_events_var"]
        alternatives = [a.name for a in
                        catalogue.by_name("QueryEvents").body.fields[0].type.alternatives]
        same(alternatives.index(choice), _int(note, "vtag"), "variant tag")
        same([v for _, v in leaves(fields)], [_int(note, "value")], "variant value")
    elif name == "ReportEvents":
        events = fields["event_list"]
        same(len(events), _int(note, "count"), "event count")
        same((events[0]["event_type"], events[0]["event_id"]),
             (_int(note, "type"), _int(note, "id")), "event")
        checked += check_inner_query(events[0]["query_message"], note, catalogue)
    elif name == "Event":
        same(fields["event_id"], _int(note, "EventID"), "event_id")
        same(fields["sequence_number"], _int(note, "EventSeq"), "sequence_number")
        report = fields["report_message"]
        same(len(report), _int(note, "size"), "report size")
        inner = catalogue.decode(report)
        m = re.search(r"inner=(\w+) (.*)", note)
        assert m, note
        same(inner.name, m.group(1), "inner report")
        checked += check_body(inner.name, inner.fields, m.group(2), catalogue)
    else:
        raise AssertionError(f"no check written for {name}: {note}")
    return checked


def check_inner_query(query: bytes, note: str, catalogue: Any) -> int:
    """The query carried by CreateEvent / ReportEvents: its name and bytes as annotated.

    Only named, not decoded: one captured client put a 4-byte presence vector in a
    QueryVelocityState (whose JSIDL field is 2 bytes), and the relay forwards such a query
    as the bytes it is.
    """
    m = re.search(r"query=(\w+) ([0-9a-f]+)", note)
    assert m, note
    definition = catalogue.get(int.from_bytes(query[:2], "little"))
    assert definition is not None and definition.name == m.group(1), f"query {query.hex()}"
    assert query[2:].hex() == m.group(2)
    if (size := re.search(r"size=(\d+)", note)) is not None:
        assert len(query) == int(size.group(1))
    return 2


# -- the tests ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def catalogue() -> Any:
    return catalogue_module.default_catalogue()


#: the one captured datagram that is malformed on purpose of its sender: a hand-written
#: client's QueryServiceList whose component record sets presence-vector bit 0 (search
#: filter present) but ends after the PV; JAUS++ does not implement the message anyway
MALFORMED = {"02001800010101960001012a00042b01009600010101010400": 0x2B04}


@pytest.mark.parametrize("row", ROWS, ids=[r.where.split()[0] for r in ROWS])
def test_capture_row_decodes_to_its_annotation(row: Row, catalogue: Any) -> None:
    print(row.where, row.note)
    head = header_of(row)
    (packet,) = unpack_datagram(row.data)
    assert row.data[0] == head.version == 2
    assert len(row.data) == 1 + head.size, "datagram length is 1 + DataSize"
    assert packet.data_size == head.size
    assert packet.flags == head.flags
    assert (packet.priority, packet.broadcast, packet.ack_nak, packet.data_flags) == \
        head.flag_parts
    assert packet.destination == JausAddress.parse(head.dst)
    assert packet.source == JausAddress.parse(head.src)
    assert packet.sequence == head.seq
    if head.name is None:  # an ACK carries no payload
        assert packet.payload == b""
        assert packet.message_code is None
        return
    if head.code is not None:
        assert packet.message_code == head.code
    if row.data.hex() in MALFORMED:
        from edge_vis.errors import DecodeError

        with pytest.raises(DecodeError) as caught:
            catalogue.decode(packet.payload)
        assert caught.value.code == MALFORMED[row.data.hex()]
        return
    message = catalogue.decode(packet.payload)
    assert message.code == packet.message_code
    assert message.name == head.name, f"0x{message.code:04X} decoded as {message.name}"
    assert message.fields is not None
    if head.body is not None:
        assert message.body.hex() == head.body
    check_body(head.name, message.fields, head.rest, catalogue)
    if head.name == "Event":  # the relay's own way in: unwrap_event
        inner = catalogue_module.unwrap_event(message, catalogue)
        assert inner == catalogue.decode(message.fields["report_message"])
        assert inner.name == re.search(r"inner=(\w+)", head.rest).group(1)


def test_every_table_was_read() -> None:
    """The parser found every row (guards against a silently skipped table)."""
    by_file: dict[str, int] = {}
    for row in ROWS:
        name = row.where.split(":")[0]
        by_file[name] = by_file.get(name, 0) + 1
    assert by_file == {"captures.md": 25 + 22 + 24, "captures-jauspp.md": 79}, by_file


def test_captures_cover_the_message_kinds(catalogue: Any) -> None:
    """Each kind of message with values gets them checked (counted over all rows)."""
    kinds: dict[str, int] = {}
    for row in ROWS:
        head = header_of(row)
        if head.name and row.data.hex() not in MALFORMED:
            message = catalogue.decode(unpack_datagram(row.data)[0].payload)
            kinds[head.name] = kinds.get(head.name, 0) + check_body(
                head.name, message.fields, head.rest, catalogue)
    print(f"\nvalues checked per message kind: {kinds}")
    for name in ("ReportIdentification", "ReportServices", "ReportGlobalPose", "Event",
                 "CreateEvent", "ConfirmEventRequest", "ReportControl", "ReportStatus",
                 "QueryEvents", "ReportEvents", "ReportLocalPose", "ReportVelocityState",
                 "ReportConfiguration", "ReportTime", "RequestControl", "ConfirmControl"):
        assert kinds.get(name, 0) > 0, f"no value of {name} checked"


def test_unknown_codes_pass_through(catalogue: Any) -> None:
    """A code nobody defines is kept as raw bytes: routing never needs to decode."""
    free = next(code for code in range(0x7000, 0x8000) if catalogue.get(code) is None)
    for row in ROWS[:10]:
        packet = unpack_datagram(row.data)[0]
        if not packet.payload:
            continue
        payload = free.to_bytes(2, "little") + packet.payload[2:]
        message = catalogue.decode(payload)
        assert (message.code, message.name, message.fields) == (free, None, None)
        assert message.body == packet.payload[2:]
        assert message.definition is None
