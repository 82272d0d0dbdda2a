"""The ``costmap`` translator (IOP CostMap2D): cost maps and no-go zones, both ways. No I/O.

JAUS -> DDS:

* ReportCostMap2D -> ``CostMap``: every cell row-major on one 0..255 scale (0 free, 254
  no-go, 255 unknown), whichever of the three encodings the vehicle uses (a cost per cell,
  cost and confidence per cell, or run-length coded 3-bit costs, spread to 0..254);
* ReportNoGoZones -> ``NoGoZones`` (every zone the vehicle holds, asked with zone ID 0);
* AddNoGoZoneResponse -> ``RequestResult`` (``request`` AddNoGoZone: the zone ID given).

DDS -> JAUS: ``NoGoZoneCommand`` ADD -> AddNoGoZone, REMOVE -> RemoveNoGoZone (behind
control, as the service requires); ``CostMapRequest`` -> QueryCostMap2D for a region (a
query: no control needed, sent at once).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    NAN,
    Action,
    Build,
    Computed,
    Const,
    From,
    Put,
    ReportRule,
    RuleTranslator,
    SendMessage,
    TranslatorContext,
    get_path,
    label,
)
from edge_vis.kit import CommandRule as Cmd

COSTMAP = "urn:jaus:jss:iop:CostMap2D"
ADD_RESPONSES = {0: "Success", 1: "GlobalVerticesNotSupported", 2: "LocalVerticesNotSupported"}
#: a run-length coded cost is 0..7; spread onto the 0..254 scale of the other encodings
RLE_MAX = 7
UNKNOWN = 255


def _data(f: Mapping[str, Any]) -> tuple[str, list[Any]]:
    var = f.get("cost_map2_d_data_var") or {}
    name = next(iter(var), "")
    return name, list(var.get(name) or [])


def costs(f: Mapping[str, Any]) -> list[int]:
    """Every cell's cost, row-major, 0..254 or 255 (unknown)."""
    name, items = _data(f)
    if name == "run_length_encoded_data_list":
        out: list[int] = []
        for item in items:
            bits = item.get("cost_and_run_length") or {}
            known = int(bits.get("certainty_sub_field", 0))
            cost = round(int(bits.get("cost_sub_field", 0)) * 254 / RLE_MAX) if known \
                else UNKNOWN
            out.extend([cost] * int(bits.get("number_cells_sub_field", 0)))
        return out
    return [int(item.get("cost", UNKNOWN)) for item in items]


def confidence(f: Mapping[str, Any]) -> list[float]:
    """Per-cell confidence, percent (only the cost-and-confidence encoding has it)."""
    name, items = _data(f)
    if name != "cost_and_confidence_data_list":
        return []
    return [float(item.get("confidence", NAN)) for item in items]


def _pose(member: str) -> Computed:
    def pick(f: Mapping[str, Any]) -> float:
        value = get_path(f, "cost_map2_d_pose_var.*." + member)
        return NAN if value is None else float(value)

    return Computed(pick, f"cost_map2_d_pose_var.*.{member}")


def _frame(f: Mapping[str, Any]) -> str:
    pose = next(iter(f.get("cost_map2_d_pose_var") or {}), "")
    return "LOCAL" if "local" in pose else "GLOBAL"


def _zones(f: Mapping[str, Any]) -> list[dict[str, Any]]:
    out = []
    for zone in f.get("no_go_zones_list") or []:
        var = zone.get("vertex_var") or {}
        kind = next(iter(var), "")
        out.append({"zone_id": int(get_path(zone, "zone_id_rec.zone_id", 0)),
                    "frame": "LOCAL" if kind.startswith("local") else "GLOBAL",
                    "vertices": [{k: float(v) for k, v in p.items()}
                                 for p in var.get(kind) or []]})
    return out


def _vertices(sample: Mapping[str, Any]) -> dict[str, Any]:
    """The vertex variant of AddNoGoZone: lat/lon (GLOBAL) or x/y (LOCAL) per vertex."""
    points = list(sample.get("vertices") or [])
    if len(points) < 3:
        raise ValueError(f"a no-go zone needs at least 3 vertices, got {len(points)}")
    if str(getattr(sample.get("frame"), "name", sample.get("frame"))).upper() == "LOCAL":
        return {"local_vertex_list": [{"x": float(p["x"]), "y": float(p["y"])}
                                      for p in points]}
    return {"global_vertex_list": [{"latitude": float(p["latitude"]),
                                    "longitude": float(p["longitude"])} for p in points]}


def query_fields(sample: Mapping[str, Any]) -> dict[str, Any]:
    """QueryCostMap2D for a CostMapRequest: size and centre only where given."""

    def given(name: str) -> float | None:
        value = sample.get(name)
        return None if value is None or math.isnan(float(value)) else float(value)

    fields: dict[str, Any] = {}
    width, height = given("max_width"), given("max_height")
    if width is not None or height is not None:
        fields["query_cost_map2_d_rec"] = {"max_width": width or 0.0,
                                           "max_height": height or 0.0}
    rotation = given("rotation") or 0.0
    if str(getattr(sample.get("frame"), "name", sample.get("frame"))).upper() == "LOCAL":
        x, y = given("center_x"), given("center_y")
        if x is not None and y is not None:
            fields["query_cost_map2_d_center_var"] = {"cost_map2_d_local_pose_rec": {
                "map_center_x": x, "map_center_y": y, "map_rotation": rotation}}
    else:
        lat, lon = given("center_latitude"), given("center_longitude")
        if lat is not None and lon is not None:
            fields["query_cost_map2_d_center_var"] = {"cost_map2_d_global_pose_rec": {
                "map_center_latitude": lat, "map_center_longitude": lon,
                "map_rotation": rotation}}
    return fields


class CostmapTranslator(RuleTranslator):
    """IOP CostMap2D <-> ``CostMap``, ``NoGoZones`` and their commands."""

    name = "costmap"
    report_rules = (
        ReportRule("ReportCostMap2D", "CostMap", {
            "rows": From("cost_map2_d_rec.number_of_rows"),
            "columns": From("cost_map2_d_rec.number_of_columns"),
            "width": From("cost_map2_d_rec.map_width", note="m"),
            "height": From("cost_map2_d_rec.map_height", note="m"),
            "frame": Computed(_frame, "cost_map2_d_pose_var alternative"),
            "center_latitude": _pose("map_center_latitude"),
            "center_longitude": _pose("map_center_longitude"),
            "center_x": _pose("map_center_x"),
            "center_y": _pose("map_center_y"),
            "rotation": _pose("map_rotation"),
            "costs": Computed(costs, "cost_map2_d_data_var: cost list, cost+confidence "
                                     "list or run-length coded (3-bit cost x 254/7)"),
            "confidence": Computed(confidence, "cost_and_confidence_data_list[].confidence"),
        }, query="QueryCostMap2D", service=COSTMAP, rate=0.2,
            doc="the whole map the vehicle holds; CostMapRequest asks for a region"),
        ReportRule("ReportNoGoZones", "NoGoZones",
                   {"zones": Computed(_zones, "no_go_zones_list[] (zone_id, vertex_var)")},
                   query="QueryNoGoZones", service=COSTMAP, query_fields={"zone_id": 0},
                   rate=0.5, on_change=True, doc="every zone (zone ID 0)"),
        ReportRule("AddNoGoZoneResponse", "RequestResult",
                   {"request": Const("AddNoGoZone"), "request_id": From("request_id"),
                    "result": From("response_code", convert=label(ADD_RESPONSES)),
                    "id": From("zone_id")}, keys=("request",),
                   doc="the answer to AddNoGoZone: the zone's ID"),
    )
    command_rules = (
        Cmd("NoGoZoneCommand", "RemoveNoGoZone", COSTMAP, "no_go_zone",
            {"zone_id": Put("zone_id", 0, 65535, convert=int)}, when={"action": "REMOVE"}),
        Cmd("NoGoZoneCommand", "AddNoGoZone", COSTMAP, "no_go_zone",
            {"request_id_rec.request_id": Put("request_id", 0, 65535, convert=int),
             "vertex_var": Build("frame, vertices", _vertices,
                                 "GLOBAL: latitude/longitude, LOCAL: x/y; 3 or more")},
            when={"action": "ADD"}),
    )
    def on_sample(self, topic: str, sample: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        """Commands by rule; a CostMapRequest queries the vehicle's CostMap2D at once."""
        if topic != "CostMapRequest":
            return super().on_sample(topic, sample, ctx)
        view = ctx.vehicle
        providers = sorted(a for a, services in (view.components if view else {}).items()
                           if any(uri == COSTMAP for uri, _v in services))
        if not providers:
            return []
        return [SendMessage(providers[0], "QueryCostMap2D", query_fields(sample),
                            traffic_class="telemetry")]

    def describe(self) -> list[dict[str, Any]]:
        """The rule rows and the region query."""
        return [*super().describe(), {
            "translator": self.name, "direction": "dds->jaus", "message": "QueryCostMap2D",
            "topic": "CostMapRequest", "query": "", "service": COSTMAP, "rate": None,
            "fields": [{"dds": "max_width, max_height", "jaus": "query_cost_map2_d_rec",
                        "note": "m; NaN: the vehicle's choice"},
                       {"dds": "frame, center_*, rotation",
                        "jaus": "query_cost_map2_d_center_var", "note": "NaN: the vehicle's"}],
            "doc": "a query: sent without control; the answer is the CostMap rule's"}]


#: the region query is no rule: read its topic too
CostmapTranslator.subscribes = (*CostmapTranslator.subscribes, "CostMapRequest")
