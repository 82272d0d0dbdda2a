"""The costmap translator: cost maps in any of the three encodings, no-go zones both ways."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, check_command_rule, check_report_rule, command_sample

from edge_vis.dds.convert import converter_for
from edge_vis.jaus.address import JausAddress
from edge_vis.kit import CommandRule, SendMessage
from translators.costmap import COSTMAP, CostmapTranslator

TR = CostmapTranslator
REPORTS = TR.report_rules
COMMANDS = TR.command_rules


@pytest.mark.parametrize("rule", REPORTS, ids=[r.message for r in REPORTS])
def test_every_declared_report_translates(rule) -> None:  # type: ignore[no-untyped-def]
    assert check_report_rule(TR(), rule) > 0


TRIANGLE = [{"latitude": 48.1, "longitude": 11.5}, {"latitude": 48.2, "longitude": 11.5},
            {"latitude": 48.1, "longitude": 11.6}]


@pytest.mark.parametrize(("rule", "values", "expected"), [
    (COMMANDS[1], {"request_id": 9, "vertices": TRIANGLE},
     {"request_id_rec": {"request_id": 9}, "vertex_var": {"global_vertex_list": TRIANGLE}}),
    (COMMANDS[0], {"zone_id": 12}, {"zone_id": 12}),
], ids=[c.message for c in COMMANDS[::-1]])
def test_every_declared_command(rule: CommandRule, values: dict[str, Any],
                                expected: dict[str, Any]) -> None:
    command = check_command_rule(TR(), rule, command_sample(rule, **values))
    assert dict(command.fields) == expected


def decoded(name: str, fields: dict[str, Any]) -> dict[str, Any]:
    return CAT.decode(CAT.encode(name, fields)).fields or {}


HEAD = {"cost_map2_d_rec": {"number_of_rows": 2, "number_of_columns": 3, "map_width": 30.0,
                            "map_height": 20.0}}


@pytest.mark.parametrize(("data", "costs", "confidence"), [
    ({"cost_data_list": [{"cost": c} for c in (0, 10, 254, 255, 7, 0)]},
     [0, 10, 254, 255, 7, 0], []),
    ({"cost_and_confidence_data_list": [{"cost": c, "confidence": 50.0} for c in range(6)]},
     [0, 1, 2, 3, 4, 5], [50.0] * 6),
    ({"run_length_encoded_data_list": [
        {"cost_and_run_length": {"cost_sub_field": 7, "certainty_sub_field": 1,
                                 "number_cells_sub_field": 4}},
        {"cost_and_run_length": {"cost_sub_field": 3, "certainty_sub_field": 0,
                                 "number_cells_sub_field": 2}}]},
     [254, 254, 254, 254, 255, 255], []),
], ids=["costs", "costs+confidence", "run-length"])
def test_cost_map_cells_on_one_scale(data: dict[str, Any], costs: list[int],
                                     confidence: list[float]) -> None:
    fields = decoded("ReportCostMap2D", {**HEAD, "cost_map2_d_pose_var": {
        "cost_map2_d_local_pose_rec": {"map_center_x": 5.0, "map_center_y": -2.0,
                                       "map_rotation": 0.5}},
        "cost_map2_d_data_var": data})
    (action,) = TR().on_message("ReportCostMap2D", fields, CTX)
    sample = action.sample
    assert (sample["rows"], sample["columns"], sample["frame"]) == (2, 3, "LOCAL")
    assert sample["costs"] == costs
    assert sample["confidence"] == pytest.approx(confidence, abs=0.5)
    assert sample["center_x"] == pytest.approx(5.0, abs=1e-3)
    assert sample["center_latitude"] != sample["center_latitude"]  # not reported: NaN
    converter_for(TYPES["CostMap"]).to_struct(sample, "CostMap")


def test_no_go_zones_and_the_add_answer() -> None:
    fields = decoded("ReportNoGoZones", {"no_go_zones_list": [
        {"zone_id_rec": {"zone_id": 3}, "vertex_var": {"global_vertex_list": TRIANGLE}},
        {"zone_id_rec": {"zone_id": 4}, "vertex_var": {"local_vertex_list": [
            {"x": 1.0, "y": 2.0}, {"x": 3.0, "y": 2.0}, {"x": 2.0, "y": 5.0}]}}]})
    (zones,) = TR().on_message("ReportNoGoZones", fields, CTX)
    got = zones.sample["zones"]
    assert [(z["zone_id"], z["frame"], len(z["vertices"])) for z in got] == [
        (3, "GLOBAL", 3), (4, "LOCAL", 3)]
    assert got[1]["vertices"][2]["y"] == pytest.approx(5.0, abs=1e-3)
    converter_for(TYPES["NoGoZones"]).to_struct(zones.sample, "NoGoZones")
    (answer,) = TR().on_message("AddNoGoZoneResponse", decoded("AddNoGoZoneResponse", {
        "request_id": 9, "response_code": 0, "zone_id": 12}), CTX)
    assert (answer.topic, answer.sample["request"], answer.sample["result"],
            answer.sample["id"]) == ("RequestResult", "AddNoGoZone", "Success", 12)


def test_a_zone_needs_three_vertices_and_local_zones_use_x_y() -> None:
    base = {"vehicle_id": "veh1", "operator_id": "op1", "action": "ADD", "request_id": 1}
    assert TR().on_sample("NoGoZoneCommand", {**base, "vertices": TRIANGLE[:2]}, CTX) == []
    (cmd,) = TR().on_sample("NoGoZoneCommand", {**base, "frame": "LOCAL", "vertices": [
        {"x": 0.0, "y": 0.0}, {"x": 4.0, "y": 0.0}, {"x": 0.0, "y": 4.0}]}, CTX)
    assert cmd.fields["vertex_var"]["local_vertex_list"][1] == {"x": 4.0, "y": 0.0}


def test_region_request_is_a_query_sent_at_once() -> None:
    view = replace(CTX.vehicle, components={JausAddress(150, 1, 4): ((COSTMAP, "1.1"),)})
    ctx = replace(CTX, vehicle=view)
    nan = float("nan")
    request = {"vehicle_id": "veh1", "operator_id": "op1", "max_width": 50.0,
               "max_height": 40.0, "frame": "GLOBAL", "center_latitude": 48.1,
               "center_longitude": 11.5, "center_x": nan, "center_y": nan, "rotation": 0.0}
    (query,) = TR().on_sample("CostMapRequest", request, ctx)
    assert isinstance(query, SendMessage) and query.destination == JausAddress(150, 1, 4)
    assert query.fields == {
        "query_cost_map2_d_rec": {"max_width": 50.0, "max_height": 40.0},
        "query_cost_map2_d_center_var": {"cost_map2_d_global_pose_rec": {
            "map_center_latitude": 48.1, "map_center_longitude": 11.5, "map_rotation": 0.0}}}
    CAT.encode(query.name, query.fields)
    whole = {"vehicle_id": "veh1", "max_width": nan, "max_height": nan,
             "center_latitude": nan, "center_longitude": nan}
    assert TR().on_sample("CostMapRequest", whole, ctx)[0].fields == {}
    assert TR().on_sample("CostMapRequest", whole, CTX) == []  # no CostMap2D: nothing
