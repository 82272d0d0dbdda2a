"""Soak the relay: a simulated fleet through ``edge-vis run`` for N minutes, with faults.

Starts two child processes on loopback - ``edge-vis sim`` (20 UGVs over JUDP on
127.0.1.10-29 and 2 UGVs behind pseudo-terminal serial radios) and ``edge-vis run`` (the
relay on 127.0.1.1, one UDP link and two 57,600 baud serial links) - and an operator
station in this process on a DDS domain of its own (Cyclone on loopback only).

Faults run on a schedule: the sim's dropouts with reboot (every 90 s on a quarter of the
fleet, 5 s each), rejected events, malformed frames; the operator takes control of one
vehicle, drives it, lets the dead-man stop it, releases it and moves to the next.

Every ``--sample`` seconds the relay's resident memory, open file descriptors and threads
(``/proc/<pid>``) and, from DDS, each link's queue depth and message counts
(``LinkStatus``), the vehicles online (``VehicleStatus``) and the poses per vehicle
(``GlobalPose``) are printed. Exit status 1 when

* resident memory keeps growing: a least-squares slope over the samples after warm-up
  (the first 2 minutes, or the first third of a shorter run) above ``--max-growth``
  KiB per minute (default 256 KiB/min, i.e. 15 MiB/hour: a per-message leak at these
  rates shows up as several MiB per minute), or a slope over the second half of those
  samples above ``--max-late-growth`` (default 64 KiB/min: caches may still fill after
  warm-up, but a relay whose memory is still rising at the end would not last days);
  or file descriptors or threads grow;
* counts go missing: after warm-up, any vehicle without a pose for ``--pose-gap`` s
  (default 30 s: more than a dropout plus its rediscovery), or a link's message counter
  that stops increasing, or the relay exits;
* any message is lost. At the end the relay is stopped first and its ``totals:`` log line
  read: Events that never arrived from a vehicle (gaps in their sequence numbers), link
  queue drops and publish/send errors must all be 0 (refused malformed input is counted
  apart), and every ``GlobalPose`` the relay published must have reached the operator,
  whose reader keeps 64 samples per vehicle so that none overwrites another.

Usage::

    .venv/bin/python bench/soak.py --minutes 10
    .venv/bin/python bench/soak.py --minutes 25 --heap-stats heap.txt   # what grows, and where
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RELAY_IP = "127.0.1.1"
UDP_VEHICLES = 20
SERIAL_VEHICLES = 2
OPERATOR = "soak-op"


def sim_profile(workdir: Path) -> str:
    lines = ["seed = 11", ""]
    for i in range(UDP_VEHICLES):
        lines += [
            "[[vehicles]]", f'name = "ugv-{i:02d}"', 'kind = "ugv"', f"subsystem = {401 + i}",
            f'link = "udp://127.0.1.{10 + i}:3794"',
            f"origin = {{ latitude = {36.6 + i * 0.001:.4f}, longitude = -121.89 }}",
            "control_timeout = 5", "event_timeout = 1",
        ]
        faults = []
        if i % 4 == 1:
            faults.append(f"dropout = {{ first = {30 + 7 * i}.0, every = 90.0, "
                          f"duration = 5.0, reboot = true }}")
        if i % 5 == 2:
            faults.append("malformed_rate = 0.5")
        if i % 7 == 3:
            faults.append('reject_events = ["QueryVelocityState"]')
        if faults:
            lines += ["", "[vehicles.faults]", *faults]
        lines.append("")
    for j in range(SERIAL_VEHICLES):
        lines += [
            "[[vehicles]]", f'name = "ugv-serial-{j}"', 'kind = "ugv"', f"subsystem = {451 + j}",
            'link = "pty"', f'pty_path_file = "{workdir}/pty-{j}.path"', "baud = 57600",
            "origin = { latitude = 36.7, longitude = -121.9 }", "control_timeout = 5",
            "event_timeout = 1", "",
        ]
        if j == 1:
            lines += ["[vehicles.faults]", "malformed_rate = 0.5",
                      "dropout = { first = 75.0, every = 120.0, duration = 5.0, reboot = true }",
                      ""]
    return "\n".join(lines)


def relay_profile(domain: int, partition: str, ptys: list[str]) -> str:
    peers = ",".join(f"127.0.1.{10 + i}:3794" for i in range(UDP_VEHICLES))
    text = f"""
[relay]
jaus_id = "200.1.1"
authority = 150
name = "soak relay"

[links.lan]
url = "udp://{RELAY_IP}:3794?peers={peers}"

[dds]
domain = {domain}
partitions = ["{partition}"]

[[operators]]
id = "{OPERATOR}"
max_authority = 200

[limits]
max_products = 64          # image products kept for late joiners (the UGVs report stills)

[discovery]
period = 2.0
liveness_period = 1.0
lost_after = 3

[commands]
rate = 10.0
lifespan = 0.5
deadman_timeout = 1.0

[report_rates]
ReportGlobalPose = 2.0
ReportVelocityState = 1.0
ReportLocalPose = 1.0
"""
    for j, path in enumerate(ptys):
        text += f'\n[links.radio{j}]\nurl = "serial://{path}?baud=57600"\nbandwidth = 57600\n'
    return text


def proc_figures(pid: int) -> dict[str, int]:
    """Resident memory (KiB), threads and open descriptors of ``pid``."""
    out = {"rss_kib": 0, "threads": 0, "fds": 0}
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                out["rss_kib"] = int(line.split()[1])
            elif line.startswith("Threads:"):
                out["threads"] = int(line.split()[1])
    out["fds"] = len(os.listdir(f"/proc/{pid}/fd"))
    return out


def read_totals(log: Path, kind: str = "totals") -> dict[str, int]:
    """The last ``totals:`` (or ``losses:``) line the relay logged (a JSON object)."""
    found: dict[str, int] = {}
    for line in log.read_text(errors="replace").splitlines():
        if f" {kind}: " in line:
            found = json.loads(line.split(f" {kind}: ", 1)[1])
    return found


def lost_messages(totals: dict[str, int], lost: dict[str, int],
                  poses_received: int) -> list[tuple[str, int, str]]:
    """(where, how many lost, what was counted) from the relay's totals, its own account
    of what it lost (the ``losses:`` line), and the poses the operator received."""
    refused = sum(v for k, v in totals.items() if " dropped: " in k and k not in lost)
    published = totals.get("published GlobalPose", 0)
    return [
        ("vehicles -> relay (Event gaps)", totals.get("events missed", 0),
         f"{totals.get('events received', 0)} Events received"),
        ("in the relay (queues, errors)", sum(lost.values()),
         ", ".join(f"{k} {v}" for k, v in lost.items())
         or f"no queue drops; {refused} malformed inputs refused"),
        ("relay -> operator (GlobalPose)", max(0, published - poses_received),
         f"{published} published, {poses_received} received"),
    ]


def slope_per_minute(points: list[tuple[float, float]]) -> float:
    """Least-squares slope of ``(seconds, value)`` points, per minute."""
    n = len(points)
    if n < 3:
        return 0.0
    mx = sum(t for t, _ in points) / n
    my = sum(v for _, v in points) / n
    var = sum((t - mx) ** 2 for t, _ in points)
    if var == 0:
        return 0.0
    return sum((t - mx) * (v - my) for t, v in points) / var * 60.0


class Operator:
    """The DDS side: collects status and poses, and drives one vehicle at a time."""

    def __init__(self, domain: int, partition: str) -> None:
        from edge_vis.dds import DdsBridge

        self.bridge = DdsBridge(domain, (partition,))
        self.bridge.open_writers(["ControlRequest", "WrenchEffortCommand"])
        # deep enough that no pose overwrites another between two polls: every one is counted
        self.poses = self.bridge.reader("GlobalPose", depth=64)
        self.status = self.bridge.reader("VehicleStatus")
        self.links = self.bridge.reader("LinkStatus")
        self.control = self.bridge.reader("ControlStatus")
        self.pose_count: Counter[str] = Counter()
        self.last_pose: dict[str, float] = {}
        self.online: dict[str, bool] = {}
        self.link_last: dict[str, dict[str, Any]] = {}
        self.controlled: dict[str, str] = {}

    def poll(self) -> None:
        now = time.monotonic()
        for sample in self.poses.take(0.0, 4096):
            vid = sample["vehicle_id"]
            self.pose_count[vid] += 1
            self.last_pose[vid] = now
        for sample in self.status.take(0.0, 4096):
            self.online[sample["vehicle_id"]] = bool(sample["online"])
        for sample in self.links.take(0.0, 4096):
            self.link_last[sample["link"]] = sample
        for sample in self.control.take(0.0, 4096):
            self.controlled[sample["vehicle_id"]] = str(sample["state"])

    def request(self, vid: str, action: str) -> None:
        self.bridge.publish("ControlRequest", {"vehicle_id": vid, "operator_id": OPERATOR,
                                               "authority": 150, "action": action})

    def drive(self, vid: str, effort: float) -> None:
        self.bridge.publish("WrenchEffortCommand", {"vehicle_id": vid, "operator_id": OPERATOR,
                                                    "propulsive_linear_x": effort,
                                                    "propulsive_rotational_z": 5.0})

    def close(self) -> None:
        self.bridge.close()


def wait_for_files(paths: list[Path], timeout: float) -> list[str]:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if all(p.exists() and p.read_text().strip() for p in paths):
            return [p.read_text().strip() for p in paths]
        time.sleep(0.1)
    raise SystemExit(f"simulator did not create {', '.join(map(str, paths))}")


async def operate(op: Operator, stop_at: float) -> None:
    """Take control of one vehicle after another: drive 10 s, go silent (dead-man), release."""
    turn = 0
    while time.monotonic() < stop_at:
        candidates = sorted(v for v, up in op.online.items() if up)
        if not candidates:
            await asyncio.sleep(1.0)
            continue
        vid = candidates[turn % len(candidates)]
        turn += 1
        op.request(vid, "request")
        end = time.monotonic() + 10.0
        while time.monotonic() < min(end, stop_at):
            op.drive(vid, 30.0)
            await asyncio.sleep(0.2)
        await asyncio.sleep(3.0)  # silence: the relay's dead-man stops the vehicle
        op.request(vid, "release")
        await asyncio.sleep(2.0)


async def soak(args: argparse.Namespace) -> int:
    from edge_vis.dds import loopback_config

    env = dict(os.environ, CYCLONEDDS_URI=loopback_config(), PYTHONUNBUFFERED="1")
    os.environ["CYCLONEDDS_URI"] = env["CYCLONEDDS_URI"]
    domain = args.domain
    partition = f"soak-{os.getpid()}"
    exe = [sys.executable, "-m", "edge_vis"]
    workdir = Path(tempfile.mkdtemp(prefix="edge-vis-soak-"))
    (workdir / "fleet.toml").write_text(sim_profile(workdir))
    sim_log = open(workdir / "sim.log", "wb")  # noqa: SIM115 - closed in finally
    relay_log = open(workdir / "relay.log", "wb")  # noqa: SIM115
    sim = subprocess.Popen([*exe, "sim", "--profile", str(workdir / "fleet.toml")],
                           stdout=sim_log, stderr=subprocess.STDOUT, env=env)
    relay = None
    op = None
    failures: list[str] = []
    try:
        ptys = wait_for_files([workdir / f"pty-{j}.path" for j in range(SERIAL_VEHICLES)], 20)
        (workdir / "relay.toml").write_text(relay_profile(domain, partition, ptys))
        relay_env = env
        if args.heap_stats:  # bench/heapstats/sitecustomize.py samples inside the relay
            relay_env = dict(env, EDGE_VIS_HEAP_STATS=str(Path(args.heap_stats).resolve()),
                             PYTHONPATH=os.pathsep.join(filter(None, (
                                 str(ROOT / "bench" / "heapstats"), env.get("PYTHONPATH")))))
        relay = subprocess.Popen([*exe, "run", "--profile", str(workdir / "relay.toml")],
                                 stdout=relay_log, stderr=subprocess.STDOUT, env=relay_env)
        op = Operator(domain, partition)
        start = time.monotonic()
        stop_at = start + args.minutes * 60.0
        warmup = min(120.0, args.minutes * 60.0 / 3)
        driver = asyncio.create_task(operate(op, stop_at))
        rss_all: list[tuple[float, float]] = []
        fds: list[tuple[float, float]] = []
        threads: list[tuple[float, float]] = []
        worst_gap: dict[str, float] = defaultdict(float)
        stalled_links: Counter[str] = Counter()
        previous_messages: dict[str, int] = {}
        print(f"soak: {args.minutes} min, relay pid {relay.pid}, logs in {workdir}")
        print(f"{'t(s)':>6} {'rss MiB':>8} {'fds':>4} {'thr':>4} {'online':>6} "
              f"{'poses':>7} {'queue':>6} {'msgs in':>9} {'msgs out':>9}")
        next_sample = start + args.sample
        while time.monotonic() < stop_at:
            await asyncio.sleep(0.25)
            op.poll()
            if relay.poll() is not None:
                failures.append(f"relay exited with status {relay.returncode}")
                break
            now = time.monotonic()
            if now < next_sample:
                continue
            next_sample += args.sample
            t = now - start
            fig = proc_figures(relay.pid)
            links = op.link_last
            queue = sum(int(s["queue_depth"]) for s in links.values())
            msgs_in = sum(int(s["messages_in"]) for s in links.values())
            msgs_out = sum(int(s["messages_out"]) for s in links.values())
            online = sum(1 for up in op.online.values() if up)
            print(f"{t:6.0f} {fig['rss_kib'] / 1024:8.1f} {fig['fds']:4d} {fig['threads']:4d} "
                  f"{online:6d} {sum(op.pose_count.values()):7d} {queue:6d} {msgs_in:9d} "
                  f"{msgs_out:9d}", flush=True)
            rss_all.append((t, fig["rss_kib"]))
            if t >= warmup:
                fds.append((t, fig["fds"]))
                threads.append((t, fig["threads"]))
                for vid in op.pose_count:
                    worst_gap[vid] = max(worst_gap[vid], now - op.last_pose.get(vid, start))
                for name, sample in links.items():
                    count = int(sample["messages_in"])
                    if previous_messages.get(name) == count:
                        stalled_links[name] += 1
                    previous_messages[name] = count
        driver.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await driver
        # stop the relay first: its totals are then final, and every pose it published has
        # had time to arrive before the operator's count is compared with them
        if relay.poll() is None:
            relay.send_signal(signal.SIGINT)
            await asyncio.to_thread(relay.wait, 20)
        for _ in range(8):
            await asyncio.sleep(0.25)
            op.poll()
        relay_log.flush()
        totals = read_totals(workdir / "relay.log")
        expected = UDP_VEHICLES + SERIAL_VEHICLES
        seen = len(op.pose_count)
        rss = [(t, kib) for t, kib in rss_all if t >= warmup]
        growth = slope_per_minute(rss)
        late_growth = slope_per_minute(rss[len(rss) // 2:])
        fd_growth = (fds[-1][1] - fds[0][1]) if len(fds) > 1 else 0
        thread_growth = (threads[-1][1] - threads[0][1]) if len(threads) > 1 else 0
        print("\nsummary")
        print(f"  vehicles with poses      {seen} of {expected}")
        print(f"  poses received           {sum(op.pose_count.values())} "
              f"(min per vehicle {min(op.pose_count.values(), default=0)})")
        print(f"  worst pose gap after warm-up  {max(worst_gap.values(), default=0):.1f} s")
        print(f"  rss after warm-up        {rss[0][1] / 1024:.1f} -> {rss[-1][1] / 1024:.1f} MiB"
              if rss else "  rss: no samples after warm-up")
        print(f"  rss slope                {growth:+.1f} KiB/min (limit {args.max_growth:g}), "
              f"second half {late_growth:+.1f} KiB/min (limit {args.max_late_growth:g})")
        print("  rss each minute (MiB)    " + " ".join(
            f"{kib / 1024:.1f}" for t, kib in rss_all if int(t) % 60 < args.sample))
        print(f"  fds change {fd_growth:+.0f}, threads change {thread_growth:+.0f}")
        for name, sample in sorted(op.link_last.items()):
            drops = {d["traffic_class"]: d["count"] for d in sample.get("drops", [])}
            print(f"  link {name}: in {sample['messages_in']} out {sample['messages_out']} "
                  f"queue {sample['queue_depth']} drops {drops or 'none'}")
        lost = lost_messages(totals, read_totals(workdir / "relay.log", "losses"),
                             sum(op.pose_count.values()))
        print("  messages lost")
        for what, count, detail in lost:
            print(f"    {what:<36} {count:>6}   {detail}")
        for what, count, _ in lost:
            if count:
                failures.append(f"{count} messages lost {what}")
        if not totals:
            failures.append("the relay logged no totals when it stopped")
        if seen < expected:
            failures.append(f"only {seen} of {expected} vehicles published poses")
        for vid, gap in sorted(worst_gap.items()):
            if gap > args.pose_gap:
                failures.append(f"{vid}: no pose for {gap:.0f} s")
        if growth > args.max_growth:
            failures.append(f"memory grows {growth:.0f} KiB/min (limit {args.max_growth:g})")
        if late_growth > args.max_late_growth:
            failures.append(f"memory still grows {late_growth:.0f} KiB/min at the end "
                            f"(limit {args.max_late_growth:g})")
        if fd_growth > 2:
            failures.append(f"open file descriptors grew by {fd_growth:.0f}")
        if thread_growth > 2:
            failures.append(f"threads grew by {thread_growth:.0f}")
        for name, stalls in stalled_links.items():
            if stalls >= 3:
                failures.append(f"link {name}: messages_in stalled in {stalls} samples")
    finally:
        if op is not None:
            op.close()
        for proc in (relay, sim):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        sim_log.close()
        relay_log.close()
    for failure in failures:
        print(f"FAIL: {failure}")
    print("soak " + ("FAILED" if failures else "passed"))
    return 1 if failures else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--sample", type=float, default=5.0, help="seconds between samples")
    parser.add_argument("--domain", type=int, default=197, help="DDS domain id")
    parser.add_argument("--max-growth", type=float, default=256.0,
                        help="KiB per minute of resident-memory growth that fails the run")
    parser.add_argument("--max-late-growth", type=float, default=64.0,
                        help="the same over the second half of the samples after warm-up")
    parser.add_argument("--heap-stats", metavar="FILE",
                        help="write the relay's heap statistics to FILE every 30 s "
                             "(bench/heapstats: glibc's mallinfo2, pymalloc, mappings)")
    parser.add_argument("--pose-gap", type=float, default=30.0,
                        help="seconds without a vehicle's pose that fail the run")
    args = parser.parse_args()
    return asyncio.run(soak(args))


if __name__ == "__main__":
    sys.exit(main())
