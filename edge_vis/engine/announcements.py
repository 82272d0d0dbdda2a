"""Vehicles found from what they send: hello and passive discovery profiles. No I/O.

A vehicle that does not answer QueryIdentification is described by a vehicle profile's
``[discovery]`` table (:class:`~edge_vis.config.vehicles.VehicleDiscovery`):

* *hello*: a message of the catalogue (the user's JSIDL) announces the vehicle; the
  profile names the fields that give its JAUS ID, vehicle id, name, type and services.
  Every hello declares the vehicle again, so a changed name or service list is taken.
* *passive*: the first message from the subsystem (or, for a family profile, one of its
  ``messages`` from any subsystem) declares the vehicle at the sender's address; each
  component offers the services that the catalogue says declare the messages it sends,
  plus those the profile lists.

Either way the vehicle is declared like a static one (no QueryConfiguration or
QueryServices), and any message counts as a sign of life: one that offers neither Liveness
nor Management is never probed (:meth:`~edge_vis.engine.liveness.Liveness.probe`) and is
lost after the profile's ``silence_timeout``. Paths are resolved against the message
definition once, so a record-qualified path (``pack_rec.pack_id``) works as well as the
flattened one.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from edge_vis.config import VehicleProfile
from edge_vis.engine.discovery import Service
from edge_vis.engine.finder import Finder
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import derive_vehicle_id
from edge_vis.kit.rules import get_path, resolve_path, type_at

log = logging.getLogger(__name__)


def discovery_problems(vehicles: tuple[VehicleProfile, ...], catalogue: Any,
                       source: str = "") -> list[tuple[str, str, str]]:
    """What the vehicles' ``[discovery]`` tables name that ``catalogue`` lacks, as
    ``(file, key, reason)``: the hello or passive messages, and every hello field path."""
    problems: list[tuple[str, str, str]] = []
    for i, vp in enumerate(vehicles):
        found = vp.discovery
        if found is None:
            continue
        inline = not vp.source or vp.source == source
        where = f"vehicles[{i}].discovery" if inline else "discovery"
        file = source if inline else vp.source
        for key, name in ([("hello", found.hello)] if found.hello else
                          [(f"messages[{j}]", m) for j, m in enumerate(found.messages)]):
            if _definition(catalogue, name) is None:
                problems.append((file, f"{where}.{key}", f"no message {name!r} in the "
                                 "catalogue (a message of your own needs its JSIDL in "
                                 "catalogue.jsidl)"))
        defn = _definition(catalogue, found.hello) if found.hello else None
        if defn is None:
            continue
        for key, path in found.hello_fields().items():
            _, problem = resolve_path(defn.body, path)
            if problem:
                problems.append((file, f"{where}.{key}", f"{path!r} of {found.hello}: "
                                 f"{problem}"))
    return problems


def verify_discovery(vehicles: tuple[VehicleProfile, ...], catalogue: Any,
                     source: str = "") -> None:
    """Raise ConfigError listing every :func:`discovery_problems` (run and check)."""
    problems = discovery_problems(vehicles, catalogue, source)
    if problems:
        raise ConfigError(problems)


def _definition(catalogue: Any, name: str) -> Any:
    try:
        return catalogue.by_name(name)
    except (KeyError, AttributeError):
        return None


def address_of(value: Any) -> JausAddress | None:
    """A JAUS ID as a hello may carry it: sub-fields, an AS5710 u32, or ``"S.N.C"``."""
    try:
        if isinstance(value, Mapping):
            return JausAddress(int(value["subsystem"]), int(value["node"]),
                               int(value["component"]))
        if isinstance(value, int) and not isinstance(value, bool):
            return JausAddress(value >> 16 & 0xFFFF, value >> 8 & 0xFF, value & 0xFF)
        if isinstance(value, str):
            return JausAddress.parse(value)
    except (KeyError, TypeError, ValueError):
        return None
    return None


class Announcements:
    """Declares the vehicles that discovery profiles describe, from their messages."""

    def __init__(self, state: EngineState, finder: Finder, changed: Changed) -> None:
        self._state = state
        self._finder = finder
        self._changed = changed
        #: (message, field path) -> the path as decoded fields hold it
        self._paths: dict[tuple[str, str], str] = {}
        #: (sender, message) whose services passive discovery has added
        self._inferred: set[tuple[JausAddress, str]] = set()

    def _profiles(self) -> tuple[VehicleProfile, ...]:
        return tuple(vp for vp in self._state.profile.vehicles if vp.discovery is not None)

    def match(self, subsystem: int, name: str) -> VehicleProfile | None:
        """The discovery profile that message ``name`` from ``subsystem`` declares a
        vehicle by: one for that subsystem first, then a family's."""
        profiles = self._profiles()
        for vp in profiles:
            if vp.subsystem == subsystem and _declares(vp, name, own=True):
                return vp
        for vp in profiles:
            if vp.is_family and _declares(vp, name, own=False):
                return vp
        return None

    def on_message(self, source: JausAddress, name: str, fields: Mapping[str, Any],
                   vehicle: Vehicle | None, now: float) -> Vehicle | None:
        """A message ``vehicle`` (None: unknown subsystem) sent: declare or update it.

        Returns the vehicle the message belongs to, if a profile placed it."""
        state = self._state
        if source.subsystem == state.profile.jaus_id.subsystem:
            return vehicle
        vp = vehicle.announced_by if vehicle is not None else None
        if vp is None:
            if vehicle is not None and vehicle.static:
                return vehicle  # declared otherwise (a static profile, a translator)
            vp = self.match(source.subsystem, name)
            if vp is None:
                return vehicle
        found = vp.discovery
        assert found is not None
        if found.hello:
            if name != found.hello:
                return vehicle
            return self._hello(vp, source, name, fields, vehicle, now)
        return self._passive(vp, source, name, vehicle, now)

    # -- hello -----------------------------------------------------------------------

    def _hello(self, vp: VehicleProfile, source: JausAddress, name: str,
               fields: Mapping[str, Any], vehicle: Vehicle | None,
               now: float) -> Vehicle | None:
        found = vp.discovery
        assert found is not None
        counters = self._state.counters
        address = source
        if found.address_field:
            given = address_of(self._get(name, fields, found.address_field))
            if given is None or given.is_broadcast or 0 in (
                    given.subsystem, given.node, given.component):
                counters["hellos_refused"] += 1
                log.warning("%s from %s: no usable JAUS ID in %s (ignored)", name, source,
                            found.address_field)
                return vehicle
            address = given
        if vehicle is not None and address.subsystem != vehicle.subsystem:
            counters["hellos_refused"] += 1
            log.warning("%s from %s names subsystem %d (ignored)", name, source,
                        address.subsystem)
            return vehicle
        label = str(self._get(name, fields, found.name_field) or "") if found.name_field \
            else ""
        label = label or vp.name
        vehicle_id = vp.vehicle_id
        if not vehicle_id and found.vehicle_id_field:
            vehicle_id = str(self._get(name, fields, found.vehicle_id_field) or "")
        vehicle_id = vehicle_id or derive_vehicle_id(label, address.subsystem)
        kind = vp.vehicle_type or self._type(name, fields, found.type_field)
        services = [*self._services(self._get(name, fields, found.services_field), found),
                    *((s.uri, s.version) for s in found.services)]
        declared = self._finder.declare(vehicle_id, {address: services}, label, kind, now,
                                        seen=False)
        if declared is not None:
            self._adopt(declared, vp)
            counters["hellos_accepted"] += 1
        return declared

    def _get(self, message: str, fields: Mapping[str, Any], path: str) -> Any:
        key = (message, path)
        resolved = self._paths.get(key)
        if resolved is None:
            defn = _definition(self._state.catalogue, message)
            resolved = resolve_path(defn.body, path)[0] if defn is not None else path
            self._paths[key] = resolved
        return get_path(fields, resolved)

    def _type(self, message: str, fields: Mapping[str, Any], path: str) -> str:
        if not path:
            return ""
        value = self._get(message, fields, path)
        defn = _definition(self._state.catalogue, message)
        labels = getattr(type_at(defn.body, path), "labels", None) if defn is not None \
            else None
        if labels and isinstance(value, int) and value in labels:
            return str(labels[value])
        return "" if value is None else str(value)

    @staticmethod
    def _services(value: Any, found: Any) -> list[Service]:
        if not isinstance(value, list | tuple):
            return []
        out: list[Service] = []
        for item in value:
            if isinstance(item, str):
                out.append((item, "1.0"))
            elif isinstance(item, Mapping) and isinstance(item.get(found.service_uri), str):
                major = item.get(found.service_major, 1)
                minor = item.get(found.service_minor, 0)
                out.append((item[found.service_uri], f"{major}.{minor}"))
        return out

    # -- passive ---------------------------------------------------------------------

    def _passive(self, vp: VehicleProfile, source: JausAddress, name: str,
                 vehicle: Vehicle | None, now: float) -> Vehicle | None:
        found = vp.discovery
        assert found is not None
        if vehicle is not None and (source, name) in self._inferred:
            return vehicle  # what this message says of its sender is known
        self._inferred.add((source, name))
        inferred = list(getattr(_definition(self._state.catalogue, name), "services", ()))
        if vehicle is not None:
            if inferred and vehicle.set_services(source, inferred):
                self._changed(vehicle, "identified", now)
            return vehicle
        vehicle_id = vp.vehicle_id or derive_vehicle_id(vp.name, source.subsystem)
        services = [*inferred, *((s.uri, s.version) for s in found.services)]
        declared = self._finder.declare(vehicle_id, {source: services}, vp.name,
                                        vp.vehicle_type, now, seen=False)
        if declared is not None:
            self._adopt(declared, vp)
            self._state.counters["vehicles_found_passively"] += 1
        return declared

    def _adopt(self, vehicle: Vehicle, vp: VehicleProfile) -> None:
        """The vehicle follows ``vp``: its rates, link and silence timeout."""
        vehicle.announced_by = vp
        if vehicle.profile is None:
            vehicle.profile = vp


def _declares(vp: VehicleProfile, name: str, *, own: bool) -> bool:
    found = vp.discovery
    if found is None:
        return False
    if found.hello:
        return name == found.hello
    return name in found.messages if found.messages else own
