"""The translation manager: loads translators and routes messages and samples to them.

Reads package metadata and imports translator plugins when built with
:meth:`TranslationManager.from_selection`; routing itself does no I/O.

Every translator declares what it consumes and produces (see
:mod:`edge_vis.kit.contract`). At start-up the manager checks that no JAUS message and no
subscribed topic is claimed twice (each must go to exactly one translator), and raises
:class:`~edge_vis.errors.PluginConflictError` naming both claimants otherwise. A message is
claimed by name and the translator's :class:`~edge_vis.kit.contract.Binding` for it (its
message set, the services of its sender): two translators may take one name when their
bindings cannot both match, and a message goes to the claim that matches it most closely. Several
translators may *publish* one topic (still images and ATR images are both image
products): a DDS topic has many writers, each keyed by its vehicle. The engine itself owns
the ``ControlRequest``, ``HandoffRequest`` and ``HandoffResponse`` topics (operator
arbitration).

A translator is a plugin, so it may fail: an exception from any hook, on either
direction, is caught here, counted per translator (:attr:`TranslationManager.errors`,
shown in the relay's totals as a loss) and logged a few times a minute at most; the
message or sample is dropped and the relay keeps running.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from edge_vis import plugins
from edge_vis.config import TranslatorSelection
from edge_vis.errors import ConfigError, PluginConflictError, PluginLoadError
from edge_vis.kit.actions import Action, Dropped
from edge_vis.kit.contract import Binding, ReportSpec, Translator, TranslatorContext
from edge_vis.routing.accounting import LogLimiter

log = logging.getLogger(__name__)

ENGINE = "engine"
#: Topics the engine reads itself.
ENGINE_SUBSCRIBES = ("ControlRequest", "HandoffRequest", "HandoffResponse")


class TranslationManager:
    """Routes JAUS messages and DDS samples to the translator that claims them."""

    def __init__(self, translators: Sequence[Translator]) -> None:
        self.translators = tuple(translators)
        self.by_message: dict[str, Translator] = {}
        #: message name -> (binding, translator) of every claim of it
        self.claims: dict[str, list[tuple[Binding, Translator]]] = {}
        self.by_topic: dict[str, Translator] = {}
        #: published topic -> the translators writing it (several may)
        self.publishers: dict[str, tuple[Translator, ...]] = {}
        #: translator name -> how many calls raised
        self.errors: Counter[str] = Counter()
        #: (translator name, reason) -> parts of messages it dropped (:class:`Dropped`)
        self.drops: Counter[tuple[str, str]] = Counter()
        self._log = LogLimiter(log)
        claims_sub: dict[str, str] = dict.fromkeys(ENGINE_SUBSCRIBES, ENGINE)
        for tr in self.translators:
            who = _name(tr)
            for message in tr.messages:
                binding = tr.bindings.get(message, Binding())
                for other_binding, other in self.claims.get(message, ()):
                    if other is not tr and binding.overlaps(other_binding):
                        raise PluginConflictError(
                            f"JAUS message {message!r} is claimed by both {_name(other)!r} "
                            f"and {who!r}" + _bound(other_binding, binding))
                self.claims.setdefault(message, []).append((binding, tr))
                self.by_message.setdefault(message, tr)
            for spec in tr.reports:
                if spec.report not in tr.messages:
                    raise PluginLoadError(
                        f"translator {who!r} wants report {spec.report} but does not list it "
                        f"in its messages"
                    )
            for topic in tr.subscribes:
                _claim(claims_sub, topic, who, "subscribed topic")
                self.by_topic[topic] = tr
            for topic in tr.publishes:
                writers = self.publishers.get(topic, ())
                if tr not in writers:
                    self.publishers[topic] = (*writers, tr)

    @classmethod
    def from_selection(cls, selection: TranslatorSelection,
                       options: Mapping[str, Any] | None = None) -> TranslationManager:
        """Load the installed translators that ``selection`` enables, sorted by name.

        A translator with a profile table (``options``, default ``selection.options``) gets
        it through its ``configure(table)`` method.
        """
        names = sorted(plugins.available(plugins.TRANSLATORS))
        for wanted in selection.enabled:
            if wanted != "*" and wanted not in names:
                # load() raises PluginNotFoundError listing what is installed
                plugins.load(plugins.TRANSLATORS, wanted, Translator)
        loaded: list[Translator] = []
        for name in names:
            if not selection.selects(name):
                log.info("translator %s disabled by profile", name)
                continue
            cls_ = plugins.load(plugins.TRANSLATORS, name, Translator)
            instance = cls_() if isinstance(cls_, type) else cls_
            if not instance.name:
                instance.name = name
            table = (options if options is not None else selection.options).get(name)
            if table is not None:
                instance.configure(table)  # raises ConfigError naming the bad keys
            loaded.append(instance)
        return cls(loaded)

    def verify(self, catalogue: Any, source: str = "") -> None:
        """Check what each translator's options name against ``catalogue`` (the relay's,
        with the profile's JSIDL); one ConfigError lists every problem of every one."""
        problems: list[tuple[str, str, str]] = []
        for tr in self.translators:
            try:
                tr.verify(catalogue, source)
            except ConfigError as exc:
                problems.extend(exc.problems)
        if problems:
            raise ConfigError(problems)

    # -- routing -----------------------------------------------------------------------

    def wanted_reports(self) -> list[tuple[Translator, ReportSpec]]:
        """Every report some translator wants, with its translator."""
        return [(tr, spec) for tr in self.translators for spec in tr.reports]

    def controlled_services(self) -> frozenset[str]:
        """Service URIs some translator commands."""
        return frozenset(uri for tr in self.translators for uri in tr.controlled_services)

    def handles(self, name: str) -> bool:
        """True when a translator consumes JAUS message ``name``."""
        return name in self.by_message

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        """Give a JAUS message to the translator whose claim matches it most closely (its
        message set, ``ctx.service_set``, and the services of its sender, ``ctx.source``);
        to each of them when several match equally (one component offering the services
        of two: its List Manager's reports concern both)."""
        out: list[Action] = []
        for tr in self.route(name, ctx):
            try:
                actions = list(tr.on_message(name, fields, ctx))
            except Exception as exc:
                self._failed(tr, f"JAUS {name}", exc, ctx)
                continue
            out += self._count_drops(tr, f"JAUS {name}", actions, ctx)
        return out

    def _count_drops(self, tr: Translator, what: str, actions: list[Action],
                     ctx: TranslatorContext) -> list[Action]:
        """Count and log what the translator dropped; pass the rest on."""
        if not any(isinstance(a, Dropped) for a in actions):
            return actions
        who = _name(tr)
        vehicle = ctx.vehicle.vehicle_id if ctx.vehicle is not None else "-"
        for action in actions:
            if isinstance(action, Dropped):
                self.drops[(who, action.reason)] += 1
                self._log.warning(f"drop {who} {action.reason}", ctx.now,
                                  "translator %s dropped part of %s from %s: %s%s", who, what,
                                  vehicle, action.reason,
                                  f" ({action.detail})" if action.detail else "")
        return [a for a in actions if not isinstance(a, Dropped)]

    def route(self, name: str, ctx: TranslatorContext) -> list[Translator]:
        """The translators a message ``name`` in ``ctx`` goes to: the claims matching it
        most closely (none: nobody takes it)."""
        claims = self.claims.get(name)
        if not claims:
            return []
        if len(claims) == 1 and not claims[0][0].specificity:
            return [claims[0][1]]
        services: tuple[str, ...] = ()
        if ctx.vehicle is not None and ctx.source is not None:
            services = tuple(uri for uri, _ in ctx.vehicle.components.get(ctx.source, ()))
        matching = [(b.specificity, tr) for b, tr in claims
                    if b.matches(ctx.service_set, services)]
        best = max((m[0] for m in matching), default=0)
        return [tr for specificity, tr in matching if specificity == best]

    def on_sample(self, topic: str, sample: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        """Give a DDS sample to the translator that subscribes to its topic."""
        tr = self.by_topic.get(topic)
        if tr is None:
            return []
        try:
            actions = list(tr.on_sample(topic, sample, ctx))
        except Exception as exc:
            return self._failed(tr, f"DDS {topic}", exc, ctx)
        return self._count_drops(tr, f"DDS {topic}", actions, ctx)

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        """Tell every translator that the vehicle in ``ctx`` changed."""
        out: list[Action] = []
        for tr in self.translators:
            try:
                out.extend(self._count_drops(tr, f"vehicle {change}",
                                             list(tr.on_vehicle(change, ctx)), ctx))
            except Exception as exc:
                self._failed(tr, f"vehicle {change}", exc, ctx)
        return out

    def _failed(self, tr: Translator, what: str, exc: Exception,
                ctx: TranslatorContext) -> list[Action]:
        who = _name(tr)
        self.errors[who] += 1
        vehicle = ctx.vehicle.vehicle_id if ctx.vehicle is not None else "-"
        self._log.warning(f"translator {who}", ctx.now,
                          "translator %s failed on %s from %s (dropped): %s: %s", who, what,
                          vehicle, type(exc).__name__, exc)
        return []

    def topics(self) -> tuple[Iterable[str], Iterable[str]]:
        """(published topics, subscribed topics) for the DDS bridge to create."""
        return tuple(self.publishers), (*ENGINE_SUBSCRIBES, *self.by_topic)


def _name(tr: Translator) -> str:
    return tr.name or type(tr).__name__


def _bound(a: Binding, b: Binding) -> str:
    if not a.specificity and not b.specificity:
        return ""
    return " (bind it to a message set or to the services sending it, without overlap)"


def _claim(claims: dict[str, str], key: str, who: str, what: str) -> None:
    other = claims.get(key)
    if other is not None and other != who:
        raise PluginConflictError(f"{what} {key!r} is claimed by both {other!r} and {who!r}")
    claims[key] = who
