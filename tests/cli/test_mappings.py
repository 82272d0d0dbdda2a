"""``edge-vis mappings``: every row names a real JAUS message and a real DDS topic."""

from __future__ import annotations

import json

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.cli import main
from edge_vis.dds.topics import TopicRegistry


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
