"""The Discovery service of a simulated subsystem: what it says about itself. No I/O.

Builds the fields of ReportIdentification, ReportConfiguration, ReportServices and
ReportServiceList from the vehicle's profile and component layout, honouring the query's
node/component filters (255 = all) and a ReportServiceList search filter (a substring of
the service URI).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from edge_vis.tools.sim import components as svc
from edge_vis.tools.sim.components import ComponentSpec
from edge_vis.tools.sim.profile import VehicleSpec

VEHICLE_TYPE = 10001
NODE_TYPE = 40001
COMPONENT_TYPE = 60001
ALL = 255
ALL_SUBSYSTEMS = 65535


def identification(spec: VehicleSpec, component: ComponentSpec,
                   fields: dict[str, Any]) -> dict[str, Any]:
    """ReportIdentification for a QueryIdentification of type 2 (subsystem), 3 or 4."""
    query_type = fields["query_type"]
    if query_type == 3:
        return {"query_type": 3, "type": NODE_TYPE,
                "identification": f"{spec.name} node {spec.node}"}
    if query_type == 4:
        return {"query_type": 4, "type": COMPONENT_TYPE, "identification": component.name}
    return {"query_type": query_type, "type": VEHICLE_TYPE, "identification": spec.name}


def configuration(spec: VehicleSpec, layout: Sequence[ComponentSpec]) -> dict[str, Any]:
    """ReportConfiguration: one node with every component."""
    return {"node_list": [{
        "node_rec": {"node_id": spec.node},
        "component_list": [{"component_id": c.component, "instance_id": 0} for c in layout],
    }]}


def _wanted(spec: VehicleSpec, node_filter: list[dict[str, Any]]) -> set[int] | None:
    """Component ids a query's node list asks for; None = all (an empty list asks for all)."""
    if not node_filter:
        return None
    wanted: set[int] = set()
    for node in node_filter:
        if node["node_rec"]["node_id"] not in (ALL, spec.node):
            continue
        for comp in node["component_list"]:
            if comp["component_id"] == ALL:
                return None
            wanted.add(comp["component_id"])
    return wanted


def _nodes(spec: VehicleSpec, layout: Sequence[ComponentSpec],
           node_filter: list[dict[str, Any]]) -> list[dict[str, Any]]:
    wanted = _wanted(spec, node_filter)
    comps = [c for c in layout if wanted is None or c.component in wanted]
    if not comps:
        return []
    return [{
        "node_rec": {"node_id": spec.node},
        "component_list": [{
            "component_rec": {"component_id": c.component, "instance_id": 0},
            "service_list": [{"uri": uri, "major_version_number": v[0],
                              "minor_version_number": v[1]}
                             for uri in c.services for v in (svc.version_of(uri, c.version),)],
        } for c in comps],
    }]


def services(spec: VehicleSpec, layout: Sequence[ComponentSpec],
             fields: dict[str, Any]) -> dict[str, Any]:
    """ReportServices for the nodes and components a QueryServices names."""
    return {"node_list": _nodes(spec, layout, fields.get("node_list", []))}


def service_list(spec: VehicleSpec, layout: Sequence[ComponentSpec],
                 fields: dict[str, Any]) -> dict[str, Any]:
    """ReportServiceList (core 1.1) for this subsystem, with search filters applied."""
    out = []
    for sub in fields.get("subsystem_list", []):
        if sub["subsystem_rec"]["subsystem_id"] not in (ALL_SUBSYSTEMS, spec.subsystem):
            continue
        nodes = _nodes(spec, layout, sub["node_list"])
        filters = [c["search_filter"] for n in sub["node_list"]
                   for c in n["component_list"] if c.get("search_filter")]
        if filters:
            for node in nodes:
                for comp in node["component_list"]:
                    comp["service_list"] = [s for s in comp["service_list"]
                                            if any(f in s["uri"] for f in filters)]
                node["component_list"] = [c for c in node["component_list"]
                                          if c["service_list"]]
        out.append({"subsystem_rec": {"subsystem_id": spec.subsystem}, "node_list": nodes})
    return {"subsystem_list": out}
