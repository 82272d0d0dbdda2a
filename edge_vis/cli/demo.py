"""``edge-vis demo``: the simulated fleet, the relay and the monitor in one command.

Starts three child processes on loopback - ``edge-vis sim`` with the fleet profile, the
relay (``edge-vis run``) and ``edge-vis monitor`` - with Cyclone DDS kept on 127.0.0.1.
Addresses, pseudo-terminal paths and the DDS domain are chosen free
(:mod:`edge_vis.tools.demo_place`), so several demos can run on one computer.

On a terminal the monitor owns it; quitting it (``q``) or Ctrl-C stops everything.
Without one (ssh without a tty, CI, output into a file) the monitor prints its table as
text every ``--interval`` seconds until SIGINT or SIGTERM, which stop everything with
exit status 0. With ``--duration N`` nothing needs a person: the demo itself joins DDS as
an operator, takes control of a ground vehicle, drives it, sends it a waypoint plan, and
after N seconds prints what DDS showed - vehicles seen, samples per topic, commands
whose effect was observed, vehicles that dropped out and came back. Child logs go to
``--log-dir``; when a child fails, the demo prints the line of its log that says why.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from edge_vis.errors import ConfigError
from edge_vis.tools.demo_place import (
    Placement,
    dump_toml,
    fleet_addresses,
    move_fleet,
    move_relay,
    place,
    relay_addresses,
)
from edge_vis.tools.monitor_view import (
    READ_TOPICS,
    WRITE_TOPICS,
    FleetView,
    control_request,
    emergency_command,
    waypoint_plan,
    wrench_command,
)
from edge_vis.tools.sim.profile import SimProfile, load_profile, parse_profile

NAME = "demo"
HELP = "run the simulated fleet, the relay and the monitor together on this computer"

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_FLEET = ROOT / "profiles" / "sim" / "fleet.toml"
DEFAULT_RELAY_PROFILE = ROOT / "profiles" / "demo.toml"
#: where the relay binds its UDP link when the demo derives links from the fleet
RELAY_BIND = "127.0.0.10:3794"
DRIVER = "urn:jaus:jss:mobility:PrimitiveDriver"
PLANNER = "urn:jaus:jss:mobility:GlobalWaypointListDriver"
#: seconds between tables when stdout is not a terminal
INTERVAL = 5.0
#: the radio between a vehicle's image server and the relay (UDT), as bench/bulk.py has it
IMAGE_RADIO = {"loss": 0.02, "delay": 0.020, "rate_bps": 10e6, "queue_bytes": 64 * 1024}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, metavar="S",
                        help="run unattended for S seconds, then print a summary")
    parser.add_argument("--domain", type=int, default=None,
                        help="DDS domain id (default: the lowest one nobody here uses)")
    parser.add_argument("--fleet", type=Path, default=None, metavar="FILE",
                        help="simulation profile (default profiles/sim/fleet.toml)")
    parser.add_argument("--relay-profile", type=Path, metavar="FILE",
                        help="relay profile, run as written with the fleet as written "
                             "(default: profiles/demo.toml with the shipped fleet, else "
                             "links derived from the fleet; both moved to free addresses)")
    parser.add_argument("--relay-address", default=RELAY_BIND, metavar="IP:PORT",
                        help=f"the relay's UDP address when links come from the fleet "
                             f"(default {RELAY_BIND}, or a free one like it)")
    parser.add_argument("--interval", type=float, default=INTERVAL, metavar="S",
                        help=f"without a terminal: seconds between tables (default "
                             f"{INTERVAL:g})")
    parser.add_argument("--operator", default="demo", metavar="ID",
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
    """The child processes, stopped in reverse order with SIGTERM, then harder.

    SIGTERM rather than SIGINT: a program started in the background by a script inherits
    SIGINT ignored, and each child stops cleanly on SIGTERM.
    """

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
                    proc.send_signal(signal.SIGTERM)
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
        """Take control of a ground vehicle, drive it, stop it with the emergency stop and
        clear that, send it a plan; note what took effect."""
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
        self.emergency_stop(vid, deadline, log)
        if PLANNER in self.services.get(vid, set()) and row.latitude is not None:
            self.poll(1.0, deadline=deadline)
            plan = waypoint_plan(vid, self.operator, row.latitude, row.longitude or 0.0,
                                 row.yaw or 0.0, plan_id="demo-plan")
            self._send(f"plan {vid}", "WaypointPlan", plan)
            if self.poll(6.0, lambda: row.mission in ("EXECUTING", "COMPLETED"), deadline):
                self.delivered.append(f"plan {vid}")
                log(f"{vid}: waypoint plan {row.mission.lower()}")

    def emergency_stop(self, vid: str, deadline: float, log: Callable[[str], None]) -> None:
        """Set the emergency stop while the vehicle is commanded, then clear it."""
        row = self.view.row(vid)
        self._send(f"emergency stop {vid}", "EmergencyCommand", emergency_command(
            vid, self.operator, self.authority, reason="demo: emergency stop drill"))
        if not self.poll(5.0, lambda: row.emergency and row.state == "EMERGENCY", deadline):
            return
        self.delivered.append(f"emergency stop {vid}")
        log(f"{vid}: EMERGENCY STOP confirmed by the vehicle")
        self._send(f"emergency clear {vid}", "EmergencyCommand", emergency_command(
            vid, self.operator, self.authority, clear=True))
        if self.poll(5.0, lambda: not row.emergency and row.state != "EMERGENCY", deadline):
            self.delivered.append(f"emergency clear {vid}")
            log(f"{vid}: emergency stop cleared, state {row.state}")

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


NEEDS_CHECKOUT = (
    "edge-vis demo: the demo runs from a source checkout of edge-vis: it needs the "
    "simulated fleet (profiles/sim/fleet.toml) and its relay profile (profiles/demo.toml), "
    "which this installation does not have. Clone the repository and run "
    "`bash scripts/demo.sh` there, or give --fleet FILE (and --relay-profile FILE) "
    "with profiles of your own.")


@dataclass
class Setup:
    """What the children are started with, after moving to free addresses."""

    sim_profile: Path
    fleet: SimProfile
    relay_argv: list[str]
    placement: Placement
    notes: list[str] = field(default_factory=list)
    #: the relay profile the demo writes (moved), when it runs the shipped one
    relay_data: dict[str, Any] | None = None


def _parse_address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ConfigError([("--relay-address", "", f"{text!r} is not IP:PORT")])
    return host, int(port)


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError([(str(path), "", f"cannot read: {exc.strerror or exc}")]) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([(str(path), "", f"not valid TOML: {exc}")]) from None


def prepare(args: argparse.Namespace, run_dir: Path) -> Setup:
    """Choose free addresses, paths and domain; write moved profiles into ``run_dir``.

    The fleet and the relay profile are used as written when their addresses are free
    (or when ``--relay-profile`` names a profile: it fixes the addresses); otherwise
    moved copies are written to ``run_dir`` and used instead.
    """
    fleet_path: Path = args.fleet or DEFAULT_FLEET
    fleet = load_profile(fleet_path)
    if args.relay_profile is not None:
        placement = place([], args.domain, as_written=True)
        return Setup(fleet_path, fleet, ["run", "--profile", str(args.relay_profile)],
                     placement)
    fleet_data = _read_toml(fleet_path)
    shipped = (args.fleet is None or fleet_path.resolve() == DEFAULT_FLEET) \
        and DEFAULT_RELAY_PROFILE.is_file()
    relay_data = _read_toml(DEFAULT_RELAY_PROFILE) if shipped else None
    relay_bind = _parse_address(args.relay_address)
    relay_wanted = relay_addresses(relay_data) if relay_data is not None else [relay_bind]
    placement = place(relay_wanted + fleet_addresses(fleet_data), args.domain)
    setup = Setup(fleet_path, fleet, ["run"], placement)
    paths: dict[str, str] = {}
    if placement.moved:
        moved, paths = move_fleet(fleet_data, placement, run_dir)
        setup.sim_profile = run_dir / "fleet.toml"
        setup.sim_profile.write_text(dump_toml(moved, header=(
            f"{fleet_path} moved by edge-vis demo to free loopback addresses and to "
            f"pseudo-terminal links in {run_dir}")), encoding="utf-8")
        setup.fleet = parse_profile(moved, str(setup.sim_profile))
        written = ", ".join("{}:{}".format(*a) for a in placement.addresses)
        used = ", ".join("{}:{}".format(*a) for a in placement.addresses.values())
        setup.notes.append(f"{written} are not all free (another demo running?); "
                           f"this demo uses {used} instead")
    if relay_data is None:
        for url in relay_links(setup.fleet, "{}:{}".format(*placement.address(*relay_bind))):
            setup.relay_argv += ["--link", url]
    elif placement.moved:
        relay_path = run_dir / "relay.toml"
        setup.relay_data = move_relay(relay_data, placement, paths)
        relay_path.write_text(dump_toml(setup.relay_data, header=(
            f"{DEFAULT_RELAY_PROFILE} with the links of the moved fleet "
            f"({setup.sim_profile}), written by edge-vis demo")), encoding="utf-8")
        setup.relay_argv += ["--profile", str(relay_path)]
    else:
        setup.relay_data = relay_data
        setup.relay_argv += ["--profile", str(DEFAULT_RELAY_PROFILE.relative_to(ROOT))
                             if Path.cwd() == ROOT else str(DEFAULT_RELAY_PROFILE)]
    setup.relay_argv += ["--domain", str(placement.domain)]
    return setup


def radio_for_images(setup: Setup, lines: list[str], run_dir: Path, lifetime: float
                     ) -> list[Any]:
    """Put an emulated radio (:data:`IMAGE_RADIO`) in front of each vehicle's image server
    (the ``images=udt://`` the sim printed) and point the relay's ``[bulk.sources]`` there,
    its images into ``run_dir``; the proxies, to stop at the end."""
    if setup.relay_data is None or "bulk" not in setup.relay_data:
        return []
    from edge_vis.tools.lossy_udp import LossyProxy

    proxies: list[Any] = []
    sources: dict[str, str] = {}
    for line in lines:
        found = re.match(r"^(\S+) \S+ (\d+) .* images=udt://(\S+):(\d+)$", line)
        if found is None:
            continue
        name, subsystem, host, port = found.groups()
        proxy = LossyProxy((host, int(port)), listen=(host, 0), lifetime=lifetime,
                           **IMAGE_RADIO).start()
        proxies.append(proxy)
        sources[f"{name}-{subsystem}"] = "{}:{}".format(*proxy.address)
        print(f"demo: {name} serves its ATR images on udt://{host}:{port}; the relay fetches "
              "them through an emulated radio (10 Mbit/s, 2 % loss, 20 ms) on "
              "{}:{}".format(*proxy.address), flush=True)
    if proxies:
        data = dict(setup.relay_data)
        data["bulk"] = {**data["bulk"], "dir": str(run_dir / "images"), "sources": sources}
        relay_path = run_dir / "relay.toml"
        relay_path.write_text(dump_toml(data, header=(
            f"{DEFAULT_RELAY_PROFILE} with the fleet's image servers behind an emulated "
            "radio, written by edge-vis demo")), encoding="utf-8")
        at = setup.relay_argv.index("--profile")
        setup.relay_argv[at + 1] = str(relay_path)
    return proxies


def _cause(log: Path) -> str:
    """The line of a child's log saying why it stopped: its last error, else its last line."""
    try:
        lines = [line.strip() for line in log.read_text(encoding="utf-8",
                                                        errors="replace").splitlines()]
    except OSError:
        return "(no log)"
    lines = [line for line in lines if line]
    for line in reversed(lines):
        if (line.startswith("edge-vis ") or " ERROR " in line or " CRITICAL " in line
                or re.match(r"^[\w.]+(Error|Exception|Exit)\b", line)):
            return line
    return lines[-1] if lines else "(nothing in its log)"


def _failed(name: str, log_dir: Path, what: str = "exited early") -> None:
    log = log_dir / f"{name}.log"
    print(f"edge-vis demo: the {name} {what}: {_cause(log)}\n  (log: {log})",
          file=sys.stderr, flush=True)


def _raise_interrupt(_signum: int, _frame: object) -> None:
    raise KeyboardInterrupt


def _watch(children: Children, monitor: subprocess.Popen[str]) -> str | None:
    """Wait for the monitor to quit; the name of a child that failed instead, if any."""
    while True:
        try:
            monitor.wait(timeout=0.5)
        except subprocess.TimeoutExpired:
            gone = children.check()
            if gone is not None:
                return gone
            continue
        return "monitor" if monitor.returncode != 0 else None


def run(args: argparse.Namespace) -> int:
    if args.fleet is None and not DEFAULT_FLEET.is_file():
        print(NEEDS_CHECKOUT, file=sys.stderr)
        return 2
    if args.interval <= 0:
        print("edge-vis demo: --interval must be positive", file=sys.stderr)
        return 2
    log_dir = args.log_dir or Path(tempfile.mkdtemp(prefix="edge-vis-demo-"))
    log_dir.mkdir(parents=True, exist_ok=True)
    setup = prepare(args, log_dir)
    domain = setup.placement.domain
    env = dict(os.environ)
    if "CYCLONEDDS_URI" not in env:
        from edge_vis.dds import loopback_config

        env["CYCLONEDDS_URI"] = loopback_config()
        os.environ["CYCLONEDDS_URI"] = env["CYCLONEDDS_URI"]  # for this process's own view
    children = Children(log_dir, env)
    interrupted = False
    failed: str | None = None
    operator: DemoOperator | None = None
    proxies: list[Any] = []
    started = time.monotonic()
    # SIGTERM stops like Ctrl-C, and so does SIGINT even when started with it ignored
    previous = {sig: signal.signal(sig, _raise_interrupt)
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for note in setup.notes:
            print(f"demo: {note}", flush=True)
        count = len(setup.fleet.vehicles)
        sim = children.start("sim", ["sim", "--profile", str(setup.sim_profile)],
                             stdout_pipe=True)
        lines = _wait_for_sim(sim, count, 15.0)
        if len(lines) < count:
            with contextlib.suppress(subprocess.TimeoutExpired):
                sim.wait(timeout=5)
            _failed("sim", log_dir, "did not start" if sim.poll() is not None
                    else f"did not bring up its {count} vehicles within 15 s")
            return 1
        for line in lines:
            print(f"vehicle {line}")
        proxies = radio_for_images(setup, lines, log_dir, lifetime=(
            args.duration + 60 if args.duration is not None else 1e9))
        children.start("relay", setup.relay_argv)
        print(f"relay: edge-vis {' '.join(setup.relay_argv)}  (logs in {log_dir})")
        print(f"demo: DDS domain {domain}; another view: "
              f"edge-vis monitor --loopback --domain {domain}", flush=True)
        sheet = ["--contact-sheet", str(log_dir / "images.html")] if proxies else []
        if sheet:
            print(f"demo: the latest image of each vehicle: {log_dir / 'images.html'} "
                  "(open it in a browser)", flush=True)
        if args.duration is None:
            argv = ["monitor", "--domain", str(domain), "--operator", args.operator,
                    "--authority", str(args.authority), *sheet]
            if not sys.stdout.isatty():  # no screen to draw on: tables until stopped
                argv += ["--interval", f"{args.interval:g}"]
            failed = _watch(children, children.start("monitor", argv, foreground=True))
        else:
            children.start("monitor", ["monitor", "--domain", str(domain), "--interval", "5",
                                       "--wait", "2", "--duration", str(args.duration),
                                       "--operator", args.operator, *sheet])
            deadline = started + args.duration
            operator = DemoOperator(domain, args.operator, args.authority)
            operator.script(deadline, lambda text: print(f"demo: {text}", flush=True))
            while time.monotonic() < deadline:
                operator.poll(min(1.0, max(0.0, deadline - time.monotonic())))
                failed = children.check()
                if failed is not None:
                    break
    except KeyboardInterrupt:
        interrupted = True
    finally:
        for sig in previous:  # a second signal must not cut the clean-up short
            signal.signal(sig, signal.SIG_IGN)
        try:
            if operator is not None:
                operator.release()
                operator.poll(0.3)
            codes = children.stop()
            for proxy in proxies:
                proxy.stop()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            setup.placement.release()
    if failed is not None:
        _failed(failed, log_dir)
    if operator is None:
        if failed is not None:
            return 1
        # without --duration the demo runs until stopped: a signal is the normal end
        return 130 if interrupted and args.duration is not None else 0
    summary = operator.summary(time.monotonic() - started)
    summary["exit_codes"] = codes
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_summary(summary, operator.view, log_dir)
    operator.close()
    return 130 if interrupted else 0
