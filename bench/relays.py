"""Three relays, thirty vehicles with overlap: one server each, take-over times, footprint.

    .venv/bin/python bench/relays.py                      # 3 rounds of kills (~2 min)
    .venv/bin/python bench/relays.py --rounds 6 --vehicles 30 --relays 3

Everything is real and on loopback: ``--vehicles`` simulated UGVs in one ``edge-vis sim``
process (JUDP, 127.46.B.10+), ``--relays`` ``edge-vis run`` processes on one Cyclone
domain, no profile naming any other relay. The vehicles are split into as many groups
as there are relays; relay *i* reaches groups *i* and *i+1*, so every vehicle is within
reach of two relays and every relay of two thirds of the fleet. This process is the
operators' side: a plain reader (Cyclone defaults but the partition) of GlobalPose and a
reader of VehicleStatus.

Measured:

* **one server per vehicle**: in a steady window, the DDS writers a plain GlobalPose
  reader sees per vehicle (must be 1), and duplicates (a sample of the same vehicle and
  time stamp from two writers);
* **CPU and memory per relay** over the steady window (``/proc/PID/stat`` user+system,
  ``VmRSS``), serving and standing by;
* **take-over**: each round SIGKILLs the relay serving the most vehicles, and for each
  of its vehicles takes the time from the kill to the first GlobalPose from another
  writer; p50/p99 over all vehicles of all rounds. The killed relay is started again
  (it stands by: the vehicles stay with their new servers) and is back on the domain
  before the next round.
  Telemetry only: with an operator holding control, add the vehicle's control timeout
  (the fault matrix cell ``serving relay SIGKILL`` measures that).

Figures, not pass/fail.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections import defaultdict
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EDGE_VIS = str(Path(sys.executable).with_name("edge-vis"))
NET = f"127.46.{10 + os.getpid() % 200}"
TICK = os.sysconf("SC_CLK_TCK")

RELAY = """\
[relay]
jaus_id = "{jaus_id}"
authority = 150

[links.radio]
url = "udp://{ip}:3794?peers={peers}"

[dds]
domain = {domain}
partitions = ["{partition}"]

[translators]
enabled = ["core", "emergency", "mobility"]

[access]
any_operator = true

[discovery]
period = 1.0
liveness_period = 0.5
lost_after = 3

[report_rates]
ReportGlobalPose = 5.0
"""


def vehicle_ip(v: int) -> str:
    return f"{NET}.{10 + v}"


def sim_profile(vehicles: int) -> str:
    out = ["seed = 7\n"]
    for v in range(vehicles):
        out.append(f'[[vehicles]]\nname = "ugv-{v:02d}"\nkind = "ugv"\nsubsystem = {300 + v}\n'
                   f'link = "udp://{vehicle_ip(v)}:3794"\ncontrol_timeout = 5\n'
                   f"event_timeout = 1\nenvironment_period = 0.0\natr_period = 0.0\n")
    return "\n".join(out)


def reach(relay: int, relays: int, vehicles: int) -> list[int]:
    """The vehicles relay ``relay`` reaches: its group and the next."""
    groups = [list(range(vehicles))[g::relays] for g in range(relays)]
    return sorted(groups[relay] + groups[(relay + 1) % relays])


class Bench:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.dir = Path(tempfile.mkdtemp(prefix="edge-vis-relays-"))
        self.domain = args.domain
        self.partition = f"bench-relays-{uuid.uuid4().hex[:8]}"
        self.procs: dict[int, subprocess.Popen[bytes]] = {}
        self.sim: subprocess.Popen[bytes] | None = None
        #: vehicle -> [(arrival, writer handle, timestamp_ms)]
        self.poses: dict[str, list[tuple[float, int, int]]] = defaultdict(list)
        self.serving: dict[str, str] = {}

    # -- processes --------------------------------------------------------------------------
    def start_sim(self) -> None:
        path = self.dir / "fleet.toml"
        path.write_text(sim_profile(self.args.vehicles))
        with open(self.dir / "sim.log", "wb") as log:
            self.sim = subprocess.Popen([EDGE_VIS, "sim", "--profile", str(path)],
                                        stdout=log, stderr=subprocess.STDOUT)

    def start_relay(self, i: int) -> None:
        peers = ",".join(f"{vehicle_ip(v)}:3794"
                         for v in reach(i, self.args.relays, self.args.vehicles))
        path = self.dir / f"relay-{i}.toml"
        path.write_text(RELAY.format(jaus_id=f"{201 + i}.1.1", ip=f"{NET}.{1 + i}",
                                     peers=peers, domain=self.domain,
                                     partition=self.partition))
        with open(self.dir / f"relay-{i}.log", "ab") as log:
            self.procs[i] = subprocess.Popen([EDGE_VIS, "run", "--profile", str(path)],
                                             stdout=log, stderr=subprocess.STDOUT)

    def stop(self) -> None:
        for proc in [*self.procs.values(), self.sim]:
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in [*self.procs.values(), self.sim]:
            if proc is not None:
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()

    # -- the operators' side --------------------------------------------------------------------
    def open_readers(self) -> None:
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.qos import Policy, Qos
        from cyclonedds.sub import DataReader, Subscriber
        from cyclonedds.topic import Topic

        from edge_vis.dds import DdsBridge
        from edge_vis.dds.model import GlobalPose

        self.participant = DomainParticipant(self.domain)
        sub = Subscriber(self.participant, qos=Qos(Policy.Partition([self.partition])))
        self.plain = DataReader(sub, Topic(self.participant, "GlobalPose", GlobalPose))
        self.bridge = DdsBridge(self.domain, (self.partition,))
        self.status = self.bridge.reader("VehicleStatus")
        self.relay_status = self.bridge.reader("RelayStatus")

    def poll(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            now = time.monotonic()
            for s in self.plain.take(1024):
                if s.sample_info.valid_data:
                    self.poses[s.vehicle_id].append(
                        (now, int(s.sample_info.publication_handle), int(s.timestamp_ms)))
            for s in self.status.take(0.0, 1024):
                if s.get("relay"):
                    self.serving[s["vehicle_id"]] = s["relay"]
            time.sleep(0.01)

    # -- figures ---------------------------------------------------------------------------------
    def cpu_ticks(self) -> dict[int, int]:
        out = {}
        for i, proc in self.procs.items():
            fields = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
            out[i] = int(fields[11]) + int(fields[12])
        return out

    def rss_mib(self, i: int) -> float:
        for line in Path(f"/proc/{self.procs[i].pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
        return 0.0

    def steady(self, seconds: float) -> dict[str, Any]:
        start = time.monotonic()
        before = self.cpu_ticks()
        self.poll(seconds)
        after = self.cpu_ticks()
        elapsed = time.monotonic() - start
        writers = {v: {h for at, h, _ in p if at >= start} for v, p in self.poses.items()}
        dupes = 0
        for p in self.poses.values():
            seen: dict[int, int] = {}
            for at, handle, stamp in p:
                if at >= start and seen.setdefault(stamp, handle) != handle:
                    dupes += 1
        per_relay = defaultdict(int)
        for relay in self.serving.values():
            per_relay[relay] += 1
        return {
            "vehicles_seen": len(writers),
            "vehicles_with_one_writer": sum(1 for w in writers.values() if len(w) == 1),
            "vehicles_with_more_writers": sum(1 for w in writers.values() if len(w) > 1),
            "duplicate_samples": dupes,
            "serving": dict(sorted(per_relay.items())),
            "relays": {f"{201 + i}.1.1": {
                "cpu_percent": round(100 * (after[i] - before[i]) / TICK / elapsed, 1),
                "rss_mib": round(self.rss_mib(i), 1),
                "serves": per_relay.get(f"{201 + i}.1.1", 0)} for i in self.procs},
        }

    def kill_round(self) -> list[float]:
        per_relay: dict[str, list[str]] = defaultdict(list)
        for vehicle, relay in self.serving.items():
            per_relay[relay].append(vehicle)
        victim_name = max(per_relay, key=lambda r: len(per_relay[r]))
        victim = int(victim_name.split(".")[0]) - 201
        vehicles = per_relay[victim_name]
        old = {v: self.poses[v][-1][1] for v in vehicles if self.poses[v]}
        killed = time.monotonic()
        self.procs[victim].send_signal(signal.SIGKILL)
        self.procs[victim].wait()
        times: dict[str, float] = {}
        deadline = killed + 20
        while len(times) < len(old) and time.monotonic() < deadline:
            self.poll(0.05)
            for v, handle in old.items():
                if v not in times:
                    new = [at for at, h, _ in self.poses[v] if at > killed and h != handle]
                    if new:
                        times[v] = new[0] - killed
        missing = sorted(set(old) - set(times))
        took = sorted(times.values())
        print(f"  killed relay {victim_name} serving {len(vehicles)}: taken over "
              f"{len(times)}" + (f" in {took[0]:.2f}-{took[-1]:.2f} s" if took else "")
              + (f", NOT taken over: {missing}" if missing else ""), flush=True)
        self.start_relay(victim)
        self.wait_joined(victim_name)  # its start-up takes seconds on a loaded machine
        self.poll(self.args.rejoin)
        return list(times.values())

    def wait_joined(self, name: str, timeout: float = 60.0) -> None:
        """Until the restarted relay's first RelayStatus is on the domain."""
        self.relay_status.take(0.0, 1024)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.poll(0.1)
            if any(s["relay"] == name for s in self.relay_status.take(0.0, 1024)):
                return
        print(f"  relay {name} did not come back within {timeout:.0f} s", flush=True)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    k = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[k]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--relays", type=int, default=3)
    parser.add_argument("--vehicles", type=int, default=30)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--settle", type=float, default=15.0,
                        help="seconds from start until the fleet is measured")
    parser.add_argument("--window", type=float, default=10.0, help="steady window, s")
    parser.add_argument("--rejoin", type=float, default=4.0,
                        help="seconds after a restarted relay is back on the domain")
    parser.add_argument("--domain", type=int, default=200 + os.getpid() % 30)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if "CYCLONEDDS_URI" not in os.environ:
        sys.path.insert(0, str(ROOT))
        from edge_vis.dds import loopback_config

        os.environ["CYCLONEDDS_URI"] = loopback_config()
    bench = Bench(args)
    try:
        bench.start_sim()
        bench.open_readers()
        for i in range(args.relays):
            bench.start_relay(i)
        bench.poll(args.settle)
        steady = bench.steady(args.window)
        takeovers: list[float] = []
        for _ in range(args.rounds):
            takeovers += bench.kill_round()
        after = bench.steady(args.window)
    finally:
        bench.stop()
    # a relay declared gone that was not killed: its heartbeats came later than the lease
    gone = sum(log.read_text(errors="replace").count(" gone: not heard")
               for log in bench.dir.glob("relay-*.log"))
    result = {"relays": args.relays, "vehicles": args.vehicles, "steady": steady,
              "gone_declared": gone, "gone_expected": args.rounds * (args.relays - 1),
              "after_kills": after, "takeovers": len(takeovers),
              "takeover_p50_s": round(percentile(takeovers, 50), 2),
              "takeover_p99_s": round(percentile(takeovers, 99), 2),
              "takeover_max_s": round(max(takeovers, default=float("nan")), 2),
              "logs": str(bench.dir)}
    print(json.dumps(result, indent=None if args.json else 2))


if __name__ == "__main__":
    main()
