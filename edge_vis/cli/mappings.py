"""``edge-vis mappings``: the table of every JAUS message <-> DDS topic edge-vis translates.

Generated from the installed translators' own declarations (their ``describe()`` rows,
the same rule tables they run), so it cannot drift from what the relay does. A plain
translator keeps the contract's default rows, from its ``messages`` and ``publishes``.
Markdown (for the README) by default, ``--json`` for tools. ``--profile`` applies a
deployment profile: its translator selection and the ``generic`` translator's mappings.
Reads the profile (and the files it references) only.

Counting (``counts``, with the catalogue: :func:`coverage`): a message is *translated* when a
row maps it JAUS -> DDS or DDS -> JAUS and it is not a query; *queried* when it is only
sent to obtain a report (a ``Query*`` message, also one a DDS command triggers); *handled
by the engine* when the core declares it (:mod:`edge_vis.engine.handled`). *On the wire*
is all three. A public service URI (of the built-in message sets, client services left
out) is *covered* when at least one message its service declares is translated or handled
by the engine. Every other catalogue message is listed with the reason it is not
translated; one without a reason is ``unexplained``.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from edge_vis import plugins
from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.config import TranslatorSelection, load_profile
from edge_vis.engine.handled import ENGINE_DECLINED, ENGINE_HANDLED, ENGINE_RECEIVES
from edge_vis.engine.manager import TranslationManager
from edge_vis.jaus.messages import BUILTIN_SETS
from edge_vis.kit import Translator

NAME = "mappings"
HELP = "print the JAUS message <-> DDS topic table of the installed translators"

_ARROWS = {"jaus->dds": "JAUS → DDS", "dds->jaus": "DDS → JAUS", "none": "not translated"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--translator", action="append", metavar="NAME",
                        help="only this translator (repeatable)")
    parser.add_argument("--profile", metavar="FILE",
                        help="use this deployment profile's translator selection and options")
    parser.add_argument("--count", action="store_true",
                        help="print only the number of translated JAUS messages")


def rows_of(translator: Translator) -> list[dict[str, Any]]:
    """The mapping rows of one translator instance (its declared ``describe()``)."""
    return [dict(row) for row in translator.describe()]


def collect(selection: TranslatorSelection | None = None,
            only: Iterable[str] | None = None) -> list[dict[str, Any]]:
    """Rows of every selected translator (all installed ones by default)."""
    if selection is None:
        selection = TranslatorSelection(tuple(only) if only else ("*",))
    manager = TranslationManager.from_selection(selection)
    wanted = set(only or ())
    rows: list[dict[str, Any]] = []
    for translator in manager.translators:
        if wanted and translator.name not in wanted:
            continue
        rows.extend(rows_of(translator))
    return rows


def is_query(name: str) -> bool:
    """Whether ``name`` is a query (JAUS names every query message ``Query...``)."""
    return name.startswith("Query")


def counts(rows: Iterable[Mapping[str, Any]],
           catalogue: Catalogue | None = None) -> dict[str, Any]:
    """How many distinct JAUS messages the rows translate, by role (see the module doc);
    with ``catalogue``, also the wire and service coverage (:func:`coverage`)."""
    rows = list(rows)
    mapped = {r["message"] for r in rows if r["direction"] != "none"}
    reports = {r["message"] for r in rows if r["direction"] == "jaus->dds"}
    commands = {r["message"] for r in rows
                if r["direction"] == "dds->jaus" and not is_query(r["message"])}
    queries = {r["query"] for r in rows if r["direction"] == "jaus->dds" and r["query"]} | {
        m for m in mapped if is_query(m)}
    translated = reports | commands
    out: dict[str, Any] = {
        "translated_messages": len(translated),
        "jaus_to_dds": len(reports),
        "dds_to_jaus": len(commands),
        "queries_sent": len(queries - translated),
        "jaus_messages_total": len(translated | queries),
        "dds_topics": len({r["topic"] for r in rows if r["direction"] != "none" and r["topic"]
                           and not r["topic"].startswith("(")}),
        "not_translated": len({r["message"] for r in rows if r["direction"] == "none"}
                              - translated),
    }
    if catalogue is not None:
        cover = coverage(rows, catalogue)
        out.update({k: v for k, v in cover.items() if not isinstance(v, list)})
    return out


def public_services(catalogue: Catalogue) -> dict[str, set[str]]:
    """Public non-client service URI -> the names of the messages it declares."""
    out: dict[str, set[str]] = {}
    for defn in catalogue:
        if defn.service_set not in BUILTIN_SETS:
            continue
        for uri, _version in defn.services:
            uri = uri.strip()
            if not uri.endswith("Client"):
                out.setdefault(uri, set()).add(defn.name)
    return out


def coverage(rows: Iterable[Mapping[str, Any]], catalogue: Catalogue) -> dict[str, Any]:
    """What reaches the wire and which public services it covers (see the module doc).

    ``untranslated`` lists every message of the built-in sets that is not translated, with
    its reason (a translator's ``not translated`` row, the engine's declaration, or the
    report it is queried for); ``unexplained`` the names that have none."""
    rows = list(rows)
    mapped = {r["message"] for r in rows if r["direction"] != "none"}
    translated = {m for m in mapped if not is_query(m)}
    queried_for: dict[str, str] = {}
    for r in rows:
        if r["direction"] == "jaus->dds" and r["query"]:
            queried_for.setdefault(r["query"], f"sent to obtain {r['message']}")
        elif r["direction"] == "dds->jaus" and is_query(r["message"]):
            queried_for.setdefault(r["message"], f"sent when {r['topic']} asks for it")
    reasons = {r["message"]: f"{r['translator']}: {r['doc']}" for r in rows
               if r["direction"] == "none" and r.get("doc")}
    wire = translated | set(queried_for) | ENGINE_HANDLED
    services = public_services(catalogue)
    covered = sorted(uri for uri, names in services.items()
                     if names & (translated | ENGINE_HANDLED))
    untranslated: list[dict[str, str]] = []
    unexplained: list[str] = []
    for defn in catalogue:
        if defn.service_set not in BUILTIN_SETS or defn.name in translated:
            continue
        if defn.name in ENGINE_HANDLED:
            why = "engine: " + (ENGINE_RECEIVES.get(defn.name) or "sent by the engine")
        elif defn.name in queried_for:
            why = "query: " + queried_for[defn.name]
        elif defn.name in reasons:
            why = reasons[defn.name]
        elif defn.name in ENGINE_DECLINED:
            why = "engine: " + ENGINE_DECLINED[defn.name]
        else:
            why = ""
            unexplained.append(defn.name)
        untranslated.append({"message": defn.name, "set": defn.service_set, "reason": why})
    return {
        "engine_handled": len(ENGINE_HANDLED - translated),
        "wire_messages": len(wire),
        "public_services": len(services),
        "public_services_covered": len(covered),
        "public_services_covered_percent": round(100.0 * len(covered) / len(services), 1)
        if services else 0.0,
        "catalogue_untranslated": len(untranslated),
        "unexplained": sorted(set(unexplained)),
        "services_not_covered": sorted(set(services) - set(covered)),
        "untranslated": untranslated,
    }


def markdown(rows: list[dict[str, Any]], catalogue: Catalogue | None = None) -> str:
    """The table as Markdown: one section per translator."""
    total = counts(rows, catalogue)
    out = [
        "# JAUS ⇄ DDS mappings",
        "",
        f"{total['translated_messages']} JAUS messages translated "
        f"({total['jaus_to_dds']} JAUS → DDS, {total['dds_to_jaus']} DDS → JAUS) over "
        f"{total['dds_topics']} DDS topics; {total['queries_sent']} more JAUS queries are "
        f"sent to obtain reports ({total['jaus_messages_total']} JAUS messages in all).",
        "Generated by `edge-vis mappings` from the translators' declarations.",
    ]
    if catalogue is not None:
        out.insert(-1, f"On the wire: {total['wire_messages']} JAUS messages (translated, "
                       f"queried, or among the {total['engine_handled']} more the engine "
                       f"handles itself); {total['public_services_covered']} of the "
                       f"{total['public_services']} public non-client service URIs "
                       f"covered ({total['public_services_covered_percent']:g} %).")
    translators = list(dict.fromkeys(r["translator"] for r in rows))
    for name in translators:
        mine = [r for r in rows if r["translator"] == name]
        done = [r for r in mine if r["direction"] != "none"]
        skipped = [r for r in mine if r["direction"] == "none"]
        out += ["", f"## {name}", ""]
        if done:
            out += ["| JAUS message | direction | DDS topic | fields (target ← source) | notes |",
                    "|---|---|---|---|---|"]
            for r in done:
                out.append("| " + " | ".join(_cell(x) for x in (
                    r["message"] + (f" (via {r['query']})" if r.get("query") else ""),
                    _ARROWS.get(r["direction"], r["direction"]), r["topic"],
                    "; ".join(_field(f, r["direction"]) for f in r["fields"]),
                    _notes(r))) + " |")
        if skipped:
            out += ["", "Not translated:", ""]
            out += [f"- {r['message']}: {r['doc']}" for r in skipped]
    if catalogue is not None:
        out += _engine_section(rows, catalogue)
    return "\n".join(out) + "\n"


def _engine_section(rows: list[dict[str, Any]], catalogue: Catalogue) -> list[str]:
    """The core messages the engine handles itself or leaves alone, and any catalogue
    message with neither a row nor a reason."""
    translated = {r["message"] for r in rows if r["direction"] != "none"}
    cover = coverage(rows, catalogue)
    out = ["", "## engine", "",
           "Handled by the engine itself (discovery, access control, events, liveness, time, "
           "emergency stop): " + ", ".join(sorted(ENGINE_HANDLED - translated)) + ".",
           "", "Not used:", ""]
    out += [f"- {name}: {why}" for name, why in ENGINE_DECLINED.items()]
    if cover["unexplained"]:
        out += ["", f"Not translated, no reason given ({len(cover['unexplained'])}): "
                    + ", ".join(cover["unexplained"]) + "."]
    return out


def _field(f: Mapping[str, Any], direction: str) -> str:
    """``target ← source``: the DDS member from the JAUS field, or the other way round."""
    if not f.get("jaus"):
        text = str(f["dds"])
    elif direction == "dds->jaus":
        text = f"{f['jaus']} ← {f['dds']}"
    else:
        text = f"{f['dds']} ← {f['jaus']}"
    return f"{text} ({f['note']})" if f.get("note") else text


def _notes(r: Mapping[str, Any]) -> str:
    parts = [str(r["doc"])] if r.get("doc") else []
    rate = r.get("rate")
    if isinstance(rate, int | float) and not math.isnan(rate):
        parts.append(f"{rate:g} Hz")
    return "; ".join(parts)


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def run(args: argparse.Namespace) -> int:
    selection = None
    if args.profile:
        selection = load_profile(args.profile).translators
    if args.translator:
        available = set(plugins.available(plugins.TRANSLATORS))
        unknown = [n for n in args.translator if n not in available]
        if unknown:
            # load() raises PluginNotFoundError listing the installed translators
            plugins.load(plugins.TRANSLATORS, unknown[0])
    rows = collect(selection, args.translator)
    # coverage is of the whole relay: with a subset of translators it would mislead
    catalogue = None if args.translator else default_catalogue()
    if args.count:
        print(counts(rows)["translated_messages"])
    elif args.json:
        cover = coverage(rows, catalogue) if catalogue is not None else {}
        print(json.dumps({"counts": counts(rows, catalogue), "rows": rows,
                          **{k: v for k, v in cover.items() if isinstance(v, list)}},
                         indent=2, default=str))
    else:
        print(markdown(rows, catalogue), end="")
    return 0
