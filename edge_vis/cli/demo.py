"""``edge-vis demo``: the simulated fleet, the relay and the monitor in one command.

Starts three child processes on loopback - ``edge-vis sim`` with the fleet profile, the
relay (``edge-vis run``) and ``edge-vis monitor`` - with Cyclone DDS kept on 127.0.0.1.
Interactively the monitor owns the terminal; quitting it (``q``) or Ctrl-C stops
everything. With ``--duration N`` nothing needs a person: the demo itself joins DDS as an
operator, takes control of a ground vehicle, drives it, sends it a waypoint plan, and
after N seconds prints what DDS showed - vehicles seen, samples per topic, commands
whose effect was observed, vehicles that dropped out and came back. Child logs go to
``--log-dir``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from edge_vis.errors import ConfigError
from edge_vis.tools.monitor_view import (
    READ_TOPICS,
    WRITE_TOPICS,
    FleetView,
    control_request,
    waypoint_plan,
    wrench_command,
)
from edge_vis.tools.sim.profile import SimProfile, load_profile

NAME = "demo"
HELP = "run the simulated fleet, the relay and the monitor together on this computer"

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_FLEET = ROOT / "profiles" / "sim" / "fleet.toml"
DEFAULT_RELAY_PROFILE = ROOT / "profiles" / "demo.toml"
#: where the relay binds its UDP link when the demo derives links from the fleet
RELAY_BIND = "127.0.0.10:3794"
DRIVER = "urn:jaus:jss:mobility:PrimitiveDriver"
PLANNER = "urn:jaus:jss:mobility:GlobalWaypointListDriver"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, metavar="S",
                        help="run unattended for S seconds, then print a summary")
    parser.add_argument("--domain", type=int, default=0, help="DDS domain id (default 0)")
    parser.add_argument("--fleet", type=Path, default=DEFAULT_FLEET, metavar="FILE",
                        help="simulation profile (default profiles/sim/fleet.toml)")
    parser.add_argument("--relay-profile", type=Path, metavar="FILE",
                        help="relay profile (default: profiles/demo.toml with the shipped "
                             "fleet when it exists, else links derived from the fleet)")
    parser.add_argument("--relay-address", default=RELAY_BIND, metavar="IP:PORT",
                        help=f"the relay's UDP address when links come from the fleet "
                             f"(default {RELAY_BIND})")
    parser.add_argument("--operator", default="demo-operator", metavar="ID",
                        help="operator id for commands")
    parser.add_argument("--authority", type=int, default=150, metavar="N",
                        help="authority for control requests (default 150)")
    parser.add_argument("--log-dir", type=Path, metavar="DIR",
                        help="where the children's logs go (default: a new temporary folder)")
    parser.add_argument("--json", action="store_true",
                        help="print the --duration summary as JSON")


def relay_links(fleet: SimProfile, bind: str = RELAY_BIND) -> list[str]:
    """Link URLs that reach every vehicle of ``fleet`` from a relay bound to ``bind``."""
    peers = [v.udp_address for v in fleet.vehicles if not v.is_pty]
    links = []
    if peers:
        text = ",".join(f"{host}:{port}" for host, port in peers)
        links.append(f"udp://{bind}?peers={text}")
    for v in fleet.vehicles:
        if v.is_pty:
            if not v.pty_link:
                raise ConfigError([(str(fleet.source), f"vehicles ({v.name}).pty_link",
                                    "the demo needs a fixed pty_link to hand to the relay")])
            links.append(f"serial://{v.pty_link}?baud={v.baud}")
    return links


class Children:
    """The child processes, stopped in reverse order with SIGINT, then harder."""

    def __init__(self, log_dir: Path, env: dict[str, str]) -> None:
        self.log_dir = log_dir
        self.env = env
        self.procs: list[tuple[str, subprocess.Popen[str]]] = []
        self._logs: list[IO[str]] = []

    def start(self, name: str, argv: list[str], *, stdout_pipe: bool = False,
              foreground: bool = False) -> subprocess.Popen[str]:
        log = open(self.log_dir / f"{name}.log", "w", encoding="utf-8")  # noqa: SIM115
        self._logs.append(log)
        cmd = [sys.executable, "-m", "edge_vis", *argv]
        if foreground:
            proc = subprocess.Popen(cmd, env=self.env, stderr=log, text=True)
        else:
            proc = subprocess.Popen(cmd, env=self.env, text=True, stderr=log,
                                    stdout=subprocess.PIPE if stdout_pipe else log,
                                    stdin=subprocess.DEVNULL, start_new_session=True)
        self.procs.append((name, proc))
        return proc

    def check(self) -> str | None:
        """The name of a child that exited, if any."""
        for name, proc in self.procs:
            if proc.poll() is not None:
                return name
        return None

    def stop(self) -> dict[str, int | None]:
        codes: dict[str, int | None] = {}
        for name, proc in reversed(self.procs):
            if proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=5)
            codes[name] = proc.returncode
        for log in self._logs:
            log.close()
        return codes


def _wait_for_sim(proc: subprocess.Popen[str], count: int, timeout: float) -> list[str]:
    """The sim's "vehicle on the air" lines (it prints one per vehicle)."""
    lines: list[str] = []
    done = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip())
            if len(lines) >= count:
                done.set()
        done.set()

    threading.Thread(target=read, daemon=True).start()
    done.wait(timeout)
    return lines


class DemoOperator:
    """The unattended operator: a DDS participant with a fleet view and command writers."""

    def __init__(self, domain: int, operator: str, authority: int) -> None:
        from edge_vis.dds import DdsBridge

        self.bridge = DdsBridge(domain)
        self.readers = {t: self.bridge.reader(t) for t in READ_TOPICS}
        self.bridge.open_writers(WRITE_TOPICS)
        self.view = FleetView()
        self.operator = operator
        self.authority = authority
        self.services: dict[str, set[str]] = {}
        self.sent: list[str] = []
        self.delivered: list[str] = []

    def poll(self, seconds: float, until: Callable[[], bool] | None = None,
             deadline: float | None = None) -> bool:
        end = time.monotonic() + seconds
        if deadline is not None:
            end = min(end, deadline)
        while True:
            now = time.monotonic()
            for topic, reader in self.readers.items():
                for sample in reader.take():
                    self.view.ingest(topic, sample, now)
                    if topic == "VehicleIdentification":
                        self.services[sample["vehicle_id"]] = {
                            s.get("uri", "") for s in sample.get("services", [])}
            if until is not None and until():
                return True
            if now >= end:
                return False
            time.sleep(0.05)

    def with_service(self, uri: str) -> list[str]:
        return sorted(v for v, uris in self.services.items() if uri in uris)

    def script(self, deadline: float, log: Callable[[str], None]) -> None:
        """Take control of a ground vehicle, drive it, send it a plan; note what took effect."""
        if not self.poll(30.0, lambda: bool(self.with_service(DRIVER)), deadline):
            log("no drivable vehicle seen on DDS")
            return
        vid = self.with_service(DRIVER)[0]
        row = self.view.row(vid)
        self._send(f"control {vid}", "ControlRequest",
                   control_request(vid, self.operator, self.authority))
        if self.poll(8.0, lambda: row.control == "CONTROLLED", deadline):
            self.delivered.append(f"control {vid}")
            log(f"{vid}: control granted")
        end_drive = time.monotonic() + 3.0
        moved = False
        while time.monotonic() < min(end_drive, deadline):
            self.bridge.publish("WrenchEffortCommand",
                                wrench_command(vid, self.operator, 60.0, 10.0))
            self.poll(0.2)
            moved = moved or (row.speed or 0.0) > 0.3
        self._send(f"drive {vid}", None, None)
        self.bridge.publish("WrenchEffortCommand", wrench_command(vid, self.operator, 0, 0))
        if moved or self.poll(1.0, lambda: (row.speed or 0.0) > 0.3, deadline):
            self.delivered.append(f"drive {vid}")
            log(f"{vid}: moving at {row.speed:.1f} m/s")
        if PLANNER in self.services.get(vid, set()) and row.latitude is not None:
            self.poll(1.0, deadline=deadline)
            plan = waypoint_plan(vid, self.operator, row.latitude, row.longitude or 0.0,
                                 row.yaw or 0.0, plan_id="demo-plan")
            self._send(f"plan {vid}", "WaypointPlan", plan)
            if self.poll(6.0, lambda: row.mission in ("EXECUTING", "COMPLETED"), deadline):
                self.delivered.append(f"plan {vid}")
                log(f"{vid}: waypoint plan {row.mission.lower()}")

    def _send(self, what: str, topic: str | None, sample: dict[str, Any] | None) -> None:
        self.sent.append(what)
        if topic is not None and sample is not None:
            self.bridge.publish(topic, sample)

    def release(self) -> None:
        for vid, row in self.view.vehicles.items():
            if row.control == "CONTROLLED" and row.controller == self.operator:
                self.bridge.publish("ControlRequest", control_request(
                    vid, self.operator, self.authority, release=True))

    def summary(self, seconds: float) -> dict[str, Any]:
        out = self.view.summary()
        out["duration_s"] = round(seconds, 1)
        out["vehicles_seen"] = len(out["vehicles"])
        out["commands_sent"] = self.sent
        out["commands_delivered"] = self.delivered
        return out

    def close(self) -> None:
        self.bridge.close()


def _print_summary(summary: dict[str, Any], view: FleetView, log_dir: Path) -> None:
    print(f"edge-vis demo: {summary['duration_s']} s, "
          f"{summary['vehicles_seen']} vehicles seen on DDS")
    for line in view.render(time.monotonic()):
        print("  " + line)
    print("samples per topic:")
    for topic, count in summary["samples_per_topic"].items():
        print(f"  {topic:<24}{count:>8}")
    sent, delivered = summary["commands_sent"], summary["commands_delivered"]
    print(f"commands: {len(sent)} sent, {len(delivered)} delivered (effect seen on DDS): "
          + (", ".join(delivered) or "none"))
    dropped = {vid: v for vid, v in summary["vehicles"].items() if v["dropouts"]}
    print(f"faults recovered: {summary['faults_recovered']}"
          + "".join(f"; {vid} dropped out {v['dropouts']}x, back {v['recovered']}x"
                    for vid, v in dropped.items()))
    print(f"logs: {log_dir}")


def run(args: argparse.Namespace) -> int:
    fleet = load_profile(args.fleet)
    relay_profile = args.relay_profile
    if (relay_profile is None and args.fleet.resolve() == DEFAULT_FLEET
            and DEFAULT_RELAY_PROFILE.exists()):
        relay_profile = DEFAULT_RELAY_PROFILE
    log_dir = args.log_dir or Path(tempfile.mkdtemp(prefix="edge-vis-demo-"))
    log_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    if "CYCLONEDDS_URI" not in env:
        from edge_vis.dds import loopback_config

        env["CYCLONEDDS_URI"] = loopback_config()
        os.environ["CYCLONEDDS_URI"] = env["CYCLONEDDS_URI"]  # for this process's own view
    children = Children(log_dir, env)
    relay_argv = ["run", "--domain", str(args.domain)]
    if relay_profile is not None:
        relay_argv += ["--profile", str(relay_profile)]
    else:
        for url in relay_links(fleet, args.relay_address):
            relay_argv += ["--link", url]
    interrupted = False
    operator: DemoOperator | None = None
    started = time.monotonic()
    try:
        sim = children.start("sim", ["sim", "--profile", str(args.fleet)], stdout_pipe=True)
        lines = _wait_for_sim(sim, len(fleet.vehicles), 15.0)
        if len(lines) < len(fleet.vehicles):
            print(f"edge-vis demo: the simulator did not start; see {log_dir / 'sim.log'}",
                  file=sys.stderr)
            return 1
        for line in lines:
            print(f"vehicle {line}")
        children.start("relay", relay_argv)
        print(f"relay: edge-vis {' '.join(relay_argv)}  (DDS domain {args.domain}, "
              f"logs in {log_dir})", flush=True)
        if args.duration is None:
            monitor = children.start("monitor", [
                "monitor", "--domain", str(args.domain), "--operator", args.operator,
                "--authority", str(args.authority)], foreground=True)
            monitor.wait()
            return 0
        children.start("monitor", ["monitor", "--domain", str(args.domain), "--interval", "5",
                                   "--wait", "2", "--duration", str(args.duration),
                                   "--operator", args.operator])
        deadline = started + args.duration
        operator = DemoOperator(args.domain, args.operator, args.authority)
        operator.script(deadline, lambda text: print(f"demo: {text}", flush=True))
        while time.monotonic() < deadline:
            operator.poll(min(1.0, max(0.0, deadline - time.monotonic())))
            gone = children.check()
            if gone is not None:
                print(f"edge-vis demo: {gone} exited early; see {log_dir / (gone + '.log')}",
                      file=sys.stderr)
                break
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if operator is not None:
            operator.release()
            operator.poll(0.3)
        codes = children.stop()
    if operator is None:
        return 130 if interrupted else 0
    summary = operator.summary(time.monotonic() - started)
    summary["exit_codes"] = codes
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_summary(summary, operator.view, log_dir)
    operator.close()
    return 130 if interrupted else 0
