"""``edge-vis check PROFILE.toml``: validate a deployment profile without opening links.

Besides the profile itself, the translators it enables are loaded and given their
``[translators.<name>]`` tables, as the relay does at start-up, so a bad mapping table or a
missing or conflicting translator shows here rather than when the relay starts. Prints
``OK`` and a one-line summary, or every problem found (file, key path, problem) and exits
with status 2. Reads the profile and the files it references; opens no link.
"""

from __future__ import annotations

import argparse
import sys

from edge_vis.config import default_profile_path, load_profile
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import ConfigError, PluginError

NAME = "check"
HELP = "validate a deployment profile (TOML) and list every problem"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", nargs="?", default=None,
                        help="profile to check (default: the built-in default profile)")


def run(args: argparse.Namespace) -> int:
    path = args.profile or str(default_profile_path())
    try:
        profile = load_profile(path)
        manager = TranslationManager.from_selection(profile.translators)
    except ConfigError as exc:
        print(f"{path}: {len(exc.problems)} problem(s)", file=sys.stderr)
        for file, key, message in exc.problems:
            where = ": ".join(part for part in (file or path, key) if part)
            print(f"  {where}: {message}", file=sys.stderr)
        return 2
    except PluginError as exc:
        print(f"{path}: 1 problem(s)", file=sys.stderr)
        print(f"  {path}: translators: {exc}", file=sys.stderr)
        return 2
    print(f"OK {path}: relay {profile.jaus_id}, {len(profile.links)} link(s), "
          f"{len(profile.vehicles)} vehicle(s), {len(manager.translators)} translator(s)")
    return 0
