"""Bandwidth plan and link scheduling on an emulated 19,200 bit/s shared serial radio.

Three simulated UGVs (``edge_vis.tools.sim``, real ptys) and one relay (the real runtime, serial
link on a real pty) share one half-duplex radio emulated by ``tests/bandwidth/radiohub.py``
(one FIFO of frames, 1,920 bytes/s). Every vehicle is asked for ReportGlobalPose and
ReportVelocityState at 10 Hz; an operator takes control and sends a WrenchEffortCommand
every 0.5 s. Runs:

* ``planned``   - link profile (budget 80 %): rates planned, traffic classes, pacing;
* ``fixed``     - the same without a link profile: fixed 10 Hz events, no scheduler
                  (what a plain node manager does);
* ``polled``    - planned, but the vehicles reject events so every report is polled.

DDS is replaced by an in-process capturing publisher (the samples the DDS bridge would
write, with the time they were handed to it). One run, prints a table::

    .venv/bin/python bench/bandwidth.py [--seconds 35] [--only planned] [--verbose]

``--verbose`` also prints each run's plan, backlog over time and air time by message.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "bandwidth"))

from radiohub import RadioHub

from edge_vis.catalogue import default_catalogue
from edge_vis.config import from_mapping
from edge_vis.shell.relay import Runtime
from edge_vis.tools.sim.profile import parse_profile
from edge_vis.tools.sim.runner import Simulation

BAUD = 19200
VEHICLES = 3
SET_WRENCH = 0x0405


class Capture:
    """Stands in for the DDS bridge: records (time, topic, sample)."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.samples: list[tuple[float, str, dict[str, Any]]] = []

    def publish(self, topic: str, sample: Any) -> None:
        self.samples.append((self.loop.time(), topic, dict(sample)))

    def close(self) -> None:
        pass


def relay_profile(path: str, planned: bool) -> Any:
    link: dict[str, Any] = {"url": f"serial://{path}?baud={BAUD}"}
    if planned:
        link.update(bit_rate=BAUD, bits_per_byte=10, half_duplex=True, budget=0.8, mtu=256,
                    overhead=18, latency=0.0)
    return from_mapping({
        "relay": {"jaus_id": "200.1.1", "authority": 200},
        "links": {"radio": link},
        "discovery": {"period": 10.0, "liveness_period": 1.0, "lost_after": 10,
                      "response_timeout": 6.0},
        "events": {"response_timeout": 6.0},
        "translators": {"enabled": ["mobility"]},
        "report_rates": {
            "ReportGlobalPose": {"desired": 10.0, "minimum": 2.0, "priority": 7},
            "ReportVelocityState": {"desired": 10.0, "minimum": 1.0, "priority": 5},
            "ReportLocalPose": {"desired": 1.0, "minimum": 0.2, "priority": 2},
        },
        "vehicles": [{"vehicle_id": f"ugv-{i + 1}", "subsystem": 101 + i, "link": "radio"}
                     for i in range(VEHICLES)],
    })


def sim_profile(reject_events: bool) -> Any:
    vehicles = []
    for i in range(VEHICLES):
        vehicle: dict[str, Any] = {
            "name": f"ugv-{i + 1}", "kind": "ugv", "subsystem": 101 + i, "link": "pty",
            "baud": 460800, "max_event_rate": 25.0, "event_timeout": 1,
            "origin": {"latitude": 36.6 + i * 0.001, "longitude": -121.89},
        }
        if reject_events:
            vehicle["faults"] = {"reject_events": True}
        vehicles.append(vehicle)
    return parse_profile({"seed": 7, "vehicles": vehicles})


def show_details(name: str, runtime: Runtime, hub: RadioHub, elapsed: float) -> None:
    """The plan, the backlog over time and the air time by message (to stderr)."""
    from edge_vis.bandwidth.planner import format_plan

    if runtime.planner is not None:
        print(format_plan(runtime.planner.plans["radio"]), file=sys.stderr)
    print(f"{name}: backlog every second:",
          [b for _t, b in hub.stats.backlog_samples][::4], file=sys.stderr)
    cat = default_catalogue()
    for (way, code, inner), n in hub.stats.by_code.most_common(16):
        label = cat.get(code).name if cat.get(code) else hex(code)
        wrapped = (cat.get(inner).name if cat.get(inner) else hex(inner)) if inner else ""
        print(f"   {way:<4} {label:<26} {wrapped:<22} {n / elapsed:7.0f} B/s", file=sys.stderr)


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


async def one_run(name: str, planned: bool, polled: bool, seconds: float,
                  verbose: bool = False) -> dict[str, Any]:
    loop = asyncio.get_running_loop()
    hub = RadioHub(BAUD, command_codes=frozenset({SET_WRENCH}))
    sim = Simulation(sim_profile(polled), default_catalogue())
    await sim.start()
    for endpoint in sim.endpoints:
        hub.add_vehicle(endpoint.slave_path)  # type: ignore[attr-defined]
    hub.start()
    profile = relay_profile(hub.relay_path, planned)
    capture = Capture(loop)
    runtime = Runtime(profile, publisher_factory=lambda _rt: capture)
    await runtime.start()
    start = loop.time()
    sent: dict[int, float] = {}
    marker = 0
    warmup = 12.0
    measure_from = start + warmup
    carried_at_start = 0
    try:
        while loop.time() - start < seconds:
            await asyncio.sleep(0.5)
            now = loop.time()
            if now < measure_from:
                for i in range(VEHICLES):
                    runtime._on_sample("ControlRequest", {
                        "vehicle_id": f"ugv-{i + 1}", "operator_id": "op", "action": 0,
                        "authority": 200})
                carried_at_start = hub.stats.carried
                measure_from = max(measure_from, now)
                continue
            marker = marker % 90 + 1
            for i in range(VEHICLES):
                runtime._on_sample("WrenchEffortCommand", {
                    "vehicle_id": f"ugv-{i + 1}", "operator_id": "op",
                    "propulsive_linear_x": float(marker)})
            sent[marker] = now
        end = loop.time()
        carried_at_end = hub.stats.carried
        if verbose:
            show_details(name, runtime, hub, loop.time() - start)
    finally:
        end = loop.time()
        carried_at_end = hub.stats.carried
        await runtime.stop()
        await hub.close()
        await sim.stop()
    window = end - measure_from
    stats = hub.stats
    capacity = BAUD / 10
    load = (carried_at_end - carried_at_start) / window / capacity
    # pose age on (the way to) DDS: publish time - when the vehicle sent that pose
    ages: list[float] = []
    by_sub: dict[int, list[tuple[float, float]]] = {}
    for sub, got, gen in stats.poses:
        by_sub.setdefault(sub, []).append((got, gen))
    for t, topic, sample in capture.samples:
        if topic != "GlobalPose" or t < measure_from:
            continue
        sub = 100 + int(str(sample.get("vehicle_id", "ugv-0")).split("-")[-1])
        delivered = [gen for got, gen in by_sub.get(sub, []) if got <= t]
        if delivered:
            ages.append(t - delivered[-1])
    poses = sum(1 for t, topic, _ in capture.samples if topic == "GlobalPose"
                and t >= measure_from)
    reports = sum(1 for t, topic, _ in capture.samples
                  if topic in ("GlobalPose", "Velocity", "LocalPose") and t >= measure_from)
    latencies = []
    catalogue = default_catalogue()
    for _code, payload, done, _queued in stats.commands:
        fields = catalogue.decode(payload).fields or {}
        at = sent.get(round(float(fields.get("propulsive_linear_effort_x", -1))))
        if at is not None and 0 <= done - at < 30:
            latencies.append(done - at)
    wanted = len(sent) * VEHICLES
    planned_period = None
    per_report = None
    if runtime.planner is not None and runtime.planner.plans:
        plan = runtime.planner.plans["radio"]
        poses_planned = [p for p in plan.reports if p.demand.report == "ReportGlobalPose"]
        rates = [p.rate for p in poses_planned]
        planned_period = 1.0 / min(rates) if rates and min(rates) > 0 else None
        if poses_planned:
            d = poses_planned[0].demand
            per_report = d.report_bytes + (d.query_bytes if d.polled else 0)
    growth = 0.0
    samples = [(t, b) for t, b in stats.backlog_samples if t >= measure_from]
    if len(samples) >= 2:
        growth = (samples[-1][1] - samples[0][1]) / (samples[-1][0] - samples[0][0])
    return {
        "run": name, "load": load, "poses": poses / window,
        "age_p50": percentile(ages, 0.5), "age_p95": percentile(ages, 0.95),
        "planned_period": planned_period,
        "cmd_sent": wanted, "cmd_delivered": len(stats.commands),
        "cmd_p99": percentile(latencies, 0.99), "backlog_max": stats.max_backlog,
        "growth": growth,
        "bytes_per_report": (carried_at_end - carried_at_start) / max(reports, 1),
        "reports": reports / window, "per_report": per_report,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=35.0)
    parser.add_argument("--only", choices=("planned", "fixed", "polled"), default=None)
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO if args.verbose else logging.ERROR)
    runs = [("planned", True, False), ("fixed", False, False), ("polled", True, True)]
    if args.only:
        runs = [r for r in runs if r[0] == args.only]
    results = [asyncio.run(one_run(n, p, q, args.seconds, args.verbose)) for n, p, q in runs]
    mtu_time = (256 + 14 + 18) / (BAUD / 10)
    print(f"emulated half-duplex serial radio {BAUD} bit/s ({BAUD // 10} B/s), {VEHICLES} "
          f"UGVs, pose + velocity wanted at 10 Hz, budget 80 %, {args.seconds:.0f} s per run "
          "(first 12 s warm-up)")
    head = (f"{'run':<8} {'load':>6} {'pose/s':>7} {'age p50':>8} {'age p95':>8} "
            f"{'2x plan':>8} {'cmds':>9} {'cmd p99':>8} {'backlog':>8} {'growth':>8} "
            f"{'B/report':>9} {'B/pose':>7}")
    print(head)
    print("-" * len(head))
    for r in results:
        limit = f"{2 * r['planned_period']:.2f}s" if r["planned_period"] else "-"
        print(f"{r['run']:<8} {r['load']:6.0%} {r['poses']:7.1f} {r['age_p50']:7.2f}s "
              f"{r['age_p95']:7.2f}s {limit:>8} {r['cmd_delivered']:>4}/{r['cmd_sent']:<4} "
              f"{r['cmd_p99']:7.3f}s {r['backlog_max']:>7}B {r['growth']:6.0f}B/s "
              f"{r['bytes_per_report']:9.0f} {r['per_report'] or '-':>7}")
    print(f"limits: load <= 80% +- 5%; pose age p95 <= 2x planned period; command p99 <= "
          f"one MTU on air ({mtu_time:.3f} s) + 0.100 s = {mtu_time + 0.1:.3f} s")
    print("load: air time used / capacity after warm-up; age: vehicle sent -> sample handed "
          "to DDS; backlog: most bytes waiting for air time; growth: its trend after warm-up;"
          "\nB/report: all bytes on the air per report delivered to DDS (liveness, control "
          "and commands included); B/pose: one pose on the air (Event, or query + report)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
