"""Reloading the deployment profile while the relay runs (SIGHUP).

:func:`diff_profiles` is pure: it compares two :class:`~edge_vis.config.RelayProfile` values
and says, setting by setting, what changed and whether the running relay can take it.
:class:`Reloader` reads the profile again (through the loader it is given, the only I/O),
applies what can change safely, logs one line per change and remembers what needs a
restart, so ``systemctl status`` can show it.

What can change without a restart:

* timing the engine reads each time it uses it (``discovery.*``), the relay ``name``;
* forwarding between links (``routing.forward``): the router's switches change at once
  (between links that are open; a link added to the profile needs a restart first);
* report rates, event/command/control timing, authority and vehicle profiles, which the
  engine captures when it sets a vehicle up: :meth:`Runtime.apply_profile` hands them to
  :meth:`Engine.apply_profile`, which re-requests events whose rate changed (no vehicle
  is dropped) and applies the rest from the next request. A vehicle profile that would
  rename a running vehicle is refused and logged as needing a restart.

What needs a restart: the relay's JAUS id, links (opened once; a vehicle behind a link
would be dropped), the DDS domain and partitions (writers and readers), the translator
selection (translators own DDS topics) and extra JSIDL files (the catalogue). The running
relay keeps the old values of these, so the next reload reports them again until the
restart.

A profile that does not validate changes nothing: every problem is logged and the relay
runs on with the profile it has.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from edge_vis.config import RelayProfile
from edge_vis.errors import ConfigError

log = logging.getLogger(__name__)

#: the change is in effect now
APPLIED = "applied"
#: the change holds for what is set up from now on; running vehicles keep the old value
DEFERRED = "deferred"
#: the running relay keeps the old value until it is restarted
RESTART = "restart"

#: top-level settings the running relay cannot change, and why
RESTART_ONLY: Mapping[str, str] = {
    "jaus_id": "the relay's JAUS id is its identity on every link",
    "links": "links are opened once at start",
    "dds": "DDS writers and readers are created at start",
    "translators": "translators own DDS topics created at start",
    "jsidl": "the message catalogue is built at start",
}
#: settings the engine reads each time it uses them, and the router's forwarding
LIVE = frozenset({"name", "discovery", "serving", "routing"})
#: leaves of a live section that still need a restart
RESTART_LEAVES: Mapping[str, str] = {
    "serving.relay_name": "the relay's name is its identity among the relays on DDS",
}
#: settings the engine captures per vehicle, subscription, control or command slot
CAPTURED = frozenset({"authority", "control", "events", "commands", "report_rates",
                      "vehicles"})
#: not settings
IGNORED = frozenset({"source"})


@dataclass(frozen=True, slots=True)
class Change:
    """One changed setting: dotted ``key``, old and new value, and what happened to it."""

    key: str
    old: Any
    new: Any
    outcome: str
    why: str = ""

    @property
    def top(self) -> str:
        """The top-level profile setting (``links`` for ``links.radio.url``)."""
        return self.key.split(".", 1)[0].split("[", 1)[0]

    def describe(self) -> str:
        """``report_rates.ReportGlobalPose: 5.0 -> 2.0``."""
        return f"{self.key}: {_show(self.old)} -> {_show(self.new)}"


@dataclass(frozen=True, slots=True)
class ReloadResult:
    """Every change found by one reload, and the profile now in force."""

    changes: tuple[Change, ...]
    profile: RelayProfile

    def by_outcome(self, outcome: str) -> tuple[Change, ...]:
        """The changes with ``outcome``."""
        return tuple(c for c in self.changes if c.outcome == outcome)

    @property
    def restart_needed(self) -> tuple[str, ...]:
        """Top-level settings waiting for a restart, in profile order."""
        return tuple(dict.fromkeys(c.top for c in self.by_outcome(RESTART)))

    def summary(self) -> str:
        """One line: counts per outcome."""
        if not self.changes:
            return "no changes"
        parts = [f"{len(self.by_outcome(APPLIED))} applied"]
        if self.by_outcome(DEFERRED):
            parts.append(f"{len(self.by_outcome(DEFERRED))} deferred to new set-ups")
        if self.by_outcome(RESTART):
            parts.append(f"{len(self.by_outcome(RESTART))} need a restart "
                         f"({', '.join(self.restart_needed)})")
        return ", ".join(parts)


# -- the pure part ------------------------------------------------------------------------


def diff_profiles(old: RelayProfile, new: RelayProfile, *,
                  engine_applies: bool = True) -> list[Change]:
    """Every setting that differs between ``old`` and ``new``, classified.

    ``engine_applies`` says the engine applies captured settings (report rates, vehicle
    profiles, ...) to running vehicles (:meth:`Engine.apply_profile`); without it they
    are :data:`DEFERRED` to what is set up later.
    """
    changes: list[Change] = []
    for fld in dataclasses.fields(RelayProfile):
        name = fld.name
        if name in IGNORED:
            continue
        before, after = getattr(old, name), getattr(new, name)
        if before == after:
            continue
        if name in RESTART_ONLY:
            outcome, why = RESTART, RESTART_ONLY[name]
        elif name in LIVE:
            outcome, why = APPLIED, ""
        elif name in CAPTURED:
            outcome, why = ((APPLIED, "") if engine_applies else
                            (DEFERRED, "running vehicles keep the old value until they are "
                                       "set up again"))
        else:  # a setting added to the profile later: never guess that it is safe
            outcome, why = RESTART, "not known to be changeable at run time"
        for key, b, a in _leaf_changes(name, before, after):
            if key in RESTART_LEAVES:
                changes.append(Change(key, b, a, RESTART, RESTART_LEAVES[key]))
                continue
            changes.append(Change(key, b, a, outcome, why))
    return changes


def effective_profile(old: RelayProfile, new: RelayProfile) -> RelayProfile:
    """``new`` with every restart-only setting kept as the running relay has it."""
    keep = {name: getattr(old, name) for name in RESTART_ONLY}
    known = LIVE | CAPTURED | IGNORED | set(RESTART_ONLY)
    for fld in dataclasses.fields(RelayProfile):
        if fld.name not in known:
            keep[fld.name] = getattr(old, fld.name)
    keep["serving"] = dataclasses.replace(new.serving, relay_name=old.serving.relay_name)
    return dataclasses.replace(new, **keep)


def _leaf_changes(key: str, before: Any, after: Any) -> list[tuple[str, Any, Any]]:
    """Break a changed value down to the smallest keys that differ."""
    if _is_section(before) and type(before) is type(after):
        out: list[tuple[str, Any, Any]] = []
        for fld in dataclasses.fields(before):
            b, a = getattr(before, fld.name), getattr(after, fld.name)
            if b != a and fld.name != "source":
                out.extend(_leaf_changes(f"{key}.{fld.name}", b, a))
        return out or [(key, before, after)]
    if isinstance(before, Mapping) and isinstance(after, Mapping):
        out = []
        for name in dict.fromkeys([*before, *after]):
            b, a = before.get(name), after.get(name)
            if b != a:
                out.extend(_leaf_changes(f"{key}.{name}", b, a))
        return out
    if isinstance(before, tuple) and isinstance(after, tuple):
        named_b, named_a = _by_name(before), _by_name(after)
        if named_b is not None and named_a is not None:
            out = []
            for name in dict.fromkeys([*named_b, *named_a]):
                b, a = named_b.get(name), named_a.get(name)
                if b != a:
                    out.extend(_leaf_changes(f"{key}.{name}", b, a))
            return out
    return [(key, before, after)]


def _is_section(value: Any) -> bool:
    """A profile section (DiscoveryProfile, LinkProfile, ...), not a value like an address."""
    return dataclasses.is_dataclass(value) and type(value).__module__ == RelayProfile.__module__


def _by_name(items: tuple[Any, ...]) -> dict[str, Any] | None:
    """Links by name, vehicles by vehicle_id; None for other tuples."""
    out: dict[str, Any] = {}
    for item in items:
        name = getattr(item, "vehicle_id", None) or getattr(item, "name", None)
        if not isinstance(name, str) or not _is_section(item) or name in out:
            return None
        out[name] = item
    return out


def _show(value: Any) -> str:
    if value is None:
        return "(none)"
    if _is_section(value):
        if hasattr(value, "url"):
            return repr(value.url)
        return type(value).__name__
    if isinstance(value, tuple):
        return "[" + ", ".join(str(v) for v in value) + "]"
    return repr(value) if isinstance(value, str) else str(value)


# -- applying it ------------------------------------------------------------------------


class Reloader:
    """Re-reads the profile with ``load`` and applies it to a running
    :class:`~edge_vis.shell.relay.Runtime` (anything with ``profile`` and ``apply_profile``).

    ``load`` returns the validated profile with the command line's overrides applied
    (the same function that built the profile at start). ``on_done`` is called after every
    reload attempt (e.g. to refresh the service status).
    """

    def __init__(self, runtime: Any, load: Callable[[], RelayProfile],
                 on_done: Callable[[ReloadResult | None], None] | None = None) -> None:
        self.runtime = runtime
        self._load = load
        self._on_done = on_done
        self.restart_needed: tuple[str, ...] = ()
        self.reloads = 0
        self.failures = 0

    def reload(self) -> ReloadResult | None:
        """Read and apply the profile; None (and nothing changed) if it does not validate."""
        source = self.runtime.profile.source or "the profile"
        log.info("reload: reading %s", source)
        try:
            new = self._load()
        except ConfigError as exc:
            self.failures += 1
            log.error("reload: %s has %d problem(s); keeping the running profile",
                      source, len(exc.problems))
            for file, key, message in exc.problems:
                where = ": ".join(part for part in (file, key) if part)
                log.error("reload: %s", f"{where}: {message}" if where else message)
            self._finish(None)
            return None
        result = self.apply(new)
        self._finish(result)
        return result

    def apply(self, new: RelayProfile) -> ReloadResult:
        """Apply ``new`` to the runtime; log and return what changed."""
        runtime = self.runtime
        old: RelayProfile = runtime.profile
        changes = diff_profiles(old, new)
        profile = effective_profile(old, new)
        not_applied = runtime.apply_profile(profile) if changes else []
        self.reloads += 1
        result = ReloadResult(tuple(changes), profile)
        self.restart_needed = result.restart_needed
        for change in changes:
            if change.outcome == APPLIED:
                log.info("reload: applied %s", change.describe())
            elif change.outcome == DEFERRED:
                log.info("reload: deferred %s (%s)", change.describe(), change.why)
            else:
                log.warning("reload: needs a restart: %s (%s)", change.describe(), change.why)
        for note in not_applied:
            log.warning("reload: needs a restart: %s", note)
        log.info("reload of %s done: %s", profile.source or "the profile", result.summary())
        return result

    def _finish(self, result: ReloadResult | None) -> None:
        if self._on_done is not None:
            self._on_done(result)


__all__ = [
    "APPLIED",
    "DEFERRED",
    "RESTART",
    "Change",
    "ReloadResult",
    "Reloader",
    "diff_profiles",
    "effective_profile",
]
