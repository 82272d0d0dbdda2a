"""The rate planner as a pure function: tables of links, vehicles and expected rates."""

from __future__ import annotations

import math

import pytest

from edge_vis.bandwidth.linkspec import LinkSpec
from edge_vis.bandwidth.planner import FixedLoad, ReportDemand, format_plan, plan_link

RADIO_9600 = LinkSpec(bit_rate=9600, bits_per_byte=10, half_duplex=True, budget=0.8,
                      reserve=0.0)  # 768 B/s
FULL = LinkSpec(bit_rate=9600, bits_per_byte=10, half_duplex=False, budget=0.8, reserve=0.0)
UNKNOWN = LinkSpec(bit_rate=0)


def pose(vehicle: str, desired: float = 10.0, minimum: float = 2.0, priority: int = 7,
         size: int = 72, polled: bool = False, query: int = 0) -> ReportDemand:
    return ReportDemand(vehicle, "ReportGlobalPose", desired, minimum, priority, size,
                        query, polled)


def velocity(vehicle: str, desired: float = 10.0, minimum: float = 1.0, priority: int = 5
             ) -> ReportDemand:
    return ReportDemand(vehicle, "ReportVelocityState", desired, minimum, priority, 72)


CASES = [
    # (name, link, demands, {(vehicle, report): expected Hz (approx)})
    ("fits: everything at its desired rate", RADIO_9600,
     [pose("a", desired=2.0), velocity("a", desired=2.0)],
     {("a", "ReportGlobalPose"): 2.0, ("a", "ReportVelocityState"): 2.0}),
    ("lower priority degrades first, to its minimum", RADIO_9600,
     [pose("a", desired=8.0), velocity("a", desired=8.0)],
     # 768 B/s: velocity at 1 Hz (72 B/s) leaves 696 B/s for the pose: 9.67 -> 8 desired
     {("a", "ReportGlobalPose"): 8.0, ("a", "ReportVelocityState"): 2.67}),
    ("one common factor across vehicles of a priority", RADIO_9600,
     [pose("a"), pose("b"), velocity("a"), velocity("b")],
     # velocities at 1 Hz = 144 B/s; poses share 624 B/s: 4.33 Hz each
     {("a", "ReportGlobalPose"): 4.33, ("b", "ReportGlobalPose"): 4.33,
      ("a", "ReportVelocityState"): 1.0, ("b", "ReportVelocityState"): 1.0}),
    ("a polled report pays for its query on a half-duplex link", RADIO_9600,
     [pose("a", polled=True, size=72, query=36)],  # 108 B per report: 7.1 Hz
     {("a", "ReportGlobalPose"): 7.11}),
    ("full duplex: the queries ride the other direction", FULL,
     [pose("a", polled=True, size=72, query=36)],  # 72 B in per report: 10 Hz fits
     {("a", "ReportGlobalPose"): 10.0}),
    ("unknown rate: not planned", UNKNOWN,
     [pose("a", desired=50.0)], {("a", "ReportGlobalPose"): 50.0}),
]


@pytest.mark.parametrize(("name", "link", "demands", "expected"), CASES,
                         ids=[c[0] for c in CASES])
def test_planned_rates(name: str, link: LinkSpec, demands: list[ReportDemand],
                       expected: dict[tuple[str, str], float]) -> None:
    plan = plan_link("radio", link, demands)
    for key, rate in expected.items():
        assert plan.rate(*key) == pytest.approx(rate, abs=0.03), (key, format_plan(plan))
    if link.limited:
        assert plan.load <= link.budget_bytes + 1e-6
    assert plan.fits and not plan.warnings


def test_never_below_minimum_and_drops_by_priority_when_minimums_do_not_fit() -> None:
    # 8 vehicles x (pose 2 Hz + velocity 1 Hz) minimums = 1728 B/s > 768 B/s
    demands = [d for v in "abcdefgh" for d in (pose(v), velocity(v))]
    plan = plan_link("radio", RADIO_9600, demands)
    assert not plan.fits
    assert any("minimum rates need" in w for w in plan.warnings)
    assert plan.load <= RADIO_9600.budget_bytes
    by_report = {(p.demand.vehicle_id, p.demand.report): p for p in plan.reports}
    # every velocity (priority 5) goes before any pose (priority 7)
    dropped_poses = [p for p in plan.reports if p.dropped and p.demand.report ==
                     "ReportGlobalPose"]
    assert dropped_poses and all(by_report[(p.demand.vehicle_id, "ReportVelocityState")]
                                 .dropped for p in plan.reports)
    for p in plan.reports:  # what is kept is never below its minimum
        assert p.dropped or p.rate >= p.demand.minimum - 0.02
        assert p.dropped == ("DROPPED" in p.reason)
    assert "WARNING" in format_plan(plan)


def test_fixed_load_is_paid_first_and_a_too_heavy_one_is_reported() -> None:
    live = [FixedLoad("liveness", "a", 300.0, 300.0)]
    plan = plan_link("radio", RADIO_9600, [pose("a")], live)
    assert plan.rate("a", "ReportGlobalPose") == pytest.approx((768 - 600) / 72, abs=0.03)
    heavy = plan_link("radio", RADIO_9600, [pose("a")], [FixedLoad("liveness", "a", 800, 0)])
    assert any("liveness alone" in w for w in heavy.warnings)


def test_rates_are_what_createevent_can_carry_and_never_above_the_plan() -> None:
    plan = plan_link("radio", RADIO_9600, [pose(v) for v in "abc"])
    for p in plan.reports:
        steps = p.rate / (1092.0 / 65535)
        assert math.isclose(steps, round(steps), abs_tol=1e-6)
    assert plan.load <= RADIO_9600.budget_bytes


def test_every_change_events_are_counted_not_paced() -> None:
    change = ReportDemand("a", "ReportActiveElement", 1.0, 0.1, 5, 44, on_change=True)
    plan = plan_link("radio", RADIO_9600, [pose("a", desired=20.0), change])
    assert plan.rate("a", "ReportActiveElement") == 0.1  # counted at its minimum
    assert plan.rate("a", "ReportGlobalPose") == pytest.approx((768 - 4.4) / 72, abs=0.03)
