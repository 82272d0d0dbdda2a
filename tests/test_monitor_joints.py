"""The monitor shows a manipulator's and a pan-tilt's joints by the names their
specifications give them (numbered where a vehicle names none, as manipulator v1.0 does)."""

from __future__ import annotations

from edge_vis.tools.monitor_view import READ_TOPICS, FleetView


def _positions(view: FleetView, vehicle: str, device: str, values: list[float],
               units: list[str], now: float = 0.0) -> None:
    view.ingest("JointState", {"vehicle_id": vehicle, "device": device,
                               "quantity": "position", "values": values, "units": units}, now)


def test_joints_are_labelled_with_their_specified_names() -> None:
    assert {"JointState", "JointSpecification"} <= set(READ_TOPICS)
    view = FleetView()
    view.ingest("JointSpecification", {"vehicle_id": "eod", "device": "manipulator",
                                       "names": ["turret", "shoulder", "slide"]}, 0.0)
    _positions(view, "eod", "manipulator", [0.4512, -0.1, 0.25], ["rad", "rad", "m"])
    _positions(view, "eod", "pan_tilt", [0.3, -1.0], ["rad", "rad"])
    # a velocity is not a position: the line keeps the positions
    view.ingest("JointState", {"vehicle_id": "eod", "device": "manipulator",
                               "quantity": "velocity", "values": [9.0, 9.0, 9.0]}, 0.1)
    lines = view.render(0.2)
    assert "   manipulator: turret 0.45 rad, shoulder -0.10 rad, slide 0.25 m" in lines
    assert "   pan-tilt: j1 0.30 rad, j2 -1.00 rad" in lines
    assert all(len(line) <= 80 for line in lines)


def test_unnamed_joints_are_numbered_and_later_names_apply() -> None:
    view = FleetView()
    view.ingest("JointSpecification", {"vehicle_id": "v1", "device": "manipulator",
                                       "names": ["", "", ""]}, 0.0)
    _positions(view, "v1", "manipulator", [0.0, 1.0, 0.1], ["rad", "rad", "m"])
    assert "   manipulator: j1 0.00 rad, j2 1.00 rad, j3 0.10 m" in view.render(0.0)
    view.ingest("JointSpecification", {"vehicle_id": "v1", "device": "manipulator",
                                       "names": ["base", "arm"]}, 1.0)
    assert "   manipulator: base 0.00 rad, arm 1.00 rad, j3 0.10 m" in view.render(1.0)
