"""``edge-vis run``: the relay itself — links, router, engine and DDS until stopped.

With no ``--profile`` it runs the shipped default deployment profile; ``--link URL``
(repeatable), ``--id S.N.C`` and ``--domain N`` override the profile, so a first try needs
no file at all. SIGINT/SIGTERM stop it cleanly: events cancelled, control released.
SIGHUP re-reads the profile (:mod:`edge_vis.shell.reload`); under systemd the relay reports
READY/WATCHDOG/STATUS/STOPPING (:mod:`edge_vis.shell.service`).

It refuses to start half-secured: with ``[dds.security]`` every file must be there, parse
and be signed by the configured CA (as ``edge-vis check`` checks), ``access.any_operator``
must be false, and the Cyclone DDS binding must have DDS Security; without it, a Cyclone
configuration (``CYCLONEDDS_URI``) that turns security on is refused too, because the relay
would then join securely but not bind commands to the operators who sent them.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import logging
import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from edge_vis.config import (
    LinkProfile,
    RelayProfile,
    link_problems,
    load_default_profile,
    load_profile,
)
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.shell import sharedloop
from edge_vis.shell.memory import tune_allocator
from edge_vis.shell.relay import Runtime
from edge_vis.shell.service import Supervisor

if TYPE_CHECKING:
    from edge_vis.shell.mirror import Mirror

NAME = "run"
HELP = "run the relay: discover JAUS vehicles and translate them to and from DDS"

log = logging.getLogger("edge_vis.run")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("--profile", type=Path, help="deployment profile (TOML); "
                        "default: the shipped profiles/default.toml")
    parser.add_argument("--link", action="append", default=[], metavar="URL",
                        help="link URL (repeatable); replaces the profile's links, e.g. "
                        "udp://127.0.0.1:3794 or serial:///dev/ttyUSB0?baud=57600")
    parser.add_argument("--id", metavar="S.N.C", help="the relay's own JAUS id")
    parser.add_argument("--domain", type=int, help="DDS domain id")
    parser.add_argument("--no-dds", action="store_true",
                        help="JAUS side only: do not join DDS (for testing links)")
    parser.add_argument("--mirror-udp", type=int, metavar="PORT",
                        help="copy every JAUS datagram seen on any link to this UDP port on "
                        "127.0.0.1 (for Wireshark or edge-vis decode)")
    parser.add_argument("--mirror-pcap", type=Path, metavar="FILE",
                        help="write every JAUS datagram seen on any link to a pcap file")
    parser.add_argument("--duration", type=float, metavar="SECONDS",
                        help="stop by itself after this many seconds")


def build_profile(args: argparse.Namespace) -> RelayProfile:
    """The profile with the command line's overrides applied."""
    profile = load_profile(args.profile) if args.profile else load_default_profile()
    changes: dict[str, object] = {}
    if args.link:
        links = tuple(LinkProfile(name=f"link{i}", url=url) for i, url in enumerate(args.link))
        # checked as a profile's links are (edge-vis check), before anything opens
        problems = [("--link", key, reason) for link in links
                    for key, reason in link_problems(link)]
        if problems:
            raise ConfigError(problems)
        changes["links"] = links
    if args.id:
        try:
            changes["jaus_id"] = JausAddress.parse(args.id)
        except ValueError as exc:
            raise ConfigError([("--id", "", str(exc))]) from None
    if args.domain is not None:
        changes["dds"] = dataclasses.replace(profile.dds, domain=args.domain)
    return dataclasses.replace(profile, **changes) if changes else profile


def _cyclone_security_outside(uri: str) -> bool:
    """True when the Cyclone configuration ``uri`` (XML text or file:// URLs) has a
    ``<Security>`` element."""
    texts = []
    for part in uri.split(","):
        part = part.strip()
        if part.startswith("file://"):
            try:
                texts.append(Path(part.removeprefix("file://")).read_text(encoding="utf-8"))
            except OSError:
                continue
        else:
            texts.append(part)
    return any("<Security" in text for text in texts)


def refuse_half_secured(profile: RelayProfile, *, dds: bool = True) -> None:
    """Raise ConfigError when the relay would run half-secured (see the module)."""
    if not dds:
        return
    where = profile.source or "profile"
    security = profile.dds.security
    if security is None:
        if _cyclone_security_outside(os.environ.get("CYCLONEDDS_URI", "")):
            raise ConfigError([(where, "dds.security", "CYCLONEDDS_URI turns DDS Security "
                                "on but the profile has no [dds.security]: commands would "
                                "not be bound to their senders; configure it in the profile")])
        return
    from edge_vis.tools.deployment_keys import security_problems  # openssl, when secured

    problems = [(where, key, problem) for key, problem in security_problems(
        security, domain=profile.dds.domain, partitions=profile.dds.partitions)]
    if profile.operators.any_operator:
        problems.append((where, "access.any_operator", "with [dds.security] only listed "
                         "[[operators]] are authenticated: set it to false"))
    if problems:
        raise ConfigError(problems)
    from edge_vis.dds.secure_qos import HOW_TO_SECURE, security_available

    if not security_available():
        raise ConfigError([(where, "dds.security", HOW_TO_SECURE)])


def _mirror(args: argparse.Namespace) -> Mirror | None:
    if args.mirror_udp is None and args.mirror_pcap is None:  # the usual case: no import
        return None
    from edge_vis.shell.mirror import Mirror

    return Mirror(udp_port=args.mirror_udp, pcap=args.mirror_pcap)


def run(args: argparse.Namespace) -> int:
    """Run until a signal (or ``--duration``)."""
    tune_allocator()  # before the relay allocates: days of running must not grow the heap
    profile = build_profile(args)
    refuse_half_secured(profile, dds=not args.no_dds)
    runtime = Runtime(profile, publisher_factory=None if args.no_dds else "dds",
                      mirror=_mirror(args))
    sharedloop.run(_main(runtime, args.duration, lambda: build_profile(args)))
    return 0


async def _main(runtime: Runtime, duration: float | None,
                reload_profile: Callable[[], RelayProfile] | None = None) -> None:
    loop = asyncio.get_running_loop()
    supervisor = Supervisor(runtime, reload_profile)  # systemd notify/watchdog, SIGHUP
    try:
        await runtime.start()
    except Exception as exc:
        supervisor.failed(exc)
        raise
    supervisor.started()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, supervisor.stop)
    if duration is not None:
        loop.call_later(duration, supervisor.stop)
    try:
        await runtime.wait_stopped()
    finally:
        supervisor.close()
