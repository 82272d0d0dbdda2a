"""``edge-vis messages``: list every JAUS message edge-vis can decode, per message set.

Lists the built-in sets and the message-set plugins (entry-point group
``edge_vis.messages``); ``--jsidl`` reads a user's JSIDL files too and says, for each of their
messages, whether it is new, the same layout as the one already known, or a different one
(a conflict: exit status 1). Reads only the JSIDL files named on the command line.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from edge_vis.codec.types import MessageDef

NAME = "messages"
HELP = "list the known JAUS messages (code, name, message set, services)"

#: attributes that do not change the bytes on the wire or the decoded keys
_COSMETIC = frozenset({"labels", "ranges", "units", "jsidl_name", "doc"})


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--set", dest="sets", action="append", metavar="NAME",
                        help="only this message set (repeatable)")
    parser.add_argument("--jsidl", action="extend", nargs=1, metavar="FILE", default=[],
                        help="also read this JSIDL file or folder (repeatable) and check its "
                             "messages against the known ones")


def _layout(value: Any) -> Any:
    """A comparable form of a definition keeping only what reaches the wire or the keys."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        kind = type(value).__name__
        parts = []
        for fld in dataclasses.fields(value):
            if fld.name in _COSMETIC or (fld.name == "name" and kind != "Field"):
                continue
            item = getattr(value, fld.name)
            if fld.name == "format" and isinstance(item, str):
                continue
            parts.append((fld.name, _layout(item)))
        return (kind, tuple(parts))
    if isinstance(value, tuple | list):
        return tuple(_layout(v) for v in value)
    return value


def _definitions(catalogue: Iterable[Any]) -> list[MessageDef]:
    """The catalogue's definitions, whether it iterates definitions or codes."""
    defs = []
    for item in catalogue:
        defn = catalogue.get(item) if isinstance(item, int) else item  # type: ignore[attr-defined]
        if defn is not None:
            defs.append(defn)
    return defs


def _builtin_sets() -> frozenset[str]:
    from edge_vis.jaus import messages

    return frozenset(getattr(messages, "BUILTIN_SETS", ()))


def _row(defn: MessageDef, source: str, origin: str, status: str = "") -> dict[str, Any]:
    row: dict[str, Any] = {
        "code": defn.code,
        "code_hex": f"0x{defn.code:04X}",
        "name": defn.name,
        "service_set": defn.service_set,
        "services": [{"uri": uri, "version": version} for uri, version in defn.services],
        "source": source,
        "from": origin,
    }
    if status:
        row["status"] = status
    return row


def _check(defn: MessageDef, known: MessageDef | None) -> tuple[str, bool]:
    """``(status, conflict)`` of a user's JSIDL message against the known one."""
    if known is None:
        return "new", False
    if _layout(known.body) == _layout(defn.body) and known.name == defn.name:
        return f"same as {known.service_set}", False
    return f"DIFFERS from {known.name} in {known.service_set}", True


def collect(args: argparse.Namespace) -> list[dict[str, Any]]:
    """A row for every known message and, with ``--jsidl``, every message of those files."""
    from edge_vis.catalogue import default_catalogue

    catalogue = default_catalogue()
    builtin = _builtin_sets()
    known = {d.code: d for d in _definitions(catalogue)}
    source_of = getattr(catalogue, "source", lambda code: "")
    rows = [_row(d, "built-in" if d.service_set in builtin else "plugin", source_of(d.code))
            for d in sorted(known.values(), key=lambda d: d.code)]
    if args.jsidl:
        from edge_vis.catalogue.jsidl import load_jsidl

        files = ", ".join(args.jsidl)
        for defn in sorted(load_jsidl([Path(p) for p in args.jsidl]), key=lambda d: d.code):
            status, conflict = _check(defn, known.get(defn.code))
            row = _row(defn, "jsidl", files, status)
            row["conflict"] = conflict
            rows.append(row)
        rows.sort(key=lambda r: (r["code"], r["source"] == "jsidl"))
    return rows


def _counts(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    counts: dict[str, dict[str, Any]] = {}
    for row in rows:
        entry = counts.setdefault(row["service_set"], {"count": 0, "source": row["source"]})
        entry["count"] += 1
    return counts


def _print_text(rows: list[dict[str, Any]], counts: dict[str, dict[str, Any]]) -> None:
    name_w = max([len(r["name"]) for r in rows] + [4])
    set_w = max([len(r["service_set"]) for r in rows] + [3])
    print(f"{'CODE':<6}  {'NAME':<{name_w}}  {'SET':<{set_w}}  SERVICES")
    for r in rows:
        services = ", ".join(f"{s['uri']} {s['version']}" for s in r["services"]) or "-"
        status = f"  [{r['source']}: {r['status']}]" if "status" in r else ""
        print(f"{r['code_hex']:<6}  {r['name']:<{name_w}}  {r['service_set']:<{set_w}}  "
              f"{services}{status}")
    print()
    width = max([len(s) for s in counts] + [5])
    for set_name, entry in counts.items():
        print(f"{set_name:<{width}}  {entry['count']:>4}  {entry['source']}")
    print(f"{'total':<{width}}  {len(rows):>4}  messages in {len(counts)} set(s)")


def run(args: argparse.Namespace) -> int:
    rows = collect(args)
    if args.sets:
        available = {r["service_set"] for r in rows}
        unknown = [s for s in args.sets if s not in available]
        if unknown:
            print(f"edge-vis messages: no message set named {', '.join(unknown)} "
                  f"(known: {', '.join(sorted(available))})", file=sys.stderr)
            return 2
        rows = [r for r in rows if r["service_set"] in args.sets]
    counts = _counts(rows)
    conflicts = sum(1 for r in rows if r.get("conflict"))
    if args.json:
        print(json.dumps({"messages": rows, "sets": counts, "total": len(rows),
                          "conflicts": conflicts}, indent=2))
    else:
        _print_text(rows, counts)
    if conflicts:
        print(f"edge-vis messages: {conflicts} JSIDL message(s) differ from the known definition "
              f"of the same code", file=sys.stderr)
        return 1
    return 0
