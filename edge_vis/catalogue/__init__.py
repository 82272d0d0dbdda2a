"""The message catalogue: JAUS message definitions by code and name, and payload codecs.

Imports the built-in message sets and the ``edge_vis.messages`` entry points, and reads
the message sets the package ships as JSIDL (``edge_vis/data/jsidl/SET/*.xml``, one folder
per set, named after it: the ``uuv`` set); no other I/O.

A *payload* is what the AS5669A transport carries: the 2-byte little-endian message code
followed by the body. :meth:`Catalogue.decode` turns a payload into a :class:`Message`;
an unknown code is not an error (routing never needs to decode), the message just has
no ``name``/``fields`` and keeps its raw ``body``. Decoding errors of a known code raise
:class:`~edge_vis.errors.DecodeError` naming the code, field path and body offset.

Codes are unique in a catalogue: adding a different definition for a code that is taken
raises :class:`~edge_vis.errors.PluginConflictError` naming both sets and sources. The
same definition declared again (same name and wire layout, whatever its labels and
documentation say) is accepted once.
Names are not unique across sets — ``ExecuteList`` is 0x041E in mobility and 0x061E in
manipulator — so :meth:`Catalogue.by_name` returns the first one added unless a set is
named.

*Dialects* (:class:`~edge_vis.codec.types.Dialect`, a message set's ``DIALECTS``) are the
other published definitions of codes the catalogue holds: manipulator v1.0 beside v2.0,
the IOP readings of a few SAE messages. :meth:`Catalogue.decode` and
:meth:`Catalogue.encode` take the dialects a vehicle speaks (:meth:`Catalogue.recognise`
finds them from its services); a decoded message keeps the base definition's ``name``
(what translators and the engine know it by) and carries the dialect's ``definition``
and ``dialect``. A dialect's names are known to ``in`` and :meth:`Catalogue.by_name`.

Events (AS5710 ``Event``, 0x41F1) carry a complete report payload in a ``JausMessage``
field; :meth:`Catalogue.unwrap_event` and :meth:`Catalogue.wrap_event` find that field and
the event-id / sequence-number integers from the catalogue's own ``Event`` definition, by
type and order, rather than by field name.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from edge_vis import plugins
from edge_vis.codec.bodies import MessageCodec, compile_message
from edge_vis.codec.layout import check_message, wire_signature
from edge_vis.codec.types import Dialect, Enum, Int, JausMessage, MessageDef, Record
from edge_vis.errors import (
    DecodeError,
    EncodeError,
    PluginConflictError,
    PluginLoadError,
)

__all__ = [
    "Catalogue",
    "Dialects",
    "Message",
    "default_catalogue",
    "shipped_jsidl_sets",
    "unwrap_event",
    "wrap_event",
]

log = logging.getLogger(__name__)

#: name of the message whose JausMessage field carries event reports
EVENT = "Event"
#: the package holding the built-in sets; its ``BUILTIN_SETS`` names the modules
BUILTIN_PACKAGE = "edge_vis.jaus.messages"
#: the folder of the package holding the sets shipped as JSIDL, one sub-folder per set
SHIPPED_JSIDL = ("data", "jsidl")


@dataclass(frozen=True, slots=True)
class Message:
    """A payload as decoded by a catalogue.

    ``name``, ``fields`` and ``definition`` are None when the catalogue does not know
    ``code``; ``body`` is always the raw body (payload minus the 2-byte code).
    """

    code: int
    name: str | None
    fields: dict[str, Any] | None
    body: bytes
    definition: MessageDef | None = None
    #: the dialect whose definition decoded it ("" for the base definition)
    dialect: str = ""

    @property
    def payload(self) -> bytes:
        """The transport payload: 2-byte little-endian code + body."""
        return self.code.to_bytes(2, "little") + self.body


class Dialects(tuple[str, ...]):
    """The dialects a vehicle speaks (first preferred), and the codes it reads in the base
    definition even so: a code a dialect redefines but the vehicle carries in a service of
    the base definition's version (a manipulator v2.0 ``ManipulatorJointMotionProfile``
    beside v1.0 drivers sends the v2.0 motion profile). A plain tuple wherever names do."""

    base: frozenset[int]

    def __new__(cls, names: Iterable[str] = (), base: Iterable[int] = ()) -> Dialects:
        self = super().__new__(cls, tuple(names))
        self.base = frozenset(base)
        return self

    def __repr__(self) -> str:
        kept = ", ".join(f"0x{c:04X}" for c in sorted(self.base))
        return f"Dialects({tuple(self)!r}" + (f", base {kept})" if kept else ")")


@dataclass(frozen=True, slots=True)
class _EventLayout:
    """Where an Event definition keeps its event id, sequence number and report."""

    definition: MessageDef
    report: tuple[str, ...]
    event_id: tuple[str, ...] | None
    sequence: tuple[str, ...] | None


class Catalogue:
    """Message definitions keyed by code, with cached compiled codecs.

    Iterating yields the definitions in code order; ``len`` counts them; ``in`` accepts a
    code or a name.
    """

    def __init__(self, defs: Iterable[MessageDef] = (), *, source: str = "") -> None:
        self._defs: dict[int, MessageDef] = {}
        self._sources: dict[int, str] = {}
        self._names: dict[str, list[MessageDef]] = {}
        self._codecs: dict[int, MessageCodec] = {}
        self._event: _EventLayout | None = None
        #: dialect name -> code -> definition; the dialects' recognising services; names
        self._dialects: dict[str, dict[int, MessageDef]] = {}
        self._recognise: dict[str, tuple[tuple[str, str], ...]] = {}
        self._dialect_names: dict[str, tuple[str, int]] = {}
        self._dialect_codecs: dict[tuple[str, int], MessageCodec] = {}
        #: every code some dialect defines (the others never need a dialect look-up)
        self._dialect_codes: set[int] = set()
        if defs:
            self.add(defs, source=source)

    # -- building ------------------------------------------------------------------------

    def add(
        self, defs: Iterable[MessageDef], *, source: str = "", replace: bool = False
    ) -> None:
        """Add definitions; all or none.

        ``source`` names where they come from (module, plugin, file) for error messages.
        A definition that cannot work (e.g. more optional fields than presence-vector bits)
        raises PluginLoadError; a code already taken by a different definition raises
        PluginConflictError naming both, unless ``replace`` lets the new one win.
        """
        incoming: dict[int, MessageDef] = {}
        where = f" from {source}" if source else ""
        for defn in defs:
            if not isinstance(defn, MessageDef):
                raise PluginLoadError(
                    f"message set{where}: {defn!r} is a {type(defn).__name__}, not a MessageDef"
                )
            problems = check_message(defn)
            if problems:
                code = f"0x{defn.code:04X}" if isinstance(defn.code, int) else repr(defn.code)
                raise PluginLoadError(
                    f"message {defn.name} ({code}){where}: " + "; ".join(problems)
                )
            earlier = incoming.get(defn.code)
            if earlier is not None and not _same(earlier, defn):
                raise PluginConflictError(
                    f"message code 0x{defn.code:04X}: {_who(defn, source)} conflicts with "
                    f"{_who(earlier, source)}"
                )
            if earlier is None:
                incoming[defn.code] = defn
        if not replace:
            for number, defn in incoming.items():
                old = self._defs.get(number)
                if old is not None and not _same(old, defn):
                    raise PluginConflictError(
                        f"message code 0x{number:04X}: {_who(defn, source)} conflicts with "
                        f"{_who(old, self._sources[number])}"
                    )
        for number, defn in incoming.items():
            old = self._defs.get(number)
            if old is not None:
                if not replace or old is defn:
                    continue
                self._names[old.name].remove(old)
                if not self._names[old.name]:
                    del self._names[old.name]
                self._codecs.pop(number, None)
            self._defs[number] = defn
            self._sources[number] = source
            self._names.setdefault(defn.name, []).append(defn)
        self._event = None

    def add_dialect(self, dialect: Dialect, *, source: str = "") -> None:
        """Add (or extend) a dialect; all or none.

        Every code it defines must be in the catalogue already (a dialect is another
        definition of a known code); a broken definition raises PluginLoadError, a code the
        dialect already defines differently PluginConflictError.
        """
        where = f" from {source}" if source else ""
        if not dialect.name:
            raise PluginLoadError(f"dialect{where} has no name")
        known = self._dialects.get(dialect.name, {})
        incoming: dict[int, MessageDef] = {}
        for defn in dialect.messages:
            problems = check_message(defn)
            if problems:
                raise PluginLoadError(f"dialect {dialect.name} message {defn.name} "
                                      f"(0x{defn.code:04X}){where}: " + "; ".join(problems))
            if defn.code not in self._defs:
                raise PluginLoadError(f"dialect {dialect.name}{where}: 0x{defn.code:04X} "
                                      f"{defn.name} is not a code of the catalogue")
            earlier = known.get(defn.code) or incoming.get(defn.code)
            if earlier is not None and not _same(earlier, defn):
                raise PluginConflictError(
                    f"dialect {dialect.name}, message code 0x{defn.code:04X}: "
                    f"{_who(defn, source)} conflicts with {_who(earlier, '')}")
            incoming[defn.code] = defn
        for name, code in dialect.aliases:
            if code not in self._defs:
                raise PluginLoadError(f"dialect {dialect.name}{where}: alias {name} names "
                                      f"0x{code:04X}, not a code of the catalogue")
        self._dialects.setdefault(dialect.name, {}).update(incoming)
        self._dialect_codes.update(incoming)
        recognise = dict.fromkeys((*self._recognise.get(dialect.name, ()), *dialect.recognise))
        self._recognise[dialect.name] = tuple(recognise)
        for defn in incoming.values():
            if defn.name not in self._names:
                self._dialect_names.setdefault(defn.name, (dialect.name, defn.code))
        for name, code in dialect.aliases:
            if name not in self._names:
                self._dialect_names.setdefault(name, (dialect.name, code))

    def dialects(self) -> dict[str, tuple[MessageDef, ...]]:
        """Dialect name -> its definitions, in code order."""
        return {name: tuple(defs[c] for c in sorted(defs))
                for name, defs in self._dialects.items()}

    def recognise(self, services: Iterable[tuple[str, str]]) -> tuple[str, ...]:
        """The dialects a vehicle offering ``services`` (``(uri, version)``) speaks: those
        with a recognising ``(URI prefix, version prefix)`` that one of them matches."""
        pairs = tuple(services)
        return tuple(name for name, patterns in self._recognise.items()
                     if any(uri.startswith(prefix) and str(version).startswith(ver)
                            for prefix, ver in patterns for uri, version in pairs))

    def speaks(self, services: Iterable[tuple[str, str]]) -> Dialects:
        """The dialects a vehicle offering ``services`` speaks (:meth:`recognise`), with the
        codes it carries in a service (at its version) that the base definition names and
        the dialect's does not: those it reads in the base definition (where a newer version
        gave a message a service of its own, a vehicle offering that service answers it
        there, as that version defines it, even if an older service beside it also could)."""
        pairs = tuple(services)

        def majors(pairs: Iterable[tuple[str, str]]) -> set[tuple[str, str]]:
            return {(uri, str(version).split(".")[0]) for uri, version in pairs}

        offered = majors(pairs)
        names = self.recognise(pairs)
        base = {code for name in names for code, defn in self._dialects[name].items()
                if offered & (majors(self._defs[code].services) - majors(defn.services))}
        return Dialects(names, base)

    def definition(self, code: int, dialects: Iterable[str] = ()) -> MessageDef | None:
        """The definition of ``code`` a speaker of ``dialects`` uses (the base one unless a
        dialect defines the code; the first listed wins)."""
        if isinstance(dialects, Dialects) and code in dialects.base:
            return self._defs.get(code)
        for dialect in dialects:
            defn = self._dialects.get(dialect, {}).get(code)
            if defn is not None:
                return defn
        return self._defs.get(code)

    def canonical(self, name: str) -> str:
        """The base name of a message named ``name`` in a dialect (``name`` itself when it
        is a base name or unknown)."""
        found = self._dialect_names.get(name)
        if found is None:
            return name
        return self._defs[found[1]].name

    def copy(self) -> Catalogue:
        """An independent catalogue with the same definitions (compiled codecs shared)."""
        other = Catalogue()
        other._defs = dict(self._defs)
        other._sources = dict(self._sources)
        other._names = {name: list(defs) for name, defs in self._names.items()}
        other._codecs = dict(self._codecs)
        other._dialects = {name: dict(defs) for name, defs in self._dialects.items()}
        other._recognise = dict(self._recognise)
        other._dialect_names = dict(self._dialect_names)
        other._dialect_codecs = dict(self._dialect_codecs)
        other._dialect_codes = set(self._dialect_codes)
        return other

    # -- looking up ----------------------------------------------------------------------

    def get(self, code: int) -> MessageDef | None:
        """The definition of ``code``, or None."""
        return self._defs.get(code)

    def by_name(self, name: str, service_set: str | None = None) -> MessageDef:
        """The definition named ``name`` (first added, or the one of ``service_set``).

        Raises KeyError when there is none.
        """
        for defn in self._names.get(name, ()):
            if service_set is None or defn.service_set == service_set:
                return defn
        found = self._dialect_names.get(name)
        if found is not None:
            dialect, code = found
            defn = self._dialects[dialect].get(code) or self._defs[code]
            if service_set is None or defn.service_set == service_set:
                return defn
        in_set = f" in set {service_set!r}" if service_set else ""
        raise KeyError(f"no message named {name!r}{in_set}")

    def source(self, code: int) -> str:
        """Where the definition of ``code`` came from ('' if unknown or not given)."""
        return self._sources.get(code, "")

    def sets(self) -> dict[str, int]:
        """Number of definitions per service set, in the order the sets were added."""
        counts: dict[str, int] = {}
        for defn in self._defs.values():
            counts[defn.service_set] = counts.get(defn.service_set, 0) + 1
        return counts

    def __iter__(self) -> Iterator[MessageDef]:
        return iter([self._defs[code] for code in sorted(self._defs)])

    def __len__(self) -> int:
        return len(self._defs)

    def __contains__(self, key: object) -> bool:
        if isinstance(key, int):
            return key in self._defs
        return key in self._names or key in self._dialect_names

    def __repr__(self) -> str:
        sets = ", ".join(f"{name} {n}" for name, n in self.sets().items())
        return f"<Catalogue of {len(self)} messages: {sets}>"

    # -- coding --------------------------------------------------------------------------

    def codec(self, code: int) -> MessageCodec:
        """The compiled codec of ``code`` (KeyError if unknown)."""
        codec = self._codecs.get(code)
        if codec is None:
            codec = self._codecs[code] = compile_message(self._defs[code])
        return codec

    def _dialect_codec(self, code: int, dialects: Iterable[str]) -> tuple[str, MessageCodec]:
        """(dialect, codec) of the first of ``dialects`` defining ``code``; KeyError when
        none does (or ``dialects`` keep the base definition of ``code``)."""
        if isinstance(dialects, Dialects) and code in dialects.base:
            raise KeyError(code)
        for dialect in dialects:
            defn = self._dialects.get(dialect, {}).get(code)
            if defn is not None:
                key = (dialect, code)
                codec = self._dialect_codecs.get(key)
                if codec is None:
                    codec = self._dialect_codecs[key] = compile_message(defn)
                return dialect, codec
        raise KeyError(code)

    def decode(self, payload: bytes, dialects: Iterable[str] = ()) -> Message:
        """Decode a payload (2-byte code + body), as a speaker of ``dialects`` sends it.

        An unknown code gives a Message with ``name``/``fields``/``definition`` None.
        Raises DecodeError for a payload shorter than 2 bytes or a body that does not
        match its known definition. A code a dialect defines keeps the base ``name``.
        """
        if len(payload) < 2:
            raise DecodeError(
                f"payload of {len(payload)} bytes has no 2-byte message code", offset=0
            )
        code = payload[0] | payload[1] << 8
        body = bytes(payload[2:])
        if dialects and code in self._dialect_codes:
            try:
                dialect, variant = self._dialect_codec(code, dialects)
            except KeyError:
                pass
            else:
                return Message(code, self._defs[code].name, variant.decode(body), body,
                               variant.definition, dialect)
        codec = self._codecs.get(code)
        if codec is None:
            if code not in self._defs:
                return Message(code, None, None, body, None)
            codec = self.codec(code)
        defn = codec.definition
        return Message(code, defn.name, codec.decode(body), body, defn)

    def encode(self, name_or_code: str | int, fields: Mapping[str, Any],
               dialects: Iterable[str] = ()) -> bytes:
        """Encode ``fields`` as the named (or numbered) message, as a speaker of
        ``dialects`` reads it (a dialect's own name picks that dialect); returns the
        payload.

        Raises EncodeError for an unknown message or a value the definition cannot carry.
        """
        if isinstance(name_or_code, str) and name_or_code not in self._names and \
                name_or_code in self._dialect_names:
            dialects = (self._dialect_names[name_or_code][0], *dialects)
        defn = self._resolve(name_or_code)
        prefix = defn.code.to_bytes(2, "little")
        if dialects and defn.code in self._dialect_codes:
            try:
                _dialect, variant = self._dialect_codec(defn.code, dialects)
            except KeyError:
                pass
            else:
                return prefix + variant.encode(fields)
        return prefix + self.codec(defn.code).encode(fields)

    def _resolve(self, name_or_code: str | int) -> MessageDef:
        if isinstance(name_or_code, int):
            defn = self._defs.get(name_or_code)
            if defn is None:
                raise EncodeError(f"no message 0x{name_or_code:04X} in the catalogue")
            return defn
        found = self._dialect_names.get(name_or_code)
        if found is not None and name_or_code not in self._names:
            return self._defs[found[1]]
        try:
            return self.by_name(name_or_code)
        except KeyError:
            raise EncodeError(f"no message named {name_or_code!r} in the catalogue") from None

    # -- events --------------------------------------------------------------------------

    def _event_layout(self) -> _EventLayout:
        defs = self._names.get(EVENT)
        if not defs:
            raise KeyError(f"the catalogue has no {EVENT!r} message")
        defn = defs[0]
        layout = self._event
        if layout is None or layout.definition is not defn:
            layout = self._event = _find_event_layout(defn)
        return layout

    def unwrap_event(self, message: Message, dialects: Iterable[str] = ()) -> Message:
        """The report carried inside an Event message, decoded by this catalogue.

        ``message`` may be decoded or raw (fields None). An unknown report code gives a
        raw Message; a report that does not decode raises DecodeError naming the
        report's code. ValueError if ``message`` is not an Event.
        """
        layout = self._event_layout()
        defn = layout.definition
        if message.code != defn.code:
            raise ValueError(f"message 0x{message.code:04X} is not an {EVENT} (0x{defn.code:04X})")
        fields = message.fields
        if fields is None or message.definition is not defn:
            fields = self.codec(defn.code).decode(message.body)
        report = _get_path(fields, layout.report)
        try:
            return self.decode(report, dialects)
        except DecodeError as exc:
            raise DecodeError(
                f"{exc.reason} (report inside {EVENT})",
                code=exc.code,
                path=exc.path,
                offset=exc.offset,
            ) from None

    def wrap_event(self, event_id: int, sequence: int, report_payload: bytes) -> bytes:
        """The payload of an Event message carrying ``report_payload`` (code + body)."""
        layout = self._event_layout()
        if layout.event_id is None or layout.sequence is None:
            raise EncodeError(
                f"the {EVENT} definition has no event id and sequence number integers",
                code=layout.definition.code,
            )
        fields: dict[str, Any] = {}
        _set_path(fields, layout.event_id, event_id)
        _set_path(fields, layout.sequence, sequence)
        _set_path(fields, layout.report, bytes(report_payload))
        return self.encode(layout.definition.code, fields)


def _same(a: MessageDef, b: MessageDef) -> bool:
    """Same code, name and wire layout (documentation such as labels may differ)."""
    if a is b:
        return True
    if a.code != b.code or a.name != b.name:
        return False
    return a.body == b.body or wire_signature(a.body) == wire_signature(b.body)


def _who(defn: MessageDef, source: str) -> str:
    where = f", {source}" if source else ""
    return f"{defn.name} (set {defn.service_set}{where})"


def _find_event_layout(defn: MessageDef) -> _EventLayout:
    """Locate the JausMessage field and the integers before it in an Event definition."""
    report: tuple[str, ...] | None = None
    integers: list[tuple[str, ...]] = []

    def walk(rec: Record, prefix: tuple[str, ...]) -> None:
        nonlocal report
        for fld in rec.fields:
            if report is not None:
                return
            path = (*prefix, fld.name)
            if isinstance(fld.type, JausMessage) and not fld.optional:
                report = path
            elif isinstance(fld.type, Int | Enum) and not fld.optional:
                integers.append(path)
            elif isinstance(fld.type, Record) and fld.type.pv is None and not fld.optional:
                walk(fld.type, path)

    walk(defn.body, ())
    if report is None:
        raise KeyError(f"the {EVENT} definition (0x{defn.code:04X}) has no JausMessage field")
    event_id = integers[0] if len(integers) >= 1 else None
    sequence = integers[1] if len(integers) >= 2 else None
    return _EventLayout(defn, report, event_id, sequence)


def _get_path(fields: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    value: Any = fields
    for key in path:
        value = value[key]
    return value


def _set_path(fields: dict[str, Any], path: tuple[str, ...], value: Any) -> None:
    for key in path[:-1]:
        fields = fields.setdefault(key, {})
    fields[path[-1]] = value


# -- the default catalogue -----------------------------------------------------------------


def _builtin_modules() -> list[str]:
    try:
        package = importlib.import_module(BUILTIN_PACKAGE)
    except ModuleNotFoundError as exc:
        if exc.name is not None and BUILTIN_PACKAGE.startswith(exc.name):
            log.warning("no built-in message sets (%s is missing)", BUILTIN_PACKAGE)
            return []
        raise PluginLoadError(f"cannot import {BUILTIN_PACKAGE}: {exc}") from exc
    names = getattr(package, "BUILTIN_SETS", ())
    if not names:
        log.warning("no built-in message sets (%s.BUILTIN_SETS is empty)", BUILTIN_PACKAGE)
    return [f"{BUILTIN_PACKAGE}.{name}" for name in names]


def _plugin_defs(name: str) -> tuple[MessageDef, ...]:
    obj = plugins.load(plugins.MESSAGES, name)
    defs = getattr(obj, "MESSAGES", obj)
    if not isinstance(defs, list | tuple) or not all(isinstance(d, MessageDef) for d in defs):
        raise PluginLoadError(
            f"plugin {name!r} in {plugins.MESSAGES}: expected a tuple of MessageDef, "
            f"got {type(defs).__name__}"
        )
    return tuple(defs)


def shipped_jsidl_sets() -> dict[str, Path]:
    """The message sets shipped as JSIDL: set name -> its folder (sorted by name)."""
    root = Path(str(resources.files("edge_vis").joinpath(*SHIPPED_JSIDL)))
    if not root.is_dir():
        return {}
    return {d.name: d for d in sorted(root.iterdir()) if d.is_dir()}


@cache
def default_catalogue() -> Catalogue:
    """The built-in sets, the sets shipped as JSIDL and every ``edge_vis.messages`` plugin,
    built once and cached.

    Raises PluginLoadError naming a set or plugin that fails to import or holds a broken
    definition, PluginConflictError when two of them claim one code differently.
    """
    cat = Catalogue()
    for module_name in _builtin_modules():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                log.warning("built-in message set %s is missing", module_name)
                continue
            raise PluginLoadError(f"cannot import message set {module_name}: {exc}") from exc
        except Exception as exc:  # a broken set must name itself, not crash anonymously
            raise PluginLoadError(f"cannot import message set {module_name}: {exc}") from exc
        defs = getattr(module, "MESSAGES", None)
        if defs is None:
            raise PluginLoadError(f"message set {module_name} has no MESSAGES")
        cat.add(defs, source=module_name)
        for dialect in getattr(module, "DIALECTS", ()):
            cat.add_dialect(dialect, source=module_name)
    from edge_vis.catalogue.jsidl import load_jsidl

    for set_name, folder in shipped_jsidl_sets().items():
        cat.add(load_jsidl(folder, service_set=set_name), source=f"shipped JSIDL {set_name}")
    for entry in plugins.entries(plugins.MESSAGES):
        source = f"plugin {entry.name} ({entry.target})"
        cat.add(_plugin_defs(entry.name), source=source)
    log.debug("default catalogue: %r", cat)
    return cat


def unwrap_event(message: Message, catalogue: Catalogue | None = None) -> Message:
    """The report inside an Event message (see :meth:`Catalogue.unwrap_event`)."""
    cat = catalogue if catalogue is not None else default_catalogue()
    return cat.unwrap_event(message)


def wrap_event(
    event_id: int, sequence: int, report_payload: bytes, catalogue: Catalogue | None = None
) -> bytes:
    """An Event payload carrying ``report_payload`` (see :meth:`Catalogue.wrap_event`)."""
    cat = catalogue if catalogue is not None else default_catalogue()
    return cat.wrap_event(event_id, sequence, report_payload)
