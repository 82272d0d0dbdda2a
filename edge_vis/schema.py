"""The validation kit: dataclasses are the schema, one reader builds them from TOML. No I/O.

Deployment, vehicle, link and simulation profiles, a link's URL options and a
translator's options table are each described by a frozen dataclass. Its fields say all
the reader needs, once: the type (``bool``, ``int``, ``float``, ``str``, ``Path``,
``JausAddress``, ``Literal`` or ``Enum`` choices, nested dataclasses, tuples, mappings,
``X | None``), the default (on the field, nowhere else) and, in :func:`setting`
metadata, the TOML key when it differs, the range of a number, its unit, what a missing
required key means and any further check on a value::

    @dataclass(frozen=True, slots=True)
    class CommandProfile:
        rate: float = setting(10.0, gt=0, unit="Hz")

    read_table(CommandProfile, {"rate": -1}, file="site.toml", path="commands")
    # ConfigError: site.toml: commands.rate: must be a positive number, got -1.0 Hz

:class:`Reader` walks a parsed table against such a dataclass and records every problem
as ``(file, key path, reason)`` instead of raising, so one run names every mistake; the
caller raises them together as one :class:`~edge_vis.errors.ConfigError`. Keys the
dataclass does not declare are reported (a typo must not be silently ignored).

A dataclass may also declare:

* ``validate(self) -> Iterable[tuple[str, str]]``: checks across fields, as
  ``(key relative to the table, reason)``; a problem at a key whose value was already
  refused is dropped (it would be about the default standing in for it);
* ``toml_shorthand: ClassVar[str]``: a bare value stands for a table holding only that
  key (``ReportGlobalPose = 5.0`` for ``ReportGlobalPose = {desired = 5.0}``).

A tuple or mapping with one bad element is refused whole (each bad element named), so
checks across its elements never see shifted indexes.

*Text mode* reads tables whose values are strings (URL query options): numbers and
booleans are parsed from their text, an array is a comma-separated list, and an empty
value counts as absent.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import MISSING, dataclass
from functools import cache
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress

T = TypeVar("T")
Problem = tuple[str, str, str]
"""``(file, key path, reason)``, as :class:`~edge_vis.errors.ConfigError` carries them."""

#: key of the :class:`Setting` in a dataclass field's metadata
METADATA_KEY = "edge_vis.schema"

#: words a text-mode boolean may be written as
TRUE_WORDS = frozenset({"1", "true", "yes", "on"})
FALSE_WORDS = frozenset({"0", "false", "no", "off"})


@dataclass(frozen=True, slots=True)
class Setting:
    """What a field's metadata adds to its type and default (see :func:`setting`)."""

    key: str | None = None
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    unit: str = ""
    doc: str = ""
    check: Callable[[Any], str | None] | None = None
    choices: tuple[Any, ...] | None = None
    keys: tuple[str, ...] | None = None
    read_as: Any = None
    convert: Callable[[Any], Any] | None = None
    merge: bool = False
    rest: bool = False
    toml: bool = True
    custom: bool = False


_PLAIN = Setting()


def setting(default: Any = MISSING, *, factory: Any = MISSING, key: str | None = None,
            ge: float | None = None, gt: float | None = None, le: float | None = None,
            lt: float | None = None, unit: str = "", doc: str = "",
            check: Callable[[Any], str | None] | None = None,
            choices: Iterable[Any] | None = None, keys: Iterable[str] | None = None,
            read_as: Any = None, convert: Callable[[Any], Any] | None = None,
            merge: bool = False, rest: bool = False, toml: bool = True,
            custom: bool = False) -> Any:
    """A dataclass field with its schema; without ``default``/``factory`` it is required.

    * ``key``: the TOML key when it is not the field name; dotted for a key of a
      sub-table (``"relay.jaus_id"``);
    * ``ge``/``gt``/``le``/``lt``: bounds of a number (of every number in a tuple or
      mapping); ``unit`` is shown in messages; ``doc`` says what a missing required key
      is for;
    * ``check(value) -> reason | None``: a further check of each scalar value;
      ``choices``: the values allowed; ``keys``: the keys a mapping may have;
    * ``read_as``: the type read from TOML when it differs from the field's, turned into
      the field's value by ``convert`` (which raises ValueError with a reason);
    * ``merge``: a mapping given in TOML updates the default instead of replacing it;
    * ``rest``: a mapping of every key of the table that no other field takes;
    * ``toml=False``: not read from the file (set by the program); ``custom=True``: a
      key of the file that the caller reads itself.
    """
    meta = {METADATA_KEY: Setting(
        key, ge, gt, le, lt, unit, doc, check,
        tuple(choices) if choices is not None else None,
        tuple(keys) if keys is not None else None,
        read_as, convert, merge, rest, toml, custom)}
    return dataclasses.field(default=default, default_factory=factory, metadata=meta)


def setting_of(f: dataclasses.Field[Any]) -> Setting:
    """The :class:`Setting` of a dataclass field (a plain one when it has none)."""
    found = f.metadata.get(METADATA_KEY)
    return found if isinstance(found, Setting) else _PLAIN


def toml_keys(cls: type) -> frozenset[str]:
    """The top-level keys a table read as dataclass ``cls`` may hold."""
    out = set()
    for f in dataclasses.fields(cls):
        s = setting_of(f)
        if s.toml and not s.rest:
            out.add((s.key or f.name).split(".", 1)[0])
    return frozenset(out)


#: scalar types read from a TOML value of another type: (TOML type, parser raising ValueError)
_PARSED: Mapping[type, tuple[type, Callable[[Any], Any]]] = {
    JausAddress: (str, JausAddress.parse),
    Path: (str, Path),
}

_INVALID: Any = object()
_MISSING: Any = MISSING


class Reader:
    """Builds dataclasses from parsed tables of one file, collecting problems.

    ``base_dir`` resolves relative :class:`~pathlib.Path` values (joining only; nothing is
    read). ``text``: values are strings, as in a URL query. ``unknown`` is the reason
    given for an undeclared key; ``list_known`` adds the declared ones.
    """

    def __init__(self, file: str = "", *, base_dir: Path | None = None, text: bool = False,
                 problems: list[Problem] | None = None, unknown: str = "unknown key",
                 list_known: bool = False) -> None:
        self.file = file
        self.base_dir = base_dir
        self.text = text
        self.problems: list[Problem] = problems if problems is not None else []
        self.unknown = unknown
        self.list_known = list_known

    def for_file(self, file: str, base_dir: Path | None = None) -> Reader:
        """A reader of another file (one a profile references) sharing these problems."""
        return Reader(file, base_dir=base_dir, text=self.text, problems=self.problems,
                      unknown=self.unknown, list_known=self.list_known)

    def problem(self, path: str, reason: str) -> None:
        """Record a problem at key ``path`` of this reader's file."""
        self.problems.append((self.file, path, reason))

    def raise_problems(self) -> None:
        """Raise every problem recorded so far as one ConfigError (nothing if none)."""
        if self.problems:
            raise ConfigError(list(self.problems))

    # -- tables ----------------------------------------------------------------------------

    def read(self, cls: type[T], data: Any, path: str = "", *, base: Any = None,
             values: Mapping[str, Any] | None = None, handled: Iterable[str] = ()) -> T | None:
        """Build ``cls`` from table ``data`` found at key ``path``; None if impossible.

        ``base``: an instance whose values stand for the keys the table leaves out (a
        link profile file under a link's own keys). ``values``: fields set by the caller.
        ``handled``: keys of the table the caller reads itself (not reported as unknown).
        Invalid values are recorded and left at their default, so the result can still be
        used to look for further problems; None when a required key is missing or bad.
        """
        if not isinstance(data, Mapping):
            self.problem(path, f"expected {_table_name(cls)}")
            return None
        schema: Any = cls  # a dataclass (type variables cannot say so)
        hints = _hints(schema)
        kwargs: dict[str, Any] = dict(values or {})
        known: dict[str, set[str]] = {"": set(handled)}
        bad_sections: set[str] = set()
        failed = False
        invalid: list[str] = []
        rest: list[dataclasses.Field[Any]] = []
        for f in dataclasses.fields(schema):
            s = setting_of(f)
            if not s.toml:
                continue
            if s.rest:
                rest.append(f)
                continue
            key = s.key or f.name
            section, _, leaf = key.rpartition(".")
            _declare(known, section, leaf)
            if s.custom or f.name in kwargs:
                continue
            table = self._section(data, section, path, bad_sections)
            raw = table.get(leaf, _MISSING) if table is not None else _MISSING
            if self.text and raw == "":
                raw = _MISSING
            required = f.default is MISSING and f.default_factory is MISSING
            if raw is _MISSING:
                if required and base is None:
                    self.problem(_join(path, key), f"missing: {s.doc}" if s.doc else "missing")
                    failed = True
                continue
            current = getattr(base, f.name) if base is not None else _default(f)
            value = self._value(hints[f.name], raw, _join(path, key), s, current)
            if value is _INVALID:
                failed = failed or (required and base is None)
                invalid.append(key)
                continue
            kwargs[f.name] = value
        for f in rest:  # after every other field has taken its key
            extra = {k: v for k, v in data.items() if k not in known[""]}
            _declare(known, "", *extra)
            value = self._value(hints[f.name], extra, path, setting_of(f), _default(f))
            if value is _INVALID:
                invalid.append(f.name)
            else:
                kwargs[f.name] = value
        self._unknown(data, known, path, bad_sections)
        if failed:
            return None
        obj: T = dataclasses.replace(base, **kwargs) if base is not None else schema(**kwargs)
        for key, reason in getattr(obj, "validate", _no_checks)():
            if not any(_related(key, bad) for bad in invalid):  # said already
                self.problem(_join(path, key), reason)
        return obj

    def take(self, data: Mapping[str, Any], key: str, hint: Any, path: str = "",
             default: Any = None, spec: Setting = _PLAIN) -> Any:
        """Read one ``key`` of ``data`` as type ``hint`` (``default`` if absent or bad).

        For keys a caller reads itself (see ``handled`` and ``custom``).
        """
        if key not in data:
            return default
        value = self._value(hint, data[key], _join(path, key), spec, _MISSING)
        return default if value is _INVALID else value

    def _section(self, data: Mapping[str, Any], section: str, path: str,
                 bad: set[str]) -> Mapping[str, Any] | None:
        table: Any = data
        walked = ""
        for part in section.split(".") if section else ():
            walked = _join(walked, part)
            table = table.get(part, {})
            if not isinstance(table, Mapping):
                if walked not in bad:
                    bad.add(walked)
                    self.problem(_join(path, walked), f"expected a table, got {_got(table)}")
                return None
        return table

    def _unknown(self, data: Mapping[str, Any], known: dict[str, set[str]], path: str,
                 bad: set[str]) -> None:
        for section, keys in known.items():
            if section in bad:
                continue
            table: Any = data
            for part in section.split(".") if section else ():
                table = table.get(part, {}) if isinstance(table, Mapping) else {}
            if not isinstance(table, Mapping):
                continue
            for key in table:
                if key not in keys:
                    reason = self.unknown
                    if self.list_known:
                        reason += f" (known: {', '.join(sorted(keys))})"
                    self.problem(_join(path, _join(section, key)), reason)

    # -- values ----------------------------------------------------------------------------

    def _value(self, hint: Any, raw: Any, path: str, spec: Setting = _PLAIN,
              current: Any = _MISSING) -> Any:
        """``raw`` read as type ``hint`` (or ``spec.read_as``), converted and checked;
        the invalid marker once the problem is recorded."""
        value = self._convert(spec.read_as if spec.read_as is not None else hint, raw, path,
                              spec, current)
        if value is _INVALID or spec.convert is None:
            return value
        try:
            return spec.convert(value)
        except ValueError as exc:
            self.problem(path, str(exc))
            return _INVALID

    def _convert(self, hint: Any, raw: Any, path: str, spec: Setting, current: Any) -> Any:
        origin, args = typing.get_origin(hint), typing.get_args(hint)
        if hint is Any or hint is object:
            return raw
        if hint in _PARSED:
            return self._scalar(hint, raw, path, spec, spec.choices)
        if origin is Union or origin is types.UnionType:
            options = [a for a in args if a is not type(None)]
            if len(options) == 1:
                return self._convert(options[0], raw, path, spec, current)
            for option in options:
                if _accepts(option, raw, self.text):
                    return self._convert(option, raw, path, spec, current)
            names = " or ".join(_name(o) for o in options)
            self.problem(path, f"expected {names}{_unit(spec)}, got {_got(raw)}")
            return _INVALID
        if origin is Literal:
            return self._scalar(type(args[0]), raw, path, spec, args)
        if origin in (tuple, list, frozenset, set):
            return self._sequence(origin, args[0] if args else Any, raw, path, spec)
        if origin in (Mapping, dict) or hint is dict:
            return self._mapping(args[1] if args else Any, raw, path, spec, current)
        if dataclasses.is_dataclass(hint) and isinstance(hint, type):
            return self._table(hint, raw, path, current)
        if isinstance(hint, type) and issubclass(hint, enum.Enum):
            return self._enum(hint, raw, path)
        return self._scalar(hint, raw, path, spec, spec.choices)

    def _sequence(self, kind: type, element: Any, raw: Any, path: str, spec: Setting) -> Any:
        items = raw
        if self.text and isinstance(raw, str):
            items = [part.strip() for part in raw.split(",") if part.strip()]
        if not isinstance(items, list):
            self.problem(path, f"expected {_name(tuple[element, ...])}, got {_got(raw)}")
            return _INVALID
        out = [self._convert(element, item, f"{path}[{i}]", spec, _MISSING)
               for i, item in enumerate(items)]
        if any(value is _INVALID for value in out):  # refused whole: indexes stay true
            return _INVALID
        return out if kind is list else kind(out)

    def _mapping(self, element: Any, raw: Any, path: str, spec: Setting, current: Any) -> Any:
        if not isinstance(raw, Mapping):
            self.problem(path, f"expected a table, got {_got(raw)}")
            return _INVALID
        out = dict(current) if spec.merge and isinstance(current, Mapping) else {}
        valid = True
        for key, item in raw.items():
            at = _join(path, key)
            if spec.keys is not None and key not in spec.keys:
                self.problem(at, f"unknown key (known: {', '.join(spec.keys)})")
                valid = False
                continue
            value = self._convert(element, item, at, spec, _MISSING)
            valid = valid and value is not _INVALID
            out[key] = value
        return out if valid else _INVALID

    def _table(self, cls: type, raw: Any, path: str, current: Any) -> Any:
        short = getattr(cls, "toml_shorthand", None)
        if not isinstance(raw, Mapping) and short and not isinstance(raw, list):
            before = len(self.problems)
            obj = self.read(cls, {short: raw}, path)
            inner = _join(path, short)  # a problem of the bare value is the value's own
            self.problems[before:] = [(f, path if p == inner else p, r)
                                      for f, p, r in self.problems[before:]]
        else:
            base = current if dataclasses.is_dataclass(current) else None
            obj = self.read(cls, raw, path, base=base)
        return _INVALID if obj is None else obj

    def _enum(self, cls: type[enum.Enum], raw: Any, path: str) -> Any:
        for member in cls:
            if raw == member.value or (isinstance(raw, str) and raw.lower() == member.name.lower()):
                return member
        names = ", ".join(str(m.value) for m in cls)
        self.problem(path, f"{raw!r} is not one of {names}")
        return _INVALID

    def _scalar(self, hint: Any, raw: Any, path: str, spec: Setting,
                choices: tuple[Any, ...] | None) -> Any:
        parsed = _PARSED.get(hint)
        want = parsed[0] if parsed else hint
        value = self._text(want, raw, path) if self.text and isinstance(raw, str) else raw
        if value is _INVALID:
            return _INVALID
        if not _is(want, value):
            self.problem(path, f"expected {_name(want)}{_unit(spec)}, got {_got(raw)}")
            return _INVALID
        if want is float:
            value = float(value)
            if not math.isfinite(value):
                self.problem(path, f"must be a finite number, got {value}")
                return _INVALID
        if parsed:
            try:
                value = parsed[1](value)
            except ValueError as exc:
                self.problem(path, str(exc))
                return _INVALID
            if isinstance(value, Path) and self.base_dir is not None and \
                    not value.is_absolute():
                value = self.base_dir / value
        if want in (int, float) and (reason := _out_of_range(value, spec)):
            self.problem(path, reason)
            return _INVALID
        if choices is not None and value not in choices:
            self.problem(path, f"{value!r} is not one of {', '.join(map(str, choices))}")
            return _INVALID
        if spec.check is not None and (refused := spec.check(value)):
            self.problem(path, refused)
            return _INVALID
        return value

    def _text(self, want: Any, raw: str, path: str) -> Any:
        """A text-mode value as ``want``; problems name the option as ``key=value``."""
        key = path.rsplit(".", 1)[-1]
        if want is bool:
            word = raw.strip().lower()
            if word in TRUE_WORDS or word in FALSE_WORDS:
                return word in TRUE_WORDS
            self.problem(path, f"{key}={raw!r} is not a boolean (1/0, true/false, yes/no, "
                               "on/off)")
            return _INVALID
        try:
            if want is int:
                return int(raw, 0)
            if want is float:
                return float(raw)
        except ValueError:
            what = "an integer" if want is int else "a number"
            self.problem(path, f"{key}={raw!r} is not {what}")
            return _INVALID
        return raw


def read_table(cls: type[T], data: Any, *, file: str = "", path: str = "", text: bool = False,
               base_dir: Path | None = None, unknown: str = "unknown key",
               list_known: bool = False) -> T:
    """Build ``cls`` from ``data``; raise ConfigError listing every problem."""
    reader = Reader(file, base_dir=base_dir, text=text, unknown=unknown, list_known=list_known)
    obj = reader.read(cls, data, path)
    reader.raise_problems()
    assert obj is not None  # no problem recorded means it was built
    return obj


# -- helpers -------------------------------------------------------------------------------


@cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _no_checks() -> Iterable[tuple[str, str]]:
    return ()


def _default(f: dataclasses.Field[Any]) -> Any:
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return _MISSING


def _declare(known: dict[str, set[str]], section: str, *keys: str) -> None:
    known.setdefault(section, set()).update(keys)
    parts = section.split(".") if section else []
    for i, part in enumerate(parts):  # the sub-table itself is a key of its parent
        known.setdefault(".".join(parts[:i]), set()).add(part)


def _related(key: str, other: str) -> bool:
    """True when one key is the other or inside it (``dropout`` and ``dropout.every``)."""
    return key == other or key.startswith(other + ".") or other.startswith(key + ".")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path and key else path or key


def _is(want: Any, value: Any) -> bool:
    if want is bool:
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False
    if want is float:
        return isinstance(value, int | float)
    return isinstance(value, want) if isinstance(want, type) else True


def _accepts(hint: Any, raw: Any, text: bool) -> bool:
    origin = typing.get_origin(hint)
    if hint is Any:
        return True
    if hint in _PARSED:
        return _is(_PARSED[hint][0], raw) or (text and isinstance(raw, str))
    if origin is Literal:
        return raw in typing.get_args(hint)
    if origin in (tuple, list, frozenset, set):
        return isinstance(raw, list) or (text and isinstance(raw, str))
    if origin in (Mapping, dict) or (dataclasses.is_dataclass(hint) and isinstance(hint, type)):
        return isinstance(raw, Mapping)
    if text and isinstance(raw, str):
        return True
    want = _PARSED[hint][0] if hint in _PARSED else hint
    return _is(want, raw)


def _name(hint: Any) -> str:
    if hint in _PARSED:
        return _PARSED[hint][0].__name__
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (tuple, list, frozenset, set):
        element = args[0] if args else Any
        if dataclasses.is_dataclass(element):
            return "an array of tables"
        return "an array" if element is Any else f"an array of {_name(element)}"
    if origin in (Mapping, dict) or dataclasses.is_dataclass(hint):
        return "a table"
    if origin is Literal:
        return "one of " + ", ".join(map(repr, args))
    return getattr(hint, "__name__", str(hint))


def _table_name(cls: type) -> str:
    keys = list(dict.fromkeys((setting_of(f).key or f.name).split(".", 1)[0]
                              for f in dataclasses.fields(cls)
                              if setting_of(f).toml and not setting_of(f).rest))
    shown = ", ".join(keys[:6]) + (", ..." if len(keys) > 6 else "")
    return f"a table {{{shown}}}"


def _got(raw: Any) -> str:
    text = repr(raw)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(raw).__name__} {text}"


def _unit(spec: Setting) -> str:
    return f" ({spec.unit})" if spec.unit else ""


def _number(value: float) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _out_of_range(value: float, spec: Setting) -> str:
    """Why ``value`` breaks the bounds of ``spec``; "" when it does not."""
    ge, gt, le, lt = spec.ge, spec.gt, spec.le, spec.lt
    if ((ge is None or value >= ge) and (gt is None or value > gt)
            and (le is None or value <= le) and (lt is None or value < lt)):
        return ""
    if ge is not None and le is not None and gt is None and lt is None:
        phrase = f"in {_number(ge)}..{_number(le)}"
    elif gt == 0 and ge is None and le is None and lt is None:
        phrase = "a positive number"
    elif ge is not None and gt is None and le is None and lt is None:
        phrase = f"at least {_number(ge)}"
    elif le is not None and ge is None and gt is None and lt is None:
        phrase = f"at most {_number(le)}"
    else:
        low = f">= {_number(ge)}" if ge is not None else f"> {_number(gt)}" \
            if gt is not None else ""
        high = f"<= {_number(le)}" if le is not None else f"< {_number(lt)}" \
            if lt is not None else ""
        phrase = " and ".join(p for p in (low, high) if p)
    unit = f" {spec.unit}" if spec.unit else ""
    return f"must be {phrase}, got {value!r}{unit}"


__all__ = ["Problem", "Reader", "Setting", "read_table", "setting", "setting_of", "toml_keys"]
