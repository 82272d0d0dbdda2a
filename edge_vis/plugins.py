"""Finding and loading plugins through entry points. Reads package metadata and imports
plugin modules; no other I/O.

Links, bulk channels, translators and message sets are separate distributions (or the
``links`` and ``translators`` packages shipped beside the core) that declare entry points in one of
:data:`GROUPS`. The core names a plugin only by group and entry-point name, so it never
imports a plugin package by name, and a user adds one by installing it, not by editing
edge-vis.

* :func:`available` lists a group from metadata alone: nothing is imported, so listing
  never fails because one plugin is broken.
* :func:`load` imports one plugin on demand and checks it against its group's contract
  (:data:`CONTRACTS`: a link class, a bulk channel, a translator, a tuple of message
  definitions), so a plugin in the wrong group is caught by ``edge-vis plugins --check``
  and at start-up, not later inside the relay. A missing name raises
  :class:`~edge_vis.errors.PluginNotFoundError` listing the names that do exist and the
  one a typo most likely meant; an import that fails, or an object of the wrong kind, raises
  :class:`~edge_vis.errors.PluginLoadError` naming the plugin, chained to the cause.
* :func:`register` adds a plugin from inside the process (tests, embedding); it is loaded
  and validated by the same code as an installed one.
"""

from __future__ import annotations

import email.parser
import importlib
import logging
from dataclasses import dataclass
from importlib import metadata
from typing import Any

from edge_vis.errors import PluginConflictError, PluginLoadError, PluginNotFoundError

log = logging.getLogger(__name__)

LINKS = "edge_vis.links"
BULK = "edge_vis.bulk"
TRANSLATORS = "edge_vis.translators"
MESSAGES = "edge_vis.messages"
GROUPS: tuple[str, ...] = (LINKS, BULK, TRANSLATORS, MESSAGES)

#: the type every plugin of a group must be (a subclass of, for classes), by
#: ``module:qualname``: imported only when a plugin of that group is loaded
CONTRACTS: dict[str, str] = {
    LINKS: "edge_vis.routing.link:Link",
    BULK: "edge_vis.routing.bulk:BulkChannel",
    TRANSLATORS: "edge_vis.kit.contract:Translator",
    MESSAGES: "builtins:tuple",
}

#: Distribution shown for plugins added with :func:`register`.
REGISTERED = "(registered)"

#: said only when a group has no plugin at all: then the package metadata is missing
_INSTALL_HINT = "is edge-vis installed (pip install -e .)?"
#: what a plugin name is called in messages, by group
_WHAT = {LINKS: "link scheme", BULK: "bulk channel", TRANSLATORS: "translator",
         MESSAGES: "message set"}

# group -> name -> an EntryPoint (lazy target) or the plugin object itself
_registry: dict[str, dict[str, Any]] = {}


@dataclass(frozen=True)
class PluginEntry:
    """One plugin as declared, before anything is imported."""

    group: str
    name: str
    target: str
    """``module:attribute`` for entry points, ``module:qualname`` for registered objects."""
    distribution: str
    version: str = ""


def _dist_of(ep: metadata.EntryPoint) -> tuple[str, str]:
    """(name, version) of the distribution declaring ``ep``, from its metadata headers.

    Only the header block is parsed: ``dist.metadata`` would also parse the long
    description after it (a whole README), which made every plugin look-up cost
    milliseconds and a relay's start-up seconds.
    """
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "", ""
    try:
        text = dist.read_text("METADATA") or dist.read_text("PKG-INFO") or ""
        headers = email.parser.HeaderParser().parsestr(text.split("\n\n", 1)[0])
        return headers["Name"] or "", headers["Version"] or ""
    except Exception:  # broken metadata must not hide the other plugins
        return "", ""


def _installed(group: str) -> dict[str, list[tuple[metadata.EntryPoint, str, str]]]:
    """Entry points of ``group`` by name; the same target seen twice is kept once.

    The same distribution can appear twice on ``sys.path`` (an editable install and a
    stray ``*.egg-info`` in the working directory), so duplicates are folded by
    (distribution, target); two *different* targets under one name are kept, for
    :func:`load` to report as a conflict.
    """
    found: dict[str, list[tuple[metadata.EntryPoint, str, str]]] = {}
    for ep in metadata.entry_points(group=group):
        dist, version = _dist_of(ep)
        claims = found.setdefault(ep.name, [])
        if any(d == dist and e.value == ep.value for e, d, _ in claims):
            continue
        claims.append((ep, dist, version))
    return found


def _describe(obj: Any) -> str:
    if isinstance(obj, metadata.EntryPoint):
        return obj.value
    module = getattr(obj, "__module__", None) or type(obj).__module__
    qualname = getattr(obj, "__qualname__", None) or type(obj).__qualname__
    return f"{module}:{qualname}"


def entries(group: str) -> list[PluginEntry]:
    """Every plugin declared in ``group``, sorted by name, without importing any.

    A registered plugin hides an installed one of the same name, as :func:`load` does.
    """
    result: dict[str, PluginEntry] = {}
    for name, claims in _installed(group).items():
        ep, dist, version = claims[0]
        result[name] = PluginEntry(group, name, ep.value, dist, version)
        for other, other_dist, _ in claims[1:]:
            log.warning(
                "plugin %r in %s is declared twice: %s (%s) and %s (%s)",
                name, group, ep.value, dist or "?", other.value, other_dist or "?",
            )
    for name, obj in _registry.get(group, {}).items():
        result[name] = PluginEntry(group, name, _describe(obj), REGISTERED)
    return [result[name] for name in sorted(result)]


def available(group: str) -> dict[str, tuple[str, str]]:
    """``{name: (target, distribution)}`` for every plugin in ``group``; imports nothing."""
    return {e.name: (e.target, e.distribution) for e in entries(group)}


def register(group: str, name: str, obj: Any) -> None:
    """Add a plugin from inside the process, ahead of any installed one of that name.

    ``obj`` is the plugin itself, or a ``"module:attribute"`` string imported lazily on
    first :func:`load`, exactly like an installed entry point.
    """
    if isinstance(obj, str):
        obj = metadata.EntryPoint(name=name, value=obj, group=group)
    _registry.setdefault(group, {})[name] = obj


def unregister(group: str, name: str) -> None:
    """Remove a plugin added with :func:`register`; absent names are ignored."""
    _registry.get(group, {}).pop(name, None)


def load(group: str, name: str, expected_type: type | None = None) -> Any:
    """Import and return plugin ``name`` of ``group``.

    The plugin must be a subclass (when it is a class) or an instance of
    ``expected_type``, by default its group's contract (:data:`CONTRACTS`); otherwise
    :class:`PluginLoadError` is raised, so a wrong entry point fails at start-up with the
    plugin's name rather than later inside the relay.
    """
    registered = _registry.get(group, {})
    if name in registered:
        target = registered[name]
    else:
        installed = _installed(group)
        claims = installed.get(name, [])
        if not claims:
            raise PluginNotFoundError(_not_found_message(group, name, installed))
        if len(claims) > 1:
            who = ", ".join(f"{ep.value} from {dist or '?'}" for ep, dist, _ in claims)
            raise PluginConflictError(f"plugin {name!r} in {group} is declared twice: {who}")
        target = claims[0][0]
    obj = target
    if isinstance(target, metadata.EntryPoint):
        try:
            obj = target.load()
        except Exception as exc:
            raise _load_error(
                group, name, exc, f"cannot import {target.value}: {type(exc).__name__}: {exc}"
            ) from exc
    if expected_type is None:
        expected_type = contract(group)
    if expected_type is not None and not _conforms(obj, expected_type):
        kind = f"class {obj.__qualname__}" if isinstance(obj, type) else type(obj).__name__
        raise _load_error(
            group, name, None,
            f"{_describe(target)} is a {kind}, not a {expected_type.__qualname__}",
        )
    return obj


def contract(group: str) -> type | None:
    """The type plugins of ``group`` must be, or None for a group without a contract."""
    target = CONTRACTS.get(group)
    if target is None:
        return None
    module, _, qualname = target.partition(":")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj if isinstance(obj, type) else None


def _conforms(obj: Any, expected: type) -> bool:
    try:
        if isinstance(obj, type):
            return issubclass(obj, expected)
        return isinstance(obj, expected)
    except TypeError:  # e.g. a typing.Protocol that is not runtime-checkable
        return False


def _load_error(group: str, name: str, cause: BaseException | None, detail: str) -> PluginLoadError:
    err = PluginLoadError(f"plugin {name!r} in {group}: {detail}")
    err.plugin = name  # type: ignore[attr-defined]
    err.group = group  # type: ignore[attr-defined]
    err.cause = cause  # type: ignore[attr-defined]
    return err


def _not_found_message(group: str, name: str, installed: dict[str, Any]) -> str:
    """Why ``name`` was not found, from the very look-up that missed it: read again, the
    metadata could have changed in between (a reinstall rewrites it) and list ``name`` itself."""
    names = sorted({*installed, *_registry.get(group, {})})
    what = _WHAT.get(group, "plugin")
    if not names:
        return f"no {what} {name!r} in {group} (installed: none); {_INSTALL_HINT}"
    message = f"no {what} {name!r} in {group} (installed: {', '.join(names)})"
    close = [n for n in names if _typo_distance(name.lower(), n.lower()) <= _typo_limit(n)]
    if close:
        message += f"; did you mean {' or '.join(repr(n) for n in close)}?"
    return message


def _typo_limit(name: str) -> int:
    """Edits a typo of ``name`` may have: one for short names, two from eight letters."""
    return 1 if len(name) < 8 else 2


def _typo_distance(a: str, b: str) -> int:
    """Edits (insert, delete, replace, swap two neighbours) turning ``a`` into ``b``."""
    prev2: list[int] = []
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        row = [i] + [0] * len(b)
        for j, cb in enumerate(b, 1):
            row[j] = min(prev[j] + 1, row[j - 1] + 1, prev[j - 1] + (ca != cb))
            if i > 1 and j > 1 and ca == b[j - 2] and a[i - 2] == cb:
                row[j] = min(row[j], prev2[j - 2] + 1)
        prev2, prev = prev, row
    return prev[-1]
