"""The rate planner: which report at which rate so a link's load fits its budget. Pure.

Input: one link (:class:`~edge_vis.bandwidth.linkspec.LinkSpec`), the reports every
vehicle behind it wants (:class:`ReportDemand`: desired and minimum rate, priority, bytes
on the link per delivery and, for a polled report, per query) and the traffic that is
not planned but always there (:class:`FixedLoad`: liveness queries and answers).

Rules, in order:

1. Everything at its desired rate if that fits the budget.
2. Otherwise degrade the lowest priority first: its reports share what is left by one
   common factor of their desired rates (equal relative degradation across vehicles),
   never below their minimum. Only when the lowest priority sits at its minimums is the
   next one degraded, and so on.
3. If even every minimum does not fit, reports are dropped (rate 0) from the lowest
   priority up, the costliest first, until the rest fits; the plan says so in
   ``warnings`` and the caller logs it loudly.

Every-change events (``on_change``) cannot be paced by a rate: they are counted at their
minimum rate (what the profile expects them to average; by default a tenth of the rate
the translator names) and never degraded. On a half-duplex link both directions
share the air time, so load is bytes in plus bytes out; on a full-duplex link it is the
busier direction.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from edge_vis.bandwidth.linkspec import LinkSpec

#: JAUS periodic rates are u16 scaled over 0..1092 Hz: about 0.0167 Hz resolution
RATE_STEP = 1092.0 / 65535


@dataclass(frozen=True, slots=True)
class ReportDemand:
    """One report one vehicle should deliver. Rates in Hz, sizes in bytes on the link.

    ``report_bytes`` is what one delivery costs (the Event carrying the report, or the
    report answering a query); ``query_bytes`` is what one query costs (polled only).
    ``priority``: higher is more important, degraded later.
    """

    vehicle_id: str
    report: str
    desired: float
    minimum: float
    priority: int
    report_bytes: int
    query_bytes: int = 0
    polled: bool = False
    on_change: bool = False

    def load(self, rate: float, half_duplex: bool) -> tuple[float, float]:
        """(bytes/s in, bytes/s out) at ``rate``."""
        inbound = self.report_bytes * rate
        outbound = self.query_bytes * rate if self.polled else 0.0
        return inbound, outbound


@dataclass(frozen=True, slots=True)
class FixedLoad:
    """Traffic the planner does not control (liveness), in bytes per second."""

    label: str
    vehicle_id: str
    inbound: float
    outbound: float


@dataclass(frozen=True, slots=True)
class PlannedReport:
    """The planned rate (0 = dropped) of a demand and why."""

    demand: ReportDemand
    rate: float
    reason: str

    @property
    def period(self) -> float:
        """Seconds between deliveries (inf when dropped)."""
        return 1.0 / self.rate if self.rate > 0 else math.inf

    @property
    def dropped(self) -> bool:
        return self.rate <= 0


@dataclass(frozen=True, slots=True)
class LinkPlan:
    """The plan of one link: rates, planned load (bytes/s) against the budget."""

    link: str
    spec: LinkSpec
    reports: tuple[PlannedReport, ...]
    fixed: tuple[FixedLoad, ...] = ()
    load: float = 0.0
    desired_load: float = 0.0
    warnings: tuple[str, ...] = ()
    rates: Mapping[tuple[str, str], float] = field(default_factory=dict)

    @property
    def budget(self) -> float:
        """Bytes per second the plan may fill (budget less the command reserve)."""
        return self.spec.planned_bytes

    @property
    def fits(self) -> bool:
        """True when nothing had to be dropped."""
        return not any(p.dropped for p in self.reports)

    def rate(self, vehicle_id: str, report: str) -> float | None:
        """Planned rate of ``report`` from ``vehicle_id`` (None: not planned here)."""
        return self.rates.get((vehicle_id, report))


def _total(demands: Sequence[ReportDemand], rates: Sequence[float],
           fixed: Iterable[FixedLoad], half_duplex: bool) -> float:
    inbound = sum(f.inbound for f in fixed)
    outbound = sum(f.outbound for f in fixed)
    for demand, rate in zip(demands, rates, strict=True):
        i, o = demand.load(rate, half_duplex)
        inbound += i
        outbound += o
    return inbound + outbound if half_duplex else max(inbound, outbound)


def _quantize(rate: float) -> float:
    """Round down to what a JAUS CreateEvent can carry (never above the plan)."""
    if rate <= 0:
        return 0.0
    return max(RATE_STEP, math.floor(rate / RATE_STEP) * RATE_STEP)


def plan_link(name: str, spec: LinkSpec, demands: Sequence[ReportDemand],
              fixed: Sequence[FixedLoad] = ()) -> LinkPlan:
    """Plan the rates of ``demands`` on link ``name`` (see the module docstring)."""
    demands = list(demands)
    half = spec.half_duplex
    rates = [d.minimum if d.on_change else d.desired for d in demands]
    desired_load = _total(demands, rates, fixed, half)
    reasons = ["desired rate fits the budget"] * len(demands)
    warnings: list[str] = []
    if not spec.limited:
        reasons = ["link rate unknown: not planned"] * len(demands)
        return _finish(name, spec, demands, rates, reasons, fixed, desired_load, warnings)
    budget = spec.planned_bytes
    fixed_load = _total([], [], fixed, half)
    if fixed_load > budget:
        warnings.append(f"link {name}: liveness alone needs {fixed_load:.0f} B/s, more than "
                        f"the budget of {budget:.0f} B/s")
    if desired_load <= budget:
        return _finish(name, spec, demands, rates, reasons, fixed, desired_load, warnings)

    levels = sorted({d.priority for d in demands if not d.on_change})
    for i, d in enumerate(demands):
        if d.on_change:
            reasons[i] = "every-change event: counted at its minimum rate, not paced"
    placed = False
    for level in levels:
        members = [i for i, d in enumerate(demands) if d.priority == level and not d.on_change]
        for i in members:
            rates[i] = min(demands[i].minimum, demands[i].desired)
        if _total(demands, rates, fixed, half) > budget:
            for i in members:
                reasons[i] = (f"at its minimum: priority {level} is degraded before "
                              "higher ones")
            continue
        lo, hi = 0.0, 1.0
        for _ in range(60):
            mid = (lo + hi) / 2
            trial = list(rates)
            for i in members:
                trial[i] = max(min(demands[i].minimum, demands[i].desired),
                               mid * demands[i].desired)
            if _total(demands, trial, fixed, half) <= budget:
                lo = mid
            else:
                hi = mid
        for i in members:
            rates[i] = max(min(demands[i].minimum, demands[i].desired), lo * demands[i].desired)
            if rates[i] <= demands[i].minimum + 1e-9:
                reasons[i] = f"at its minimum: priority {level} degraded to fit the budget"
            else:
                reasons[i] = (f"degraded to {lo:.0%} of desired: priority {level} shares "
                              "what higher priorities leave")
        placed = True
        break
    if not placed:
        warnings.append(
            f"link {name}: even the minimum rates need "
            f"{_total(demands, rates, fixed, half):.0f} B/s, more than the budget of "
            f"{budget:.0f} B/s ({spec.bit_rate:.0f} bit/s x {spec.budget:.0%} less the "
            f"{spec.reserve:.0%} command reserve); dropping "
            "reports by priority")
        order = sorted((i for i, d in enumerate(demands) if not d.on_change),
                       key=lambda i: (demands[i].priority,
                                      -sum(demands[i].load(rates[i], half))))
        for i in order:
            if _total(demands, rates, fixed, half) <= budget:
                break
            rates[i] = 0.0
            reasons[i] = (f"DROPPED: minimum rates do not fit the budget (priority "
                          f"{demands[i].priority})")
            warnings.append(f"link {name}: {demands[i].vehicle_id} {demands[i].report} dropped")
    return _finish(name, spec, demands, rates, reasons, fixed, desired_load, warnings)


def _finish(name: str, spec: LinkSpec, demands: list[ReportDemand], rates: list[float],
            reasons: list[str], fixed: Sequence[FixedLoad], desired_load: float,
            warnings: list[str]) -> LinkPlan:
    final = [r if d.on_change or not spec.limited else _quantize(r)
             for d, r in zip(demands, rates, strict=True)]
    reports = tuple(PlannedReport(d, r, why) for d, r, why in zip(demands, final, reasons,
                                                                   strict=True))
    load = _total(demands, final, fixed, spec.half_duplex)
    return LinkPlan(name, spec, reports, tuple(fixed), load, desired_load, tuple(warnings),
                    {(d.vehicle_id, d.report): r for d, r in zip(demands, final, strict=True)})


def format_plan(plan: LinkPlan) -> str:
    """The plan as a table for people: what, at which rate, on which link and why."""
    spec = plan.spec
    lines = []
    if spec.limited:
        mtu_time = spec.serialization_time(spec.mtu)
        lines.append(
            f"link {plan.link}: {spec.bit_rate:.0f} bit/s "
            f"{'half' if spec.half_duplex else 'full'} duplex, budget {spec.budget:.0%} = "
            f"{spec.budget_bytes:.0f} B/s of {spec.capacity_bytes:.0f}, {spec.reserve:.0%} "
            f"kept for commands: {plan.budget:.0f} B/s to plan; planned {plan.load:.0f} B/s "
            f"({plan.load / plan.budget:.0%} of budget), desired {plan.desired_load:.0f} B/s; "
            f"MTU {spec.mtu} B = {mtu_time * 1000:.0f} ms on air")
    else:
        lines.append(f"link {plan.link}: rate unknown, not planned")
    for f in plan.fixed:
        lines.append(f"  {f.vehicle_id:<16} {f.label:<24} fixed {f.inbound + f.outbound:7.0f}"
                     " B/s")
    if plan.reports:
        lines.append(f"  {'vehicle':<16} {'report':<24} {'mode':<6} {'desired':>8} "
                     f"{'minimum':>8} {'planned':>8} {'prio':>4} {'B/msg':>6} {'B/s':>7}  why")
    for p in plan.reports:
        d = p.demand
        cost = sum(d.load(p.rate, spec.half_duplex))
        mode = "change" if d.on_change else "poll" if d.polled else "event"
        per = d.report_bytes + (d.query_bytes if d.polled else 0)
        lines.append(f"  {d.vehicle_id:<16} {d.report:<24} {mode:<6} {d.desired:7.2f}Hz "
                     f"{d.minimum:6.2f}Hz {p.rate:6.2f}Hz {d.priority:>4} {per:>6} "
                     f"{cost:7.0f}  {p.reason}")
    for warning in plan.warnings:
        lines.append(f"  WARNING: {warning}")
    return "\n".join(lines)
