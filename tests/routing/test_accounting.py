"""The relay's accounting as data: which counts are losses, the flat names logged, the
queue-drop reasons named by traffic class, and the rate-limited log."""

from __future__ import annotations

import logging

import pytest

from edge_vis.routing.accounting import (
    Kind,
    LogLimiter,
    Tally,
    is_loss,
    losses,
    refused,
    tallies_of,
    totals,
)
from edge_vis.routing.traffic import QueueDrop


@pytest.mark.parametrize(
    ("tally", "label", "loss"),
    [
        (Tally(Kind.RELAY, "publish errors"), "publish errors", True),
        (Tally(Kind.RELAY, "send errors"), "send errors", True),
        (Tally(Kind.RELAY, "encode errors"), "encode errors", True),
        (Tally(Kind.RELAY, "delivery failed"), "delivery failed", True),
        (Tally(Kind.RELAY, "samples in"), "samples in", False),
        (Tally(Kind.ENGINE, "events missed"), "events missed", False),
        (Tally(Kind.LINK_TRAFFIC, "messages in", "radio"), "link radio messages in", False),
        (Tally(Kind.LINK_DROP, "queue full (telemetry)", "radio"),
         "link radio dropped: queue full (telemetry)", True),
        (Tally(Kind.LINK_DROP, "malformed: bad CRC", "radio"),
         "link radio dropped: malformed: bad CRC", False),
        (Tally(Kind.PUBLISHED, "samples", "GlobalPose"), "published GlobalPose", False),
        (Tally(Kind.TRANSLATOR_ERROR, "errors", "ugv"), "translator ugv errors", True),
        # input a translator cannot use, dropped on purpose with its reason: refused
        (Tally(Kind.TRANSLATOR_DROP, "range compression bzip2: undecodable", "environment"),
         "translator environment dropped: range compression bzip2: undecodable", False),
    ],
)
def test_each_kind_of_count_is_labelled_and_classed(tally: Tally, label: str,
                                                     loss: bool) -> None:
    assert tally.label() == label
    assert is_loss(tally) is loss


def test_losses_are_read_from_fields_not_names() -> None:
    # a link whose name looks like a loss counter, and a topic named like a drop
    tallies = {
        **tallies_of(Kind.LINK_TRAFFIC, {"messages in": 7}, "send errors"),
        Tally(Kind.PUBLISHED, "samples", "dropped: queue full"): 3,
        Tally(Kind.LINK_DROP, "malformed: short frame", "radio"): 4,
        Tally(Kind.LINK_DROP, "superseded (telemetry)", "radio"): 2,
        Tally(Kind.RELAY, "publish errors"): 0,
    }
    assert losses(tallies) == {"link radio dropped: superseded (telemetry)": 2}
    assert refused(tallies) == 4
    assert list(totals(tallies)) == sorted(totals(tallies))


@pytest.mark.parametrize(
    ("drop", "text", "named"),
    [
        (QueueDrop("queue full", 0), "queue full (priority 0)", "queue full (telemetry)"),
        (QueueDrop("superseded", 2), "superseded (priority 2)",
         "superseded (control/command)"),
        (QueueDrop("queue full", 3), "queue full (priority 3)", "queue full (priority 3)"),
        (QueueDrop("exceeds MTU"), "exceeds MTU", "exceeds MTU"),
    ],
)
def test_queue_drops_are_named_by_the_classes_of_their_priority(
        drop: QueueDrop, text: str, named: str) -> None:
    priorities = {"telemetry": 0, "control": 2, "command": 2}
    assert str(drop) == text
    assert drop.named(priorities) == named


def test_the_log_limiter_allows_a_burst_per_key_and_window(
        caplog: pytest.LogCaptureFixture) -> None:
    logger = logging.getLogger("test.accounting")
    limiter = LogLimiter(logger, burst=3, window=60.0)
    with caplog.at_level(logging.WARNING, "test.accounting"):
        logged = [limiter.warning("decode", t * 1.0, "bad %d", t) for t in range(10)]
        other = limiter.warning("send", 5.0, "send failed")
        again = limiter.warning("decode", 61.0, "bad again")
    assert logged == [True] * 3 + [False] * 7
    assert other and again
    messages = [r.getMessage() for r in caplog.records]
    assert messages == ["bad 0", "bad 1", "bad 2",
                        "decode: further messages of this kind suppressed for 60 s",
                        "send failed", "bad again"]
