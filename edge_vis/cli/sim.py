"""``edge-vis sim``: run simulated JAUS vehicles from a simulation profile.

Every vehicle of the profile comes up on its own loopback address or serial
pseudo-terminal and behaves like a JAUS robot until SIGINT/SIGTERM. One line per vehicle
is printed on stdout when it is on the air (for scripts: ``NAME KIND SUBSYSTEM WHERE``);
what the vehicles do, and any error, goes to stderr, so stdout carries only those lines.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import errno
import logging
import signal
import sys
from pathlib import Path

from edge_vis.tools.sim.profile import load_profile
from edge_vis.tools.sim.runner import Simulation

log = logging.getLogger(__name__)

NAME = "sim"
HELP = "simulate JAUS vehicles (UDP on loopback, serial on pseudo-terminals) from a profile"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", required=True, type=Path, metavar="FILE",
                        help="simulation profile (e.g. profiles/sim/fleet.toml)")
    parser.add_argument("--only", action="append", metavar="NAME", default=[],
                        help="simulate only this vehicle of the profile (repeatable)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after S seconds (default: run until interrupted)")


async def _main(args: argparse.Namespace) -> int:
    profile = load_profile(args.profile)
    if args.only:
        unknown = set(args.only) - {v.name for v in profile.vehicles}
        if unknown:
            names = ", ".join(v.name for v in profile.vehicles)
            print(f"edge-vis sim: no vehicle {', '.join(sorted(unknown))} in {args.profile} "
                  f"(it has {names})", file=sys.stderr)
            return 2
        profile = type(profile)(tuple(v for v in profile.vehicles if v.name in args.only),
                                profile.source)
    sim = Simulation(profile)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        await sim.start()
    except OSError as exc:
        hint = ""
        if exc.errno == errno.EADDRINUSE:
            hint = " (another program holds it: a simulator or demo already running?)"
        print(f"edge-vis sim: {exc}{hint}", file=sys.stderr)
        return 2
    try:
        for ep in sim.endpoints:
            server = sim.image_servers.get(ep.name)
            images = " images=udt://{}:{}".format(*server.address) if server else ""
            print(f"{ep.name} {ep.spec.kind} {ep.spec.subsystem} {ep.where}{images}",
                  flush=True)
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(args.duration):
                await stop.wait()
        log.info("stopping the simulation")
    finally:
        for ep in sim.endpoints:
            ep._log_stats()
        await sim.stop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    return 0


def run(args: argparse.Namespace) -> int:
    return asyncio.run(_main(args))
