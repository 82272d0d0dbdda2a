"""Discovery helpers: reading discovery reports into a system tree. No I/O.

The engine finds subsystems with a periodic broadcast QueryIdentification(2), then asks
each one QueryConfiguration(2) and QueryServices for every node and component (AS5710
Discovery). The helpers here turn the decoded reports into plain tuples and tolerate what
real robots send:

* the JTS example lists node 1 twice in ReportServices (one entry per service): entries
  for the same component are merged;
* core services are often not listed (JTS registers only the services it was built with
  by name): every listed service implies the services it inherits from
  (:data:`SERVICE_PARENTS`, from the JSIDL ``inherits-from`` chains), so a
  LocalWaypointListDriver implies Management, AccessControl, Events and Transport;
* the JTS example answers QueryIdentification(4) with a type-2 (subsystem) report: any
  ReportIdentification identifies the subsystem of its sender.

Decoded nested records may be flattened or kept as sub-dicts depending on the message
definition; :func:`pick` finds a field either way.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

CORE = "urn:jaus:jss:core:"
MOBILITY = "urn:jaus:jss:mobility:"
ENV = "urn:jaus:jss:environmentSensing:"

#: service URI -> the URI it inherits from (JSIDL ``inherits-from``; core v1.1,
#: mobility v1.0, environment sensing v1.0).
SERVICE_PARENTS: Mapping[str, str] = {
    CORE + "Events": CORE + "Transport",
    CORE + "AccessControl": CORE + "Events",
    CORE + "Management": CORE + "AccessControl",
    CORE + "Time": CORE + "AccessControl",
    CORE + "Liveness": CORE + "Events",
    CORE + "Discovery": CORE + "Events",
    CORE + "ListManager": CORE + "Management",
    MOBILITY + "GlobalPoseSensor": CORE + "AccessControl",
    MOBILITY + "LocalPoseSensor": CORE + "AccessControl",
    MOBILITY + "VelocityStateSensor": CORE + "Events",
    MOBILITY + "AccelerationStateSensor": CORE + "Events",
    MOBILITY + "PrimitiveDriver": CORE + "Management",
    MOBILITY + "VelocityStateDriver": CORE + "Management",
    MOBILITY + "GlobalVectorDriver": CORE + "Management",
    MOBILITY + "LocalVectorDriver": CORE + "Management",
    MOBILITY + "GlobalWaypointDriver": CORE + "Management",
    MOBILITY + "LocalWaypointDriver": CORE + "Management",
    MOBILITY + "ListManager": CORE + "Management",
    MOBILITY + "GlobalWaypointListDriver": MOBILITY + "ListManager",
    MOBILITY + "LocalWaypointListDriver": MOBILITY + "ListManager",
    MOBILITY + "GlobalPathSegmentDriver": MOBILITY + "ListManager",
    MOBILITY + "LocalPathSegmentDriver": MOBILITY + "ListManager",
    ENV + "VisualSensor": CORE + "AccessControl",
    ENV + "StillImage": ENV + "VisualSensor",
    ENV + "DigitalVideo": ENV + "VisualSensor",
    ENV + "AnalogVideo": ENV + "VisualSensor",
    ENV + "RangeSensor": CORE + "AccessControl",
}

#: ReportIdentification.type values
IDENTIFICATION_TYPES: Mapping[int, str] = {
    10001: "VEHICLE", 20001: "OCU", 30001: "OTHER_SUBSYSTEM", 40001: "NODE", 50001: "PAYLOAD",
    60001: "COMPONENT",
}

Service = tuple[str, str]


def with_inherited(services: Iterable[Service]) -> tuple[Service, ...]:
    """``services`` plus every service they inherit from (version of the child)."""
    result: dict[str, str] = {}
    for uri, version in services:
        result.setdefault(uri, version)
    for uri, version in list(result.items()):
        parent = SERVICE_PARENTS.get(uri)
        seen = {uri}
        while parent is not None and parent not in seen:
            seen.add(parent)
            result.setdefault(parent, version if parent.split(":")[3] == uri.split(":")[3]
                              else "1.0")
            parent = SERVICE_PARENTS.get(parent)
    return tuple(sorted(result.items()))


def pick(value: Any, name: str, default: Any = None) -> Any:
    """Field ``name`` of a decoded record, looking into nested records if needed."""
    if isinstance(value, Mapping):
        if name in value:
            return value[name]
        for child in value.values():
            if isinstance(child, Mapping):
                found = pick(child, name, _MISSING)
                if found is not _MISSING:
                    return found
    return default


_MISSING = object()


def _list(value: Any, name: str) -> list[Any]:
    found = pick(value, name, [])
    return list(found) if isinstance(found, list | tuple) else []


def services_from_report(fields: Mapping[str, Any]) -> dict[tuple[int, int], list[Service]]:
    """ReportServices fields -> ``{(node, component): [(uri, "major.minor"), ...]}``.

    Repeated node or component entries are merged (JTS lists node 1 once per service).
    """
    result: dict[tuple[int, int], list[Service]] = {}
    for node in _list(fields, "node_list"):
        node_id = pick(node, "node_id")
        for comp in _list(node, "component_list"):
            comp_id = pick(comp, "component_id")
            if node_id is None or comp_id is None:
                continue
            entry = result.setdefault((int(node_id), int(comp_id)), [])
            for svc in _list(comp, "service_list"):
                uri = pick(svc, "uri")
                if not isinstance(uri, str):
                    continue
                major = pick(svc, "major_version_number", 1)
                minor = pick(svc, "minor_version_number", 0)
                item = (uri, f"{major}.{minor}")
                if item not in entry:
                    entry.append(item)
    return result


def components_from_configuration(fields: Mapping[str, Any]) -> list[tuple[int, int]]:
    """ReportConfiguration fields -> ``[(node, component), ...]``."""
    found: list[tuple[int, int]] = []
    for node in _list(fields, "node_list"):
        node_id = pick(node, "node_id")
        for comp in _list(node, "component_list"):
            comp_id = pick(comp, "component_id")
            if node_id is not None and comp_id is not None:
                key = (int(node_id), int(comp_id))
                if key not in found:
                    found.append(key)
    return found


