"""``edge-vis mappings``: every row names a real JAUS message and a real DDS topic."""

from __future__ import annotations

import json

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.cli import main, mappings
from edge_vis.dds.topics import TopicRegistry
from edge_vis.engine.handled import ENGINE_HANDLED
from edge_vis.jaus.messages import BUILTIN_SETS


def test_every_row_is_a_known_message_and_topic(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mappings", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    rows = [row for row in table["rows"] if row["direction"] in ("jaus->dds", "dds->jaus")]
    catalogue = default_catalogue()
    topics = {spec.name for spec in TopicRegistry.standard()} | {"GenericReport"}
    assert len({row["message"] for row in rows}) >= 100
    for row in rows:
        catalogue.by_name(row["message"])  # KeyError names a message the catalogue lacks
        for topic in row["topic"].split(", "):
            if topic.startswith("("):  # an engine effect, e.g. "(vehicle declaration)"
                continue
            assert topic in topics, f"{row['message']}: unknown topic {topic!r}"


def test_count_matches_the_table(capsys: pytest.CaptureFixture[str]) -> None:
    main(["mappings", "--count"])
    count = int(capsys.readouterr().out)
    main(["mappings"])
    assert f"{count} JAUS messages translated" in capsys.readouterr().out


# -- counting and coverage ---------------------------------------------------------------------

#: message sets whose rows are still being written: each lists its unexplained messages
#: as an expected failure until it is complete (then strict xfail makes the test fail:
#: take the set out of this list)
PENDING: frozenset[str] = frozenset()
#: the list manager's messages (core set) are read back by the mobility and manipulator
#: translators
PENDING_SERVICES = ("urn:jaus:jss:core:ListManager",)


def _table() -> dict:  # type: ignore[type-arg]
    rows = mappings.collect()
    return {"counts": mappings.counts(rows, CATALOGUE), **mappings.coverage(rows, CATALOGUE)}


CATALOGUE = default_catalogue()
SETS = sorted({d.service_set for d in CATALOGUE if d.service_set in BUILTIN_SETS})


@pytest.mark.parametrize("message_set", [
    pytest.param(s, marks=pytest.mark.xfail(strict=True, reason=f"{s}: not yet complete"))
    if s in PENDING else s for s in SETS])
def test_every_catalogue_message_is_translated_handled_or_explained(message_set: str) -> None:
    untranslated = _table()["untranslated"]
    pending = {d.name for d in CATALOGUE if any(u.strip() in PENDING_SERVICES
                                                for u, _v in d.services)}
    missing = sorted({u["message"] for u in untranslated
                      if u["set"] == message_set and not u["reason"]} - pending)
    assert not missing, (f"{len(missing)} {message_set} messages have no mapping row, "
                         f"engine declaration or reason: {', '.join(missing)}")


def test_json_lists_every_untranslated_catalogue_message(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mappings", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    translated = {r["message"] for r in table["rows"]
                  if r["direction"] in ("jaus->dds", "dds->jaus")
                  and not r["message"].startswith("Query")}
    public = {d.name for d in CATALOGUE if d.service_set in BUILTIN_SETS}
    listed = {u["message"] for u in table["untranslated"]}
    assert listed == public - translated
    assert table["counts"]["translated_messages"] == len(translated)
    on_wire = table["counts"]["wire_messages"]
    assert on_wire >= table["counts"]["jaus_messages_total"]
    for entry in table["untranslated"]:  # the reason says which kind it is
        if entry["message"] in ENGINE_HANDLED:
            assert entry["reason"].startswith("engine: ")


def test_queries_triggered_from_dds_count_as_queries_not_translations() -> None:
    rows = [{"translator": "t", "direction": "dds->jaus", "message": "QueryStillImageData",
             "topic": "SensorCommand", "query": "", "doc": ""},
            {"translator": "t", "direction": "jaus->dds", "message": "ReportStillImageData",
             "topic": "ImageProduct", "query": "QueryStillImageData", "doc": ""}]
    counts = mappings.counts(rows, CATALOGUE)
    assert (counts["translated_messages"], counts["queries_sent"]) == (1, 1)
    assert counts["wire_messages"] == 2 + len(ENGINE_HANDLED)


def test_a_service_is_covered_by_one_translated_or_engine_message() -> None:
    services = mappings.public_services(CATALOGUE)
    assert all(not uri.endswith("Client") and uri == uri.strip() for uri in services)
    still = "urn:jaus:jss:environmentSensing:StillImage"
    assert "ReportStillImageData" in services[still]
    rows = [{"translator": "t", "direction": "jaus->dds", "message": "ReportStillImageData",
             "topic": "ImageProduct", "query": "QueryStillImageData", "doc": ""}]
    cover = mappings.coverage(rows, CATALOGUE)
    assert still not in cover["services_not_covered"]
    # a query alone covers nothing
    rows = [{"translator": "t", "direction": "dds->jaus", "message": "QueryStillImageData",
             "topic": "SensorCommand", "query": "", "doc": ""}]
    assert still in mappings.coverage(rows, CATALOGUE)["services_not_covered"]
    # the engine's own messages cover the core services it uses
    assert "urn:jaus:jss:core:AccessControl" not in cover["services_not_covered"]
    assert cover["public_services_covered"] + len(cover["services_not_covered"]) == \
        cover["public_services"] == len(services)


def test_markdown_states_the_wire_and_service_counts(capsys: pytest.CaptureFixture[str]) -> None:
    counts = _table()["counts"]
    main(["mappings"])
    out = capsys.readouterr().out
    assert f"On the wire: {counts['wire_messages']} JAUS messages" in out
    assert (f"{counts['public_services_covered']} of the {counts['public_services']} public "
            f"non-client service URIs") in out
