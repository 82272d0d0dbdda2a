"""Messages a simulated vehicle sends as its profile writes them: hellos and reports of any JSIDL.

A ``custom`` vehicle is described by TOML alone: the JSIDL files that define its messages,
a hello (``[vehicles.hello]``: message and field values, sent every ``hello_period``) and
reports (``[[vehicles.reports]]``: field values, answered to their query and/or sent every
``period``). Field paths are written as the relay's profiles write them (flattened or
qualified by the body's record, see :func:`~edge_vis.kit.rules.resolve_path`); an
enumeration field takes its label (``"DISCHARGING"``) or its number. A number may drift::

    [vehicles.reports.drift]
    state_of_charge = { ramp = -0.5, min = 20.0 }     # -0.5 per second, never below 20
    voltage = { amplitude = 0.4, period = 30.0 }      # a sine of 30 s around the value

The UUV's VendorHello is the same mechanism with a built-in :data:`UUV_HELLO`. The
hello may ask for fields filled from the vehicle itself: its JAUS ID (a record of
subsystem/node/component, a 32-bit AS5710 ID or ``"S.N.C"`` text, as the JSIDL types it),
its name and its services. Checking a profile against its JSIDL (:func:`problems`) encodes
every message once, so a missing message, field or value is named before anything runs.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from edge_vis.catalogue import Catalogue
from edge_vis.codec.types import BitField, FixedString, List, Record, VarString
from edge_vis.errors import ConfigError, EncodeError, PluginError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.rules import resolve_path, set_path, type_at
from edge_vis.schema import setting


@dataclass(frozen=True, slots=True)
class Drift:
    """How a number moves: ``value + ramp * t + amplitude * sin(2 pi t / period)``,
    kept within ``min`` and ``max`` (``t``: seconds since the vehicle started)."""

    ramp: float = setting(0.0, ge=-1e9, le=1e9, unit="per second")
    amplitude: float = setting(0.0, ge=-1e9, le=1e9)
    period: float = setting(60.0, gt=0.0, unit="s")
    min: float | None = None
    max: float | None = None

    def at(self, value: float, t: float) -> float:
        """The drifted value ``t`` seconds after the start."""
        out = value + self.ramp * t + self.amplitude * math.sin(2 * math.pi * t / self.period)
        if self.min is not None:
            out = max(out, self.min)
        if self.max is not None:
            out = min(out, self.max)
        return out

    def validate(self) -> Iterable[tuple[str, str]]:
        """A range must not be empty."""
        if self.min is not None and self.max is not None and self.min > self.max:
            yield "min", f"{self.min:g} is above max {self.max:g}"


@dataclass(frozen=True, slots=True)
class HelloSpec:
    """The message a vehicle announces itself with (``[vehicles.hello]``)."""

    message: str = setting(doc="the hello's message name (from the JSIDL) is required")
    #: field path -> value, as written (paths flattened or record-qualified)
    fields: Mapping[str, Any] = setting(factory=dict)
    #: a field filled with the sending component's JAUS ID
    jaus_id_field: str = ""
    #: a field filled with the vehicle's ``name``
    name_field: str = ""
    #: a list field filled with the component's service URIs
    services_field: str = ""

    def filled(self) -> tuple[str, ...]:
        """The field paths the vehicle fills itself."""
        return tuple(p for p in (self.jaus_id_field, self.name_field, self.services_field) if p)


@dataclass(frozen=True, slots=True)
class ReportSpec:
    """A report the vehicle sends (``[[vehicles.reports]]``)."""

    message: str = setting(doc="the report's message name (from the JSIDL) is required")
    #: the query it answers ("": none)
    query: str = ""
    #: also sent to everyone every ``period`` seconds (0: only when asked)
    period: float = setting(0.0, ge=0.0, unit="s")
    fields: Mapping[str, Any] = setting(factory=dict)
    #: field path -> how its number moves
    drift: Mapping[str, Drift] = setting(factory=dict)

    def validate(self) -> Iterable[tuple[str, str]]:
        """A report must go out somehow, and only numbers drift."""
        if not self.query and not self.period:
            yield "query", "give the query it answers, a period, or both"
        for path in self.drift:
            value = self.fields.get(path)
            if isinstance(value, bool) or not isinstance(value, int | float):
                yield f"drift.{path}", "drifts a number: give it in fields too " \
                                       f"(fields.{path} = ...)"


#: the UUV's VendorHello (edge_vis/data/jsidl/uuv/VendorDiscovery.xml)
UUV_HELLO = HelloSpec(message="VendorHello",
                      fields={"vehicle_type": 1, "firmware_version": "sim-1.0"},
                      jaus_id_field="jaus_id", name_field="vehicle_name",
                      services_field="services")


def vehicle_catalogue(jsidl: Iterable[Path], base: Catalogue | None = None) -> Catalogue:
    """``base`` (default: the default catalogue) plus the messages of ``jsidl``."""
    from edge_vis.catalogue.jsidl import profile_catalogue

    return profile_catalogue(jsidl, base=base, source="sim JSIDL")


def services_of(catalogue: Catalogue, names: Iterable[str]) -> tuple[str, ...]:
    """The URIs of the services that declare the messages ``names``, in order, once."""
    out: dict[str, None] = {}
    for name in names:
        try:
            out.update((uri, None) for uri, _ in catalogue.by_name(name).services)
        except KeyError:
            continue
    return tuple(out)


def build(catalogue: Catalogue, message: str, values: Mapping[str, Any],
          extra: Mapping[str, Any] = {}) -> dict[str, Any]:
    """The decoded-form fields of ``message`` from path -> value (labels -> numbers)."""
    body = catalogue.by_name(message).body
    out: dict[str, Any] = {}
    for path, value in {**values, **extra}.items():
        resolved, problem = resolve_path(body, path)
        if problem:
            raise EncodeError(f"{message}: {path!r}: {problem}")
        labels = getattr(type_at(body, path), "labels", None)
        if isinstance(value, str) and labels:
            by_label = {str(v): k for k, v in labels.items()}
            if value not in by_label:
                raise EncodeError(f"{message}: {path!r}: no label {value!r} (labels: "
                                  f"{', '.join(by_label)})")
            value = by_label[value]
        set_path(out, resolved, value)
    return out


def hello_fields(catalogue: Catalogue, hello: HelloSpec, name: str, address: JausAddress,
                 services: Iterable[tuple[str, tuple[int, int]]]) -> dict[str, Any]:
    """The hello's fields, with what it asks the vehicle to fill."""
    body = catalogue.by_name(hello.message).body
    extra: dict[str, Any] = {}
    if hello.jaus_id_field:
        extra[hello.jaus_id_field] = _jaus_id(type_at(body, hello.jaus_id_field), address)
    if hello.name_field:
        extra[hello.name_field] = name
    if hello.services_field:
        extra[hello.services_field] = _services(type_at(body, hello.services_field), services)
    return build(catalogue, hello.message, hello.fields, extra)


def report_fields(catalogue: Catalogue, report: ReportSpec, t: float) -> dict[str, Any]:
    """The report's fields ``t`` seconds after the start (drifts applied)."""
    moved = {path: drift.at(float(report.fields[path]), t)
             for path, drift in report.drift.items()}
    return build(catalogue, report.message, {**report.fields, **moved})


def problems(jsidl: tuple[Path, ...], hello: HelloSpec | None,
             reports: tuple[ReportSpec, ...], where: str) -> list[tuple[str, str]]:
    """``(key path, reason)`` for what the messages of ``jsidl`` cannot carry."""
    try:
        catalogue = vehicle_catalogue(jsidl)
    except (ConfigError, PluginError) as exc:
        text = "; ".join(f"{f}: {k}: {r}" for f, k, r in exc.problems) \
            if isinstance(exc, ConfigError) else str(exc)
        return [(f"{where}.jsidl", text)]
    found: list[tuple[str, str]] = []
    entries: list[tuple[str, str, str, Mapping[str, Any]]] = []
    if hello is not None:
        extra = {p: _sample(catalogue, hello.message, p, hello) for p in hello.filled()}
        entries.append((f"{where}.hello", "message", hello.message, {**hello.fields, **extra}))
    for i, report in enumerate(reports):
        entries.append((f"{where}.reports[{i}]", "message", report.message, report.fields))
        if report.query:
            entries.append((f"{where}.reports[{i}]", "query", report.query, {}))
    for at, key, name, values in entries:
        try:
            catalogue.by_name(name)
        except KeyError:
            found.append((f"{at}.{key}", f"no message {name!r} in the catalogue (a message "
                          "of your own needs its JSIDL in jsidl = [...])"))
            continue
        try:
            catalogue.encode(name, build(catalogue, name, values))
        except (EncodeError, ValueError, TypeError, KeyError) as exc:
            found.append((f"{at}.fields", f"{name} cannot be sent with these values: {exc}"))
    return found


def _sample(catalogue: Catalogue, message: str, path: str, hello: HelloSpec) -> Any:
    """A stand-in for a field the vehicle fills, to encode the hello while checking."""
    try:
        body = catalogue.by_name(message).body
    except KeyError:
        return None
    if path == hello.jaus_id_field:
        return _jaus_id(type_at(body, path), JausAddress(1, 1, 1))
    if path == hello.services_field:
        return _services(type_at(body, path), [("urn:example:Service", (1, 0))])
    return "name"


def _jaus_id(kind: Any, address: JausAddress) -> Any:
    if isinstance(kind, Record | BitField):  # sub-fields subsystem, node, component
        return {"subsystem": address.subsystem, "node": address.node,
                "component": address.component}
    if isinstance(kind, VarString | FixedString):
        return str(address)
    return address.subsystem << 16 | address.node << 8 | address.component


def _services(kind: Any, services: Iterable[tuple[str, tuple[int, int]]]) -> list[Any]:
    element = kind.element if isinstance(kind, List) else None
    if not isinstance(element, Record):
        return [uri for uri, _ in services]
    names = [f.name for f in element.fields]
    uri_field = next((n for n in names if "uri" in n), names[0])
    major = next((n for n in names if "major" in n), None)
    minor = next((n for n in names if "minor" in n), None)
    out = []
    for uri, (ma, mi) in services:
        item: dict[str, Any] = {uri_field: uri}
        if major:
            item[major] = ma
        if minor:
            item[minor] = mi
        out.append(item)
    return out


__all__ = ["UUV_HELLO", "Drift", "HelloSpec", "ReportSpec", "build", "hello_fields", "problems",
           "report_fields", "services_of", "vehicle_catalogue"]
