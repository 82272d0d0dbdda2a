"""``edge-vis check FILE.toml``: validate a profile of any kind without running anything.

The kind of file (deployment, vehicle, sim or link profile) is told from its keys and its
folder (:mod:`edge_vis.config.kinds`), or given with ``--kind``, and the file is checked
against that kind's schema. A deployment profile is checked as ``edge-vis run`` starts:
every link URL and its options by its link plugin (nothing is opened), the translators
it enables built with their ``[translators.NAME]`` tables, and what those tables name
(generic mappings: message, query, service, field paths) and what vehicle discovery
profiles name (hello or passive messages, hello field paths) looked up in the message
catalogue with the profile's own JSIDL; ``[dds.security]`` files exist, parse, are signed
by the configured CA and name the relay's certificate (with the ``openssl`` command).
Prints ``OK``, the kind and a one-line summary, or every problem (file, key path,
problem) and exits with status 2. Reads the file and the files it references.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from edge_vis.bandwidth.linkspec import read_link_profile
from edge_vis.catalogue.jsidl import profile_catalogue
from edge_vis.config import default_profile_path, read_profile_file, read_toml
from edge_vis.config.kinds import (
    DEPLOYMENT,
    KINDS,
    LINK,
    SIM,
    VEHICLE,
    expected_kinds,
    profile_kind,
)
from edge_vis.config.vehicles import read_vehicle
from edge_vis.engine.announcements import discovery_problems
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import ConfigError, PluginError
from edge_vis.schema import Reader
from edge_vis.tools.deployment_keys import security_problems
from edge_vis.tools.sim.profile import read_sim_profile

NAME = "check"
HELP = "validate a profile (deployment, vehicle, sim or link) and list every problem"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", nargs="?", default=None,
                        help="profile to check (default: the built-in default profile)")
    parser.add_argument("--kind", choices=KINDS,
                        help="the kind of profile (default: told from its keys and folder)")


def run(args: argparse.Namespace) -> int:
    path = Path(args.profile) if args.profile else default_profile_path()
    try:
        data = read_toml(path)
    except ConfigError as exc:
        return _refused(path, "", exc.problems)
    kind, why = (args.kind, "") if args.kind else profile_kind(data, path)
    if kind is None:
        print(f"{path}: cannot tell which kind of profile this is: {why}. Expected one of:\n"
              f"{expected_kinds()}\n(or name it: edge-vis check --kind KIND {path})",
              file=sys.stderr)
        return 2
    try:
        summary = CHECKS[kind](path, data)
    except ConfigError as exc:
        return _refused(path, kind, exc.problems)
    except PluginError as exc:
        return _refused(path, kind, [(str(path), "translators", str(exc))])
    print(f"OK {path}: {kind} profile: {summary}")
    return 0


def _refused(path: Path, kind: str, problems: list[tuple[str, str, str]]) -> int:
    what = f" {kind} profile:" if kind else ""
    print(f"{path}:{what} {len(problems)} problem(s)", file=sys.stderr)
    for file, key, message in problems:
        where = ": ".join(part for part in (file or str(path), key) if part)
        print(f"  {where}: {message}", file=sys.stderr)
    return 2


def _checked(path: Path, read: Callable[[Reader, Mapping[str, Any]], Any],
             data: Mapping[str, Any]) -> Any:
    reader = Reader(str(path), base_dir=path.parent)
    result = read(reader, data)
    reader.raise_problems()
    return result


def check_deployment(path: Path, data: Mapping[str, Any]) -> str:
    """What ``edge-vis run`` checks before it opens anything (links: by their plugins)."""
    profile = _checked(path, read_profile_file, data)
    manager = TranslationManager.from_selection(profile.translators)
    try:
        catalogue = profile_catalogue(profile.jsidl)
    except PluginError as exc:  # a JSIDL code clashing with a known message
        raise ConfigError([(str(path), "catalogue.jsidl", str(exc))]) from exc
    problems: list[tuple[str, str, str]] = []
    try:
        manager.verify(catalogue, str(path))
    except ConfigError as exc:
        problems.extend(exc.problems)
    problems.extend(discovery_problems(profile.vehicles, catalogue, str(path)))
    security = profile.dds.security
    if security is not None:
        problems.extend((str(path), key, problem)
                        for key, problem in security_problems(
                            security, domain=profile.dds.domain,
                            partitions=profile.dds.partitions))
        if profile.operators.any_operator:
            problems.append((str(path), "access.any_operator", "with [dds.security] only "
                             "listed [[operators]] are authenticated: set it to false"))
    if problems:
        raise ConfigError(problems)
    return (f"relay {profile.jaus_id}, {len(profile.links)} link(s), "
            f"{len(profile.vehicles)} vehicle(s), {len(manager.translators)} translator(s)"
            + (", DDS Security" if security is not None else "")
            + "".join(f", forwarding between {' and '.join(group)}"
                      for group in profile.routing.forward))


def check_vehicle(path: Path, data: Mapping[str, Any]) -> str:
    """A vehicle profile on its own; its link name is checked with the deployment."""
    vehicle = _checked(path, read_vehicle, data)
    where = f"subsystem {vehicle.subsystem}" if vehicle.subsystem is not None else \
        "subsystem from discovery"
    static = f", static ({len(vehicle.components)} component(s))" if vehicle.is_static else ""
    found = vehicle.discovery
    how = "" if found is None else \
        f", found by its hello {found.hello}" if found.hello else ", found passively"
    who = repr(vehicle.vehicle_id) if vehicle.vehicle_id else "family (id from each vehicle)"
    return f"vehicle {who}, {where}{static}{how}"


def check_sim(path: Path, data: Mapping[str, Any]) -> str:
    """A simulation profile, as ``edge-vis sim`` reads it."""
    sim = _checked(path, read_sim_profile, data)
    return f"{len(sim.vehicles)} vehicle(s): " + ", ".join(
        f"{v.name} ({v.kind}{_arm(v)}, {v.link})" for v in sim.vehicles)


def _arm(vehicle: Any) -> str:
    arm = vehicle.manipulator
    return f" + manipulator v{arm.version}" if arm is not None else ""


def check_link(path: Path, data: Mapping[str, Any]) -> str:
    """A link profile file, as a deployment's ``profile =`` reads it."""
    spec = _checked(path, read_link_profile, data)
    duplex = "half" if spec.half_duplex else "full"
    return f"{spec.bit_rate:.0f} bit/s {duplex} duplex, mtu {spec.mtu}, budget {spec.budget:g}"


CHECKS: Mapping[str, Callable[[Path, Mapping[str, Any]], str]] = {
    DEPLOYMENT: check_deployment, VEHICLE: check_vehicle, SIM: check_sim, LINK: check_link,
}
