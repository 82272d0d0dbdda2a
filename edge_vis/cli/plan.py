"""``edge-vis plan PROFILE``: print the bandwidth plan without running anything.

For every link with a link profile: which vehicle reports what at which rate, the bytes
each report costs on the link, the planned load against the budget and why each rate is
what it is. Vehicles come from the profile; ``--vehicles N`` assumes N vehicles like the
profile's (or N anonymous ones on the first planned link). A vehicle's reports are those
its static services offer, else the reports the profiles give rates for, else every
periodic report of the enabled translators. A link no vehicle is planned on gets a note
on stderr saying how to plan one. Exits 1 when a report had to be dropped.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from edge_vis.bandwidth.demands import SizeSource, VehicleWants, plan_fleet
from edge_vis.bandwidth.planner import format_plan
from edge_vis.catalogue import default_catalogue
from edge_vis.config import RelayProfile, VehicleProfile, load_profile
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import ConfigError
from edge_vis.kit.contract import ReportSpec

NAME = "plan"
HELP = "print the bandwidth plan of a deployment profile (rates per vehicle and link)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", help="deployment profile (TOML)")
    parser.add_argument("--vehicles", type=int, default=None, metavar="N",
                        help="assume N vehicles like the profile's")
    parser.add_argument("--polled", action="store_true",
                        help="plan as if every vehicle answered queries only (no events)")


def _reports(relay: RelayProfile, vehicle: VehicleProfile | None,
             wanted: list[ReportSpec]) -> list[ReportSpec]:
    if vehicle is not None and vehicle.is_static:
        offered = {s.uri for c in vehicle.components for s in c.services}
        return [w for w in wanted if w.service in offered]
    named = set(relay.report_rates) | set(vehicle.report_rates if vehicle else ())
    if named:
        return [w for w in wanted if w.report in named]
    return [w for w in wanted if not w.on_change]


def _vehicles(relay: RelayProfile, planned: list[str], count: int | None
              ) -> list[tuple[VehicleProfile | None, str, str]]:
    """(profile, vehicle id, link) of every vehicle to plan."""
    base = []
    for vp in relay.vehicles:
        link = vp.link or (planned[0] if len(relay.links) == 1 and planned else "")
        if link in planned:
            base.append((vp, vp.vehicle_id, link))
    if count is None:
        return base
    if not base:
        if not planned:
            return []
        return [(None, f"vehicle-{i + 1}", planned[0]) for i in range(count)]
    out = []
    for i in range(count):
        vp, vid, link = base[i % len(base)]
        rounds = i // len(base)
        out.append((vp, vid if rounds == 0 else f"{vid}-{rounds + 1}", link))
    return out


def run(args: argparse.Namespace) -> int:
    try:
        relay = load_profile(args.profile)
        manager = TranslationManager.from_selection(relay.translators)
    except ConfigError as exc:
        print(f"{args.profile}: {len(exc.problems)} problem(s)", file=sys.stderr)
        for file, key, message in exc.problems:
            where = ": ".join(part for part in (file or args.profile, key) if part)
            print(f"  {where}: {message}", file=sys.stderr)
        return 2
    specs = {lp.name: lp.spec for lp in relay.links if lp.spec is not None}
    if not specs:
        print(f"{args.profile}: no link has a link profile (profile = \"serial-9600\" or "
              "bit_rate = ...): nothing to plan")
        return 0
    wanted = list({spec.report: spec for _tr, spec in manager.wanted_reports()}.values())
    wants = []
    for vp, vehicle_id, link in _vehicles(relay, list(specs), args.vehicles):
        reports = _reports(relay, vp, wanted)
        if vp is not None and vehicle_id != vp.vehicle_id:
            vp = replace(vp, vehicle_id=vehicle_id)
        wants.append(VehicleWants(vehicle_id, link,
                                  vp, tuple((r, bool(args.polled)) for r in reports)))
    plans = plan_fleet(relay, specs, wants, SizeSource(default_catalogue()))
    dropped = False
    for plan in plans.values():
        print(format_plan(plan))
        print()
        dropped |= not plan.fits
    unplanned = [v.vehicle_id for v in relay.vehicles
                 if v.vehicle_id not in {w.vehicle_id for w in wants}]
    if unplanned:
        print(f"not planned (no link profile on their link): {', '.join(unplanned)}")
    empty = [link for link in specs if not any(w.link == link for w in wants)]
    if empty:
        sys.stdout.flush()
        print(_empty_note(args, relay, empty), file=sys.stderr)
    return 1 if dropped else 0


def _empty_note(args: argparse.Namespace, relay: RelayProfile, links: list[str]) -> str:
    """Why a link's plan is empty, and how to get one."""
    which = ", ".join(links)
    if args.vehicles is not None or relay.vehicles:
        return (f"note: no vehicle on link {which}: vehicles found at run time are planned "
                f"then; put one on it with [[vehicles]] link = \"{links[0]}\" in the profile")
    return (f"note: nothing planned on link {which}: the profile lists no vehicles "
            f"([[vehicles]]); plan for some with: edge-vis plan {args.profile} --vehicles N")
