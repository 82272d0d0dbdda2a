"""The fetch scheduling decisions, table-driven: queue order, backoff, retries."""

from __future__ import annotations

import pytest

from links.udt.fetch_queue import FetchQueue, Wanted

SRC = ("127.0.0.1", 9100)


def wanted(n: int, vehicle: str = "a", confidence: float = 0.5, capture: float = 0.0) -> Wanted:
    return Wanted(vehicle, f"atr-{n}", f"atr-{n}.png", f"{n:064x}", 1000, SRC, confidence,
                  capture)


@pytest.mark.parametrize(("priority", "images", "order"), [
    ("confidence", [(1, 0.2, 10.0), (2, 0.9, 30.0), (3, 0.9, 20.0)], [3, 2, 1]),
    ("oldest", [(1, 0.2, 10.0), (2, 0.9, 30.0), (3, 0.9, 20.0)], [1, 3, 2]),
    ("newest", [(1, 0.2, 10.0), (2, 0.9, 30.0), (3, 0.9, 20.0)], [2, 3, 1]),
])
def test_priority_orders_the_queue(priority, images, order):
    q = FetchQueue(priority=priority)
    for n, conf, capture in images:
        q.add(wanted(n, vehicle=f"v{n}", confidence=conf, capture=capture))
    taken = []
    while (w := q.take(0.0)) is not None:
        taken.append(int(w.image_id.split("-")[1]))
        q.finished(w, "verified", 0.0)
    assert taken == order


@pytest.mark.parametrize(("outcomes", "expected"), [
    # (outcome, progressed) in turn -> the verdicts' (action, delay from now)
    ([("lost", False), ("lost", False), ("lost", False)],
     [("retry", 0.5), ("retry", 1.0), ("retry", 2.0)]),
    ([("lost", False), ("lost", True), ("lost", False)],
     [("retry", 0.5), ("retry", 0.5), ("retry", 1.0)]),
    ([("mismatch", False)] * 3, [("retry", 0.25)] * 2 + [("given_up", 0.0)]),
    ([("not_found", False)] * 2, [("retry", 1.0), ("retry", 2.0)]),
    ([("lost", False)] * 8, [("retry", d) for d in (0.5, 1, 2, 4, 4, 4, 4, 4)]),
    ([("verified", False)], [("done", 0.0)]),
])
def test_retry_and_backoff(outcomes, expected):
    q = FetchQueue(initial=0.5, maximum=4.0, mismatch_delay=0.25, max_mismatches=3)
    q.add(wanted(1))
    now, got = 100.0, []
    for state, progressed in outcomes:
        w = q.take(now + 1000.0)
        assert w is not None
        now += 1000.0
        v = q.finished(w, state, now, "why", progressed)
        got.append((v.action, round(v.at - now, 3) if v.action == "retry" else 0.0))
    assert got == expected


def test_a_vehicle_out_of_reach_does_not_hold_up_the_others():
    q = FetchQueue(initial=1.0)
    q.add(wanted(1, vehicle="away", confidence=0.9))
    q.add(wanted(2, vehicle="away", confidence=0.8))
    q.add(wanted(3, vehicle="here", confidence=0.1))
    first = q.take(0.0)
    assert first is not None and first.vehicle_id == "away"
    assert q.take(0.0).vehicle_id == "here"  # one fetch per vehicle at a time
    q.finished(first, "lost", 0.0)
    assert q.take(0.5) is None  # "away" backs off; "here" is busy
    assert q.take(1.0).image_id == "atr-1"


def test_an_image_is_queued_once_and_dropped_when_pushed():
    q = FetchQueue()
    assert q.add(wanted(1)) and not q.add(wanted(1))
    q.discard(wanted(1).sha256)
    assert len(q) == 0 and q.take(0.0) is None
