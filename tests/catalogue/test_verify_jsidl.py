"""Every built-in message definition matches the public JSIDL, read independently.

``tests/jsidl_walk.py`` reads the JAUS Toolset (``jsidl/``) and IOP (``jsidl-iop/``) JSIDL
without using ``edge_vis.catalogue.jsidl`` and reduces every message to its flattened wire
items; here
each built-in definition in ``default_catalogue()`` is reduced the same way and compared:
code, name, field order and names, types and signedness, scale limits, named values,
presence-vector widths and bits, list count widths, variant tags, string and byte counts.
Where the two JSIDL sets disagree for one code, either layout is accepted and the one
matched is reported.
Run with ``-s`` to see the counts.
"""

from __future__ import annotations

import importlib
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from edge_vis.codec.types import (
    BitField,
    Enum,
    Field,
    List,
    MessageDef,
    Scaled,
    SubField,
    Variant,
    f,
    message,
    opt,
    record,
    u8,
    u16,
    u32,
)

TESTS = Path(__file__).resolve().parents[1]
if str(TESTS) not in sys.path:  # the test-only JSIDL reader lives beside the test folders
    sys.path.append(str(TESTS))
from jsidl_walk import JsidlMessage, compare_items, flatten_record, load_all  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"
ROOTS = ((SHARED / "jsidl", "JTS"), (SHARED / "jsidl-iop", "IOP"))
#: distinct message codes in the two JSIDL sets (338) minus the few that collide or that no
#: built-in set is expected to carry
EXPECTED_MINIMUM = 330

pytestmark = pytest.mark.skipif(not (SHARED / "jsidl").is_dir(),
                                reason=f"JAUS reference material not found at {SHARED}")


def builtin_definitions() -> list[object]:
    """Every built-in MessageDef, taken from ``default_catalogue()`` when it exists.

    The message modules say what is built in; the catalogue must hold each of them (the
    same definition), so a set that fails to load into the catalogue is caught here too.
    """
    try:
        messages = importlib.import_module("edge_vis.jaus.messages")
    except ImportError:
        return []
    defs = []
    for set_name in getattr(messages, "BUILTIN_SETS", ()):
        module = importlib.import_module(f"edge_vis.jaus.messages.{set_name}")
        defs.extend(module.MESSAGES)
    try:
        from edge_vis.catalogue import default_catalogue
    except ImportError:
        return defs
    catalogue = default_catalogue()
    held = []
    for defn in defs:
        got = catalogue.get(defn.code)
        assert got is not None, (
            f"0x{defn.code:04X} {defn.name} ({defn.service_set}) is built in but missing "
            f"from default_catalogue()")
        assert got == defn, (
            f"0x{defn.code:04X}: default_catalogue() holds {got.name} from {got.service_set}, "
            f"not the built-in {defn.name} from {defn.service_set}")
        held.append(got)
    return held


@dataclass(repr=False)
class Verdict:
    checked: int = 0
    mismatches: list[str] = field(default_factory=list)
    #: codes where JTS and IOP disagree: (code, name, matched source labels)
    divergent: list[tuple[int, str, str]] = field(default_factory=list)
    per_set: dict[str, int] = field(default_factory=dict)
    definitions: list[object] = field(default_factory=list)
    jsidl: dict[int, list[JsidlMessage]] = field(default_factory=dict)


def _labels(msg: JsidlMessage) -> str:
    return ", ".join(sorted({f"{label}:{path.split('/')[0]}" for label, path in msg.sources}))


def verify(defn: object, candidates: list[JsidlMessage]) -> tuple[list[str], JsidlMessage | None]:
    """Problems of ``defn`` against the best candidate; empty when one matches exactly."""
    actual = flatten_record(defn.body)
    results = []
    for cand in candidates:
        problems = compare_items(cand.items, actual)
        if cand.name != defn.name:
            problems.insert(0, f"name: expected {cand.name!r}, actual {defn.name!r}")
        if not problems:
            return [], cand
        results.append((cand.name != defn.name, len(problems), problems, cand))
    results.sort(key=lambda r: (r[0], r[1]))
    _, _, problems, cand = results[0]
    return [f"{p}   [JSIDL {_labels(cand)}]" for p in problems], None


@pytest.fixture(scope="module")
def verdict() -> Verdict:
    result = Verdict(jsidl=load_all(ROOTS))
    result.definitions = builtin_definitions()
    for defn in result.definitions:
        head = f"0x{defn.code:04X} {defn.name} ({defn.service_set})"
        candidates = result.jsidl.get(defn.code)
        result.checked += 1
        result.per_set[defn.service_set] = result.per_set.get(defn.service_set, 0) + 1
        if not candidates:
            result.mismatches.append(f"{head}: code not defined by any JSIDL file")
            continue
        problems, matched = verify(defn, candidates)
        result.mismatches.extend(f"{head}: {p}" for p in problems)
        if matched is not None and len(candidates) > 1:
            others = "; ".join(f"{c.name} in {_labels(c)}" for c in candidates
                               if c is not matched)
            result.divergent.append((defn.code, defn.name, f"{_labels(matched)} (not {others})"))
    print(f"\nverified {result.checked} built-in messages against "
          f"{len(result.jsidl)} JSIDL message codes; per set: {result.per_set}")
    for code, name, labels in result.divergent:
        print(f"  0x{code:04X} {name}: the JSIDL sets differ; matches {labels}")
    return result


def test_every_builtin_message_matches_the_jsidl(verdict: Verdict) -> None:
    shown = "\n".join(verdict.mismatches[:60])
    more = len(verdict.mismatches) - 60
    tail = f"\n... and {more} more" if more > 0 else ""
    assert not verdict.mismatches, (
        f"{len(verdict.mismatches)} differences in {verdict.checked} messages checked:\n"
        f"{shown}{tail}")


def test_the_catalogue_covers_the_jsidl_sets(verdict: Verdict) -> None:
    missing = sorted(set(verdict.jsidl) - {d.code for d in verdict.definitions})
    print(f"\n{verdict.checked} messages verified; JSIDL codes without a built-in "
          f"definition: {len(missing)}: "
          + ", ".join(f"0x{c:04X} {'/'.join(m.name for m in verdict.jsidl[c])}"
                      for c in missing[:30]))
    assert verdict.checked >= EXPECTED_MINIMUM, (
        f"only {verdict.checked} built-in messages were verified against the JSIDL "
        f"(expected at least {EXPECTED_MINIMUM}); per set: {verdict.per_set}; e.g. missing: "
        + ", ".join(f"0x{c:04X} {verdict.jsidl[c][0].name}" for c in missing[:15]))


def test_declared_services_come_from_the_jsidl(verdict: Verdict) -> None:
    """A built-in message names only services whose JSIDL declares that message."""
    problems = []
    for defn in verdict.definitions:
        declared = {s for cand in verdict.jsidl.get(defn.code, []) for s in cand.services}
        if not declared:  # no service lists it (e.g. list elements): nothing to hold it to
            print(f"0x{defn.code:04X} {defn.name}: no JSIDL service declares it")
            continue
        for uri, version in defn.services:
            if (uri, version) not in declared:
                problems.append(f"0x{defn.code:04X} {defn.name}: service {uri} v{version} "
                                f"does not declare it (JSIDL: {sorted(declared)})")
    assert not problems, "\n".join(problems[:40])


def test_no_two_builtin_sets_claim_one_code(verdict: Verdict) -> None:
    seen: dict[int, object] = {}
    clashes = []
    for defn in verdict.definitions:
        other = seen.setdefault(defn.code, defn)
        if other is not defn:
            clashes.append(f"0x{defn.code:04X}: {other.name} ({other.service_set}) and "
                           f"{defn.name} ({defn.service_set})")
    assert not clashes, "\n".join(clashes)


def test_the_reader_finds_the_known_layouts() -> None:
    """The independent reader itself, on layouts written down in wire-facts.md."""
    jsidl = load_all(ROOTS)
    pose = next(m for m in jsidl[0x4402] if m.name == "ReportGlobalPose")
    pv, lat, lon = pose.items[:3]
    assert (pv.kind, pv.bits) == ("pv", 16)
    assert (lat.name, lat.kind, lat.bits, lat.lower, lat.upper, lat.gate) == (
        "latitude", "scaled", 32, -90.0, 90.0, (0,))
    assert (lon.name, lon.gate) == ("longitude", (1,))
    assert [i.gate for i in pose.items[1:]] == [(b,) for b in range(9)]
    event = jsidl[0x41F1][0]
    assert [(i.name, i.kind, i.bits) for i in event.items] == [
        ("event_id", "int", 8), ("sequence_number", "int", 8), ("report_message", "bytes", 32)]
    services = jsidl[0x4B03][0]
    (nodes,) = services.items
    assert (nodes.kind, nodes.bits) == ("list", 8)
    assert [i.kind for i in nodes.element] == ["int", "list"]
    query_events = jsidl[0x21F0][0].items[0]
    assert query_events.kind == "variant" and [t for t, _, _ in query_events.alternatives] == [
        0, 1, 2, 3]
    reject = jsidl[0x01F4][0]
    assert [(i.kind, i.gate) for i in reject.items] == [
        ("pv", ()), ("int", ()), ("int", (0,)), ("fixstr", (1,))]
    assert len(jsidl) >= 330


# -- the comparison itself can fail, and says where -----------------------------------------

TIME_STAMP = BitField(u32, (SubField("milliseconds", 0, 9), SubField("seconds", 10, 15),
                            SubField("minutes", 16, 21), SubField("hour", 22, 26),
                            SubField("day", 27, 31)))


def _global_pose(**change: object) -> MessageDef:
    """ReportGlobalPose written by hand from AS6009, with one thing changed."""
    fields = {
        "latitude": Scaled(u32, -90, 90), "longitude": Scaled(u32, -180, 180),
        "altitude": Scaled(u32, -10000, 35000), "position_rms": Scaled(u32, 0, 100),
        "roll": Scaled(u16, -math.pi, math.pi), "pitch": Scaled(u16, -math.pi, math.pi),
        "yaw": Scaled(u16, -math.pi, math.pi), "attitude_rms": Scaled(u16, 0, math.pi),
        "time_stamp": TIME_STAMP,
    }
    order = list(change.pop("order", fields))
    mandatory = change.pop("mandatory", None)
    fields.update(change)
    return message(0x4402, "ReportGlobalPose",
                   *((f if name == mandatory else opt)(name, fields[name]) for name in order),
                   pv=u16, service_set="test")


@pytest.fixture(scope="module")
def jsidl() -> dict[int, list[JsidlMessage]]:
    return load_all(ROOTS)


def test_a_faithful_definition_matches(jsidl: dict[int, list[JsidlMessage]]) -> None:
    assert verify(_global_pose(), jsidl[0x4402]) == ([], jsidl[0x4402][0])


@pytest.mark.parametrize(("change", "expected"), [
    ({"latitude": Scaled(u32, -180, 180)},
     "latitude: expected scale [-90.0..90.0], actual [-180.0..180.0]"),
    ({"yaw": Scaled(u32, -math.pi, math.pi)},
     "yaw: expected u16[-3.14159..3.14159] (PV bit 6), actual u32[-3.14159..3.14159] (PV bit 6)"),
    ({"order": ["longitude", "latitude", "altitude", "position_rms", "roll", "pitch", "yaw",
                "attitude_rms", "time_stamp"]},
     "latitude: expected name 'latitude', actual 'longitude'"),
    ({"mandatory": "roll"},
     "roll: expected u16[-3.14159..3.14159] (PV bit 4), actual mandatory"),
    ({"time_stamp": BitField(u32, TIME_STAMP.subfields[:4])},
     "time_stamp: expected bit ranges [(0, 9), (10, 15), (16, 21), (22, 26), (27, 31)], "
     "actual [(0, 9), (10, 15), (16, 21), (22, 26)]"),
    ({"order": ["latitude", "longitude", "altitude", "position_rms", "roll", "pitch", "yaw",
                "attitude_rms"]},
     "time_stamp: expected bitfield u32"),
])
def test_a_wrong_definition_is_named_precisely(jsidl: dict[int, list[JsidlMessage]],
                                               change: dict[str, object], expected: str) -> None:
    problems, matched = verify(_global_pose(**change), jsidl[0x4402])
    assert matched is None
    assert problems[0].startswith(expected), problems


def test_list_count_widths_and_variant_tags_are_checked(
        jsidl: dict[int, list[JsidlMessage]]) -> None:
    node_id = Enum(u8, {0: "Reserved", 255: "All nodes in the subsystem"})
    component_id = Enum(u8, {0: "Reserved", 255: "All components in the subsystem"})
    node = record(f("node_id", node_id),
                  f("component_list", List(u8, record(f("component_id", component_id)))))
    good = message(0x2B03, "QueryServices", f("node_list", List(u8, node)), service_set="t")
    assert verify(good, jsidl[0x2B03])[0] == []
    wide = message(0x2B03, "QueryServices", f("node_list", List(u16, node)), service_set="t")
    assert verify(wide, jsidl[0x2B03])[0][0].startswith(
        "node_list: expected list (count u8) of 2 item(s), actual list (count u16)")
    inner = record(f("node_id", node_id),
                   f("component_list", List(u16, record(f("component_id", component_id)))))
    deep = message(0x2B03, "QueryServices", f("node_list", List(u8, inner)), service_set="t")
    assert verify(deep, jsidl[0x2B03])[0][0].startswith("node_list[].component_list: expected")
    plain = message(0x2B03, "QueryServices", f("node_list", List(u8, record(
        f("node_id", u8), f("component_list", List(u8, record(f("component_id", component_id))))
    ))), service_set="t")
    assert verify(plain, jsidl[0x2B03])[0][0].startswith(
        "node_list[].node_id: expected value names {0: 'Reserved', 255: 'All nodes in the "
        "subsystem'}, actual {}")
    alternatives = (Field("message_id_rec", record(f("message_code", u16))),
                    Field("event_type_rec", record(f("event_type", Enum(
                        u8, {0: "Periodic (SC)", 1: "Every change"})))),
                    Field("event_id_rec", record(f("event_id", u8))),
                    Field("all_events_rec", record(f("all_events", u8))))
    query = message(0x21F0, "QueryEvents", f("query_events_var", Variant(u8, alternatives)),
                    service_set="t")
    assert verify(query, jsidl[0x21F0])[0] == []
    shifted = message(0x21F0, "QueryEvents", f("query_events_var", Variant(
        u8, alternatives, tag_values=(1, 2, 3, 4))), service_set="t")
    assert verify(shifted, jsidl[0x21F0])[0][0].startswith(
        "query_events_var: expected alternatives with tags [0, 1, 2, 3], actual [1, 2, 3, 4]")
