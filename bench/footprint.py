"""Footprint of a running relay: idle CPU, CPU with three simulated vehicles at 10 Hz,
resident memory, and start-up time. Starts processes, uses loopback sockets, reads /proc.

    .venv/bin/python bench/footprint.py                   # the installed edge-vis
    .venv/bin/python bench/footprint.py --bundle dist/edge-vis.pyz --seconds 20
    .venv/bin/python bench/footprint.py --no-dds          # JAUS side only

Phases, one relay process throughout:

1. start-up: from just before the relay process is started to the first
   QueryIdentification it sends, received by a UDP socket standing in for a peer;
2. idle: no vehicle answers; CPU seconds / wall seconds over ``--seconds`` (from
   ``/proc/PID/stat``, all threads);
3. three vehicles: ``edge-vis sim`` runs three UGVs on loopback; the relay discovers them
   and asks for their reports as events at 10 Hz. Once the samples flow, CPU is measured
   again over ``--seconds``. With DDS, a subscriber in this process counts GlobalPose
   samples per vehicle, to show the telemetry really is 10 Hz. The simulator's and this
   process's CPU are not counted.

Targets: idle < 1 % of a core, three vehicles < 10 %, start-up <= 1 s.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from edge_vis.catalogue import default_catalogue
from edge_vis.jaus.transport import unpack_datagram

RELAY_IP = "127.0.62.1"
LISTENER_IP = "127.0.62.9"
VEHICLE_IPS = ("127.0.62.11", "127.0.62.12", "127.0.62.13")
PORT = 3794
RATE = 10.0
#: reports the relay asks for at RATE (those a UGV simulator offers)
REPORTS = ("ReportGlobalPose", "ReportLocalPose", "ReportVelocityState")
CLK_TCK = os.sysconf("SC_CLK_TCK")


def relay_profile(domain: int, partition: str) -> str:
    peers = ",".join(f"{ip}:{PORT}" for ip in (LISTENER_IP, *VEHICLE_IPS))
    rates = "\n".join(f"{name} = {RATE}" for name in REPORTS)
    return f"""
[relay]
jaus_id = "200.1.1"
name = "footprint"

[links.lan]
url = "udp://{RELAY_IP}:{PORT}?peers={peers}&multicast=off"

[dds]
domain = {domain}
partitions = ["{partition}"]

[discovery]
period = 2.0

[report_rates]
{rates}
"""


def sim_profile() -> str:
    vehicles = []
    for i, ip in enumerate(VEHICLE_IPS):
        vehicles.append(f"""
[[vehicles]]
name = "ugv-{i + 1}"
kind = "ugv"
subsystem = {101 + i}
link = "udp://{ip}:{PORT}"
origin = {{ latitude = 36.60, longitude = -121.89 }}
""")
    return "seed = 1\n" + "".join(vehicles)


def cpu_seconds(pid: int) -> float:
    """utime + stime of every thread of ``pid``."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def memory(pid: int) -> dict[str, int]:
    """VmRSS and VmHWM in KiB."""
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = int(value.split()[0])
    return out


def cpu_share(pid: int, seconds: float, meanwhile: Callable[[], None] | None = None) -> float:
    """Fraction of one core used by ``pid`` over ``seconds`` of wall time.

    ``meanwhile`` is called every 50 ms (e.g. to drain a DDS reader whose history keeps
    only the latest sample).
    """
    c0, t0 = cpu_seconds(pid), time.monotonic()
    end = t0 + seconds
    while (left := end - time.monotonic()) > 0:
        time.sleep(min(left, 0.05) if meanwhile else left)
        if meanwhile is not None:
            meanwhile()
    return (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


def first_discovery(sock: socket.socket, timeout: float) -> float | None:
    """Wall-clock time of the first QueryIdentification received, or None."""
    catalogue = default_catalogue()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sock.settimeout(max(deadline - time.monotonic(), 0.01))
        try:
            data, _ = sock.recvfrom(65536)
        except TimeoutError:
            return None
        arrived = time.monotonic()
        for packet in unpack_datagram(data):
            if packet.message_code is not None and \
                    catalogue.decode(packet.payload).name == "QueryIdentification":
                return arrived
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="each measurement window")
    parser.add_argument("--no-dds", action="store_true", help="run the relay without DDS")
    parser.add_argument("--bundle", type=Path, help="measure this edge-vis.pyz instead")
    args = parser.parse_args(argv)

    dds = not args.no_dds
    if dds:
        try:
            from edge_vis.dds import DdsBridge, loopback_config
        except ImportError:
            print("cyclonedds is not installed: measuring without DDS", file=sys.stderr)
            dds = False
    domain, partition = 200 + os.getpid() % 30, f"footprint-{os.getpid()}"
    env = {k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC")}
    if dds:
        env["CYCLONEDDS_URI"] = os.environ["CYCLONEDDS_URI"] = loopback_config()

    with tempfile.TemporaryDirectory(prefix="edge-vis-footprint-") as tmp:
        profile, sim = Path(tmp, "relay.toml"), Path(tmp, "sim.toml")
        profile.write_text(relay_profile(domain, partition))
        sim.write_text(sim_profile())
        command = ([sys.executable, str(args.bundle)] if args.bundle
                   else [sys.executable, "-m", "edge_vis"])
        if args.bundle:  # unpack once, so start-up is what every later start costs
            subprocess.run([*command, "--version"], env=env, check=True,
                           stdout=subprocess.DEVNULL)
        listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        listener.bind((LISTENER_IP, PORT))
        relay_cmd = [*command, "--log-level", "WARNING", "run", "--profile", str(profile)]
        if not dds:
            relay_cmd.append("--no-dds")
        started = time.monotonic()
        relay = subprocess.Popen(relay_cmd, env=env, stderr=subprocess.PIPE)
        simulation: subprocess.Popen[bytes] | None = None
        reader_bridge = None
        try:
            seen = first_discovery(listener, 10.0)
            startup = seen - started if seen is not None else float("nan")
            time.sleep(1.0)  # let start-up work settle
            idle = cpu_share(relay.pid, args.seconds)
            idle_mem = memory(relay.pid)

            if dds:
                reader_bridge = DdsBridge(domain, (partition,))
                poses = reader_bridge.reader("GlobalPose")
            simulation = subprocess.Popen(
                [sys.executable, "-m", "edge_vis", "--log-level", "WARNING", "sim",
                 "--profile", str(sim)], env=env, stdout=subprocess.DEVNULL)
            time.sleep(8.0)  # discovery (2 s period), services, events
            per_vehicle: Counter[str] = Counter()

            def count() -> None:
                for sample in poses.take(max_samples=100000):
                    per_vehicle[sample["vehicle_id"]] += 1

            if dds:
                poses.take(max_samples=100000)
            busy = cpu_share(relay.pid, args.seconds, count if dds else None)
            busy_mem = memory(relay.pid)
            alive = relay.poll() is None
        finally:
            if simulation is not None:
                simulation.terminate()
                simulation.wait(10)
            relay.terminate()
            try:
                _, err = relay.communicate(timeout=15)
            except subprocess.TimeoutExpired:
                relay.kill()
                _, err = relay.communicate()
            if reader_bridge is not None:
                reader_bridge.close()
            listener.close()
    if not alive:
        print(err.decode(errors="replace")[-2000:], file=sys.stderr)
        return 1

    what = f"bundle {args.bundle}" if args.bundle else "python -m edge_vis"
    print(f"edge-vis footprint ({what}, DDS {'on' if dds else 'off'}, "
          f"{args.seconds:g} s windows, {os.cpu_count()} cores)")
    rows = [
        ("start-up to first discovery query", f"{startup:.2f} s", "<= 1 s",
         startup <= 1.0),
        ("CPU idle (no vehicles)", f"{idle * 100:.2f} % of a core", "< 1 %", idle < 0.01),
        ("CPU, 3 vehicles at 10 Hz", f"{busy * 100:.2f} % of a core", "< 10 %", busy < 0.10),
        ("resident memory idle", f"{idle_mem['VmRSS'] / 1024:.1f} MiB", "", True),
        ("resident memory, 3 vehicles", f"{busy_mem['VmRSS'] / 1024:.1f} MiB "
         f"(peak {busy_mem['VmHWM'] / 1024:.1f})", "", True),
    ]
    if dds:
        rates = ", ".join(f"{v} {n / args.seconds:.1f} Hz" for v, n in sorted(per_vehicle.items()))
        rows.append(("GlobalPose samples on DDS", rates or "none", f"{RATE:g} Hz each",
                     len(per_vehicle) == 3 and
                     all(n / args.seconds >= RATE * 0.8 for n in per_vehicle.values())))
    width = max(len(r[0]) for r in rows)
    vwidth = max(len(r[1]) for r in rows)
    for name, value, target, ok in rows:
        mark = "" if not target else ("ok" if ok else "MISSED")
        print(f"  {name:<{width}}  {value:<{vwidth}}  {target:<9} {mark}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
