"""The catalogue: definitions by code and name, payload coding, plugins, Events."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from codec_defs import (
    EVENT,
    QUERY_EVENTS,
    REPORT_GLOBAL_POSE,
    REPORT_IDENTIFICATION,
    REPORT_TIME,
    TEST,
)

from edge_vis import plugins
from edge_vis.catalogue import (
    Catalogue,
    Message,
    default_catalogue,
    unwrap_event,
    wrap_event,
)
from edge_vis.codec.types import (
    Enum,
    JausMessage,
    MessageDef,
    f,
    message,
    opt,
    record,
    u8,
    u16,
    u32,
)
from edge_vis.errors import (
    DecodeError,
    EncodeError,
    PluginConflictError,
    PluginLoadError,
)
from edge_vis.jaus.transport import unpack_datagram

SHARED = Path(__file__).resolve().parents[3] / "shared" / "jaus"

# captures-jauspp.md, t=5.053: Event(EventID 0, seq 0) carrying a ReportGlobalPose
POSE_PAYLOAD = bytes.fromhex("0244" "4701178696a8655e2146083f0f395e94402dd1b2")
EVENT_PAYLOAD = bytes.fromhex("f141" "00" "00" "16000000") + POSE_PAYLOAD


def other_set(defn: MessageDef, **changes: object) -> MessageDef:
    """``defn`` as another set would declare it."""
    fields = {"code": defn.code, "name": defn.name, "body": defn.body,
              "service_set": "other", **changes}
    return MessageDef(**fields)  # type: ignore[arg-type]


@pytest.fixture
def cat() -> Catalogue:
    return Catalogue([EVENT, REPORT_GLOBAL_POSE, QUERY_EVENTS, REPORT_TIME], source="tests")


# -- building and looking up ---------------------------------------------------------------


def test_lookup(cat: Catalogue) -> None:
    assert len(cat) == 4
    assert cat.get(0x4402) is REPORT_GLOBAL_POSE and cat.get(0x9999) is None
    assert cat.by_name("Event") is EVENT
    with pytest.raises(KeyError, match="Nope"):
        cat.by_name("Nope")
    assert [d.code for d in cat] == [0x21F0, 0x4011, 0x41F1, 0x4402]
    assert 0x4402 in cat and "ReportTime" in cat and 0x1234 not in cat
    assert cat.sets() == {TEST: 4}
    assert cat.source(0x4402) == "tests"


def test_a_different_definition_of_a_taken_code_names_both(cat: Catalogue) -> None:
    clash = other_set(REPORT_TIME, name="ReportClock")
    with pytest.raises(PluginConflictError) as info:
        cat.add([clash], source="plugin clock (clock:MESSAGES)")
    text = str(info.value)
    assert "0x4011" in text and "ReportClock" in text and "ReportTime" in text
    assert "set other" in text and "plugin clock" in text
    assert f"set {TEST}" in text and "tests" in text
    assert cat.get(0x4011) is REPORT_TIME


def test_the_same_definition_twice_is_kept_once(cat: Catalogue) -> None:
    cat.add([other_set(REPORT_TIME)], source="again")
    assert len(cat) == 4 and cat.get(0x4011) is REPORT_TIME


def test_replace_lets_the_new_definition_win(cat: Catalogue) -> None:
    newer = other_set(REPORT_TIME, name="ReportClock")
    cat.add([newer], source="override", replace=True)
    assert cat.get(0x4011) is newer and cat.by_name("ReportClock") is newer
    with pytest.raises(KeyError):
        cat.by_name("ReportTime")
    assert cat.sets() == {TEST: 3, "other": 1}


def test_broken_definitions_are_refused_whole(cat: Catalogue) -> None:
    nine = tuple(opt(f"f{i}", u8) for i in range(9))
    bad = message(0xD0AA, "TooMany", *nine, pv=u8, service_set="x")
    good = message(0xD0AB, "Fine", f("a", u8), service_set="x")
    with pytest.raises(PluginLoadError, match=r"TooMany \(0xD0AA\) from my-set: .*presence"):
        cat.add([good, bad], source="my-set")
    with pytest.raises(PluginLoadError, match="not a MessageDef"):
        cat.add([good, "ReportPose"], source="my-set")  # type: ignore[list-item]
    assert 0xD0AB not in cat


def test_names_can_repeat_across_sets() -> None:
    mobility = message(0x041E, "ExecuteList", f("speed", u16), service_set="mobility")
    manipulator = message(0x061E, "ExecuteList", f("speed", u16), service_set="manipulator")
    cat = Catalogue([mobility, manipulator])
    assert cat.by_name("ExecuteList") is mobility
    assert cat.by_name("ExecuteList", "manipulator") is manipulator
    assert cat.encode(0x061E, {"speed": 1}) == bytes.fromhex("1e06" "0100")


def test_copy_is_independent(cat: Catalogue) -> None:
    other = cat.copy()
    other.add([message(0xD0AC, "Extra", service_set="x")])
    assert 0xD0AC in other and 0xD0AC not in cat


# -- payloads ------------------------------------------------------------------------------


def test_decode_known_and_unknown(cat: Catalogue) -> None:
    msg = cat.decode(bytes.fromhex("1140" "01" "402dd1b2"))
    assert (msg.code, msg.name, msg.definition) == (0x4011, "ReportTime", REPORT_TIME)
    assert msg.fields == {"time_stamp": {
        "milliseconds": 320, "seconds": 11, "minutes": 17, "hour": 11, "day": 22}}
    assert msg.body == bytes.fromhex("01" "402dd1b2")
    assert msg.payload == bytes.fromhex("1140" "01" "402dd1b2")
    raw = cat.decode(bytes.fromhex("3412" "ffff"))  # routing never needs to decode
    assert raw == Message(0x1234, None, None, b"\xff\xff", None)
    assert raw.payload == bytes.fromhex("3412ffff")


def test_decode_errors_carry_the_code(cat: Catalogue) -> None:
    with pytest.raises(DecodeError) as info:
        cat.decode(bytes.fromhex("1140" "01" "402dd1"))
    assert info.value.code == 0x4011 and info.value.path == "time_stamp"
    with pytest.raises(DecodeError, match="no 2-byte message code"):
        cat.decode(b"\x11")


def test_encode_by_name_or_code(cat: Catalogue) -> None:
    expected = bytes.fromhex("f021" "0300")
    assert cat.encode("QueryEvents", {"query_events_variant": {"all_events": 0}}) == expected
    assert cat.encode(0x21F0, {"query_events_variant": {"all_events": 0}}) == expected
    with pytest.raises(EncodeError, match="QueryEvent'"):
        cat.encode("QueryEvent", {})
    with pytest.raises(EncodeError, match="0x1234"):
        cat.encode(0x1234, {})
    with pytest.raises(EncodeError) as info:
        cat.encode("ReportTime", {"time_stamp": {"hour": 24, "day": 40}})
    assert info.value.code == 0x4011 and info.value.path == "time_stamp.day"


# -- events --------------------------------------------------------------------------------


def test_unwrap_a_captured_event(cat: Catalogue) -> None:
    event = cat.decode(EVENT_PAYLOAD)
    inner = cat.unwrap_event(event)
    assert inner.name == "ReportGlobalPose" and inner.payload == POSE_PAYLOAD
    assert inner.fields is not None
    assert inner.fields["latitude"] == pytest.approx(28.538426, abs=1e-6)
    raw_event = Message(0x41F1, None, None, EVENT_PAYLOAD[2:])  # not decoded yet
    assert unwrap_event(raw_event, cat) == inner


def test_wrap_event_rebuilds_the_capture(cat: Catalogue) -> None:
    assert cat.wrap_event(0, 0, POSE_PAYLOAD) == EVENT_PAYLOAD
    assert wrap_event(0, 0, POSE_PAYLOAD, cat) == EVENT_PAYLOAD
    again = cat.unwrap_event(cat.decode(cat.wrap_event(3, 255, POSE_PAYLOAD)))
    assert again.payload == POSE_PAYLOAD


def test_unwrap_unknown_and_broken_reports(cat: Catalogue) -> None:
    unknown = cat.unwrap_event(cat.decode(cat.wrap_event(1, 2, bytes.fromhex("0448" "abcd"))))
    assert unknown.code == 0x4804 and unknown.name is None and unknown.body == b"\xab\xcd"
    broken = cat.decode(cat.wrap_event(1, 2, POSE_PAYLOAD[:-1]))
    with pytest.raises(DecodeError, match="inside Event") as info:
        cat.unwrap_event(broken)
    assert info.value.code == 0x4402 and info.value.path == "time_stamp"
    with pytest.raises(ValueError, match="not an Event"):
        cat.unwrap_event(cat.decode(POSE_PAYLOAD))


def test_events_are_found_by_type_not_by_field_names() -> None:
    renamed = message(
        0x41F1, "Event",
        f("header", record(f("id", u8), f("seq", u8))),
        f("payload", JausMessage(u32)),
        service_set="renamed",
    )
    cat = Catalogue([renamed, REPORT_GLOBAL_POSE])
    payload = cat.wrap_event(7, 9, POSE_PAYLOAD)
    assert payload == bytes.fromhex("f141" "07" "09" "16000000") + POSE_PAYLOAD
    assert cat.decode(payload).fields["header"] == {"id": 7, "seq": 9}  # type: ignore[index]
    assert cat.unwrap_event(cat.decode(payload)).name == "ReportGlobalPose"
    with pytest.raises(KeyError, match="no 'Event'"):
        Catalogue([REPORT_GLOBAL_POSE]).wrap_event(0, 0, POSE_PAYLOAD)


# -- the default catalogue -----------------------------------------------------------------


def test_default_catalogue_loads_builtin_sets_and_plugins() -> None:
    cat = default_catalogue()
    assert cat is default_catalogue()
    try:
        from edge_vis.jaus.messages import BUILTIN_SETS
    except ImportError:
        BUILTIN_SETS = ()
    sources = {cat.source(d.code).rsplit(".", 1)[-1] for d in cat}
    assert set(BUILTIN_SETS) <= sources
    for entry in plugins.entries(plugins.MESSAGES):
        assert f"plugin {entry.name} ({entry.target})" in {cat.source(d.code) for d in cat}
    assert sum(cat.sets().values()) == len(cat)


@pytest.fixture
def plugin_slot() -> Iterator[str]:
    name = "codec-test-plugin"
    default_catalogue.cache_clear()
    yield name
    plugins.unregister(plugins.MESSAGES, name)
    default_catalogue.cache_clear()


def test_a_plugin_that_fails_to_import_is_named(plugin_slot: str) -> None:
    plugins.register(plugins.MESSAGES, plugin_slot, "no_such_module_xyz:MESSAGES")
    with pytest.raises(PluginLoadError, match=plugin_slot):
        default_catalogue()


def test_a_plugin_that_is_not_a_message_set_is_named(plugin_slot: str) -> None:
    plugins.register(plugins.MESSAGES, plugin_slot, ("not", "definitions"))
    with pytest.raises(PluginLoadError, match=f"{plugin_slot}.*tuple of MessageDef"):
        default_catalogue()


def test_a_plugin_claiming_a_builtin_code_conflicts(plugin_slot: str) -> None:
    event = default_catalogue().by_name("Event")
    default_catalogue.cache_clear()
    fake = message(event.code, "MyEvent", f("x", u8), service_set="mine")
    plugins.register(plugins.MESSAGES, plugin_slot, (fake,))
    with pytest.raises(PluginConflictError) as info:
        default_catalogue()
    assert plugin_slot in str(info.value) and "MyEvent" in str(info.value)
    assert "set mine" in str(info.value) and f"set {event.service_set}" in str(info.value)


def test_a_plugin_set_is_added(plugin_slot: str) -> None:
    mine = message(0xDEAD, "MyReport", f("x", u8), service_set="mine")
    plugins.register(plugins.MESSAGES, plugin_slot, (mine,))
    cat = default_catalogue()
    assert cat.get(0xDEAD) is mine and cat.sets()["mine"] == 1
    assert cat.decode(bytes.fromhex("adde" "05")).fields == {"x": 5}


def captured_events() -> list[tuple[bytes, str]]:
    path = SHARED / "captures-jauspp.md"
    if not path.exists():
        return []
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("|") and "**Event**" in line:
            hex_text = re.search(r"`([0-9a-f]+)`", line)
            assert hex_text
            rows.append((bytes.fromhex(hex_text.group(1)), line.split("**Event**", 1)[1]))
    return rows


def test_every_captured_event_unwraps_with_the_default_catalogue() -> None:
    rows = captured_events()
    if not rows:
        pytest.skip(f"{SHARED} not present")
    cat = default_catalogue()
    for datagram, note in rows:
        (packet,) = unpack_datagram(datagram)
        event = cat.decode(packet.payload)
        inner = cat.unwrap_event(event)
        assert inner.name is not None and inner.name in note, note
        assert inner.fields is not None
        if inner.name == "ReportGlobalPose":
            lat = float(re.search(r"lat=(-?[\d.]+)", note).group(1))  # type: ignore[union-attr]
            assert inner.fields["latitude"] == pytest.approx(lat, abs=1e-6)
        wrapped = cat.wrap_event(
            event.fields["event_id"], event.fields["sequence_number"], inner.payload  # type: ignore[index]
        )
        assert wrapped == packet.payload


def test_documentation_differences_are_not_conflicts(cat: Catalogue) -> None:
    relabelled = message(
        0x21F0, "QueryEvents",
        f("query_events_variant", QUERY_EVENTS.body.fields[0].type, jsidl="QueryEventsVar"),
        service_set="other", doc="another copy",
    )
    cat.add([relabelled], source="copy")
    assert cat.get(0x21F0) is QUERY_EVENTS
    time_labels = message(
        0x4011, "ReportTime",
        opt("time_stamp", REPORT_TIME.body.fields[0].type),
        opt("date_stamp", Enum(u16, {0: "a label the other copy lacks"})),
        pv=u8, service_set="other",
    )
    with pytest.raises(PluginConflictError):  # a bit field is not an integer: conflict
        cat.add([time_labels], source="labels")
    ident = Catalogue([REPORT_IDENTIFICATION])
    other_labels = message(
        0x4B00, "ReportIdentification",
        f("query_type", Enum(u8, {1: "SYSTEM"}, units="none")),
        *REPORT_IDENTIFICATION.body.fields[1:],
        service_set="other",
    )
    ident.add([other_labels], source="labels")  # labels are documentation: same message
    assert ident.get(0x4B00) is REPORT_IDENTIFICATION
    wider = message(0x21F0, "QueryEvents", f("query_events_variant", u16), service_set="x")
    with pytest.raises(PluginConflictError):
        cat.add([wider], source="wider")
