"""``edge-vis plugins``: list the installed links, translators and message sets.

Reads package metadata; with ``--check`` it also imports each plugin, so a broken one
shows up here rather than when the relay starts.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from edge_vis import plugins
from edge_vis.errors import PluginError

NAME = "plugins"
HELP = "list installed link, translator and message-set plugins"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--check", action="store_true",
        help="also import every plugin and report failures (exit 1 if any fails)",
    )
    parser.add_argument(
        "--group", choices=plugins.GROUPS, action="append",
        help="only this group (repeatable; default all)",
    )


def _collect(groups: list[str], check: bool) -> dict[str, list[dict[str, Any]]]:
    report: dict[str, list[dict[str, Any]]] = {}
    for group in groups:
        rows = []
        for entry in plugins.entries(group):
            row: dict[str, Any] = {
                "name": entry.name,
                "target": entry.target,
                "distribution": entry.distribution,
                "version": entry.version,
            }
            if check:
                try:
                    plugins.load(group, entry.name)
                    row["ok"] = True
                except PluginError as exc:
                    row["ok"] = False
                    row["error"] = str(exc)
            rows.append(row)
        report[group] = rows
    return report


def _print_text(report: dict[str, list[dict[str, Any]]]) -> None:
    for group, rows in report.items():
        print(f"{group}:")
        if not rows:
            print("  (none installed)")
            continue
        name_w = max(len(r["name"]) for r in rows)
        target_w = max(len(r["target"]) for r in rows)
        for r in rows:
            dist = " ".join(p for p in (r["distribution"], r["version"]) if p) or "?"
            line = f"  {r['name']:<{name_w}}  {r['target']:<{target_w}}  {dist}"
            if "ok" in r:
                line += "  ok" if r["ok"] else f"  FAILED: {r['error']}"
            print(line)


def run(args: argparse.Namespace) -> int:
    groups = args.group or list(plugins.GROUPS)
    report = _collect(groups, args.check)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_text(report)
    failed = any(not r.get("ok", True) for rows in report.values() for r in rows)
    return 1 if failed else 0
