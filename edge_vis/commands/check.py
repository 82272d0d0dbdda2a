"""``edge-vis check PROFILE.toml``: validate a deployment profile without opening links.

Prints ``OK`` and a one-line summary, or every problem found (file, key path, problem)
and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys

from edge_vis.config import default_profile_path, load_profile
from edge_vis.errors import ConfigError

NAME = "check"
HELP = "validate a deployment profile (TOML) and list every problem"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", nargs="?", default=None,
                        help="profile to check (default: the built-in default profile)")


def run(args: argparse.Namespace) -> int:
    path = args.profile or str(default_profile_path())
    try:
        profile = load_profile(path)
    except ConfigError as exc:
        print(f"{path}: {len(exc.problems)} problem(s)", file=sys.stderr)
        for file, key, message in exc.problems:
            where = ": ".join(part for part in (file, key) if part)
            print(f"  {where}: {message}" if where else f"  {message}", file=sys.stderr)
        return 2
    print(f"OK {path}: relay {profile.jaus_id}, {len(profile.links)} link(s), "
          f"{len(profile.vehicles)} vehicle(s)")
    return 0
