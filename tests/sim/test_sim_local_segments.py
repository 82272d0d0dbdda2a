"""The simulated platform's Local Path Segment Driver (sans-I/O, fake clock): segments in
the local frame are loaded into the List Manager, driven to their end points, and the
active one is reported back."""

from __future__ import annotations

import math
from typing import Any

import pytest
from conftest import Wire


def segment(wire: Wire, uid: int, prev: int, nxt: int, x: float, y: float,
            **extra: Any) -> dict[str, Any]:
    fields = {"p1_x": 0.0, "p1_y": 0.0, "p2_x": x, "p2_y": y, "weighting_factor": 0.0,
              **extra}
    return {"element_uid": uid, "previous_uid": prev, "next_uid": nxt,
            "element_data": {"format": 0, "data": wire.payload("SetLocalPathSegment", fields)}}


def test_local_segments_are_driven_to_their_end_points(wire: Wire) -> None:
    wire.ready()
    ends = [(15.0, 0.0), (15.0, 15.0)]
    out = wire.query("SetElement", {"request_id_rec": {"request_id": 7}, "element_list": [
        segment(wire, 1, 0, 2, *ends[0], path_tolerance=1.0),
        segment(wire, 2, 1, 0, *ends[1], p1_x=15.0)]})
    assert (out.name, out.fields) == ("ConfirmElementRequest", {"request_id": 7})
    assert wire.query("QueryElementCount").fields == {"element_count": 2}
    wire.send("ExecuteList", {"speed": 2.0})
    reported: list[dict[str, Any]] = []
    active = []
    for _ in range(40):
        wire.take_control()
        wire.advance(1.0, step=0.1)
        active.append(wire.query("QueryActiveElement").fields["element_uid"])
        reported += [out.fields for out in wire.send("QueryLocalPathSegment",
                                                     {"presence_vector": 7})]
    assert active[0] == 1 and 2 in active and active[-1] == 0
    # while a segment is active the driver reports it, as it was set (local metres); once
    # the list is done it reports nothing
    assert len(reported) == sum(1 for uid in active if uid)
    assert [(round(r["p2_x"], 2), round(r["p2_y"], 2)) for r in reported] == \
        [ends[uid - 1] for uid in active if uid]
    assert reported[-1]["p1_x"] == pytest.approx(15.0, abs=0.01)
    pose = wire.query("QueryLocalPose", {"presence_vector": 3}).fields
    assert math.hypot(pose["x"] - 15.0, pose["y"] - 15.0) <= 1.0
    assert wire.vehicle.waypoints.reached == [1, 2]


def test_the_global_driver_reports_nothing_for_a_local_segment(wire: Wire) -> None:
    wire.ready()
    wire.query("SetElement", {"request_id_rec": {"request_id": 1}, "element_list": [
        segment(wire, 1, 0, 0, 50.0, 0.0)]})
    wire.send("ExecuteList", {"speed": 1.0})
    wire.advance(1.0, step=0.1)
    (local,) = wire.send("QueryLocalPathSegment", {"presence_vector": 7})
    assert local.fields["p2_x"] == pytest.approx(50.0, abs=0.01)
    assert wire.send("QueryGlobalPathSegment", {"presence_vector": 7}) == []
