"""The IOP and UGV services of a simulated UGV with ``iop = true`` (sans-I/O, fake clock)."""

from __future__ import annotations

import pytest
from conftest import OCU, OTHER, Wire, named, spec

from edge_vis.jaus.address import JausAddress

IOP = JausAddress(101, 1, 4)


def ready() -> Wire:
    wire = Wire(spec(iop=True, control_timeout=0))
    wire.advance(1.0)
    wire.take_control(to=IOP)
    wire.send("Resume", to=IOP)
    return wire


def test_the_iop_component_is_listed_only_when_asked_for() -> None:
    services = Wire(spec(iop=True)).query("QueryServices", {"node_list": []},
                                          to=JausAddress(101, 1, 1)).fields
    components = [c["component_rec"]["component_id"]
                  for n in services["node_list"] for c in n["component_list"]]
    assert components == [1, 2, 3, 4]
    plain = Wire().query("QueryServices", {"node_list": []}, to=JausAddress(101, 1, 1))
    assert len(plain.fields["node_list"][0]["component_list"]) == 3


def test_handoff_asked_of_the_controller_and_granted() -> None:
    wire = ready()
    outs = wire.send("RequestHandoff", {"authority_code": 70, "explanation": "relieve"},
                     to=IOP, source=OTHER)
    queued, ask = outs
    assert (queued.destination, queued.fields["response_code"]) == (OTHER, 4)  # QUEUED
    assert ask.name == "RequestReleaseControl" and ask.destination == OCU
    (request,) = ask.fields["request_release_control_list"]
    assert (request["src_subsystem_id"], request["authority_code"], request["explanation"]) \
        == (201, 70, "relieve")
    outs = wire.send("ConfirmReleaseControl", {"release_control_list": [
        {"id": request["id"], "response_code": 2}]}, to=IOP)
    assert [(o.name, o.destination, o.fields["response_code"]) for o in outs] == [
        ("ConfirmHandoffRequest", OTHER, 5)]  # WAIT -> DEFERRED
    outs = wire.send("ConfirmReleaseControl", {"release_control_list": [
        {"id": request["id"], "response_code": 0}]}, to=IOP)
    assert [(o.name, o.destination) for o in outs] == [
        ("RejectControl", OCU), ("ConfirmHandoffRequest", OTHER)]
    assert outs[1].fields["response_code"] == 0
    assert wire.query("QueryControl", to=IOP).fields["subsystem_id"] == 201


def test_handoff_denied_or_timed_out_leaves_control_where_it_was() -> None:
    wire = ready()
    ask = named(wire.send("RequestHandoff", {"authority_code": 70, "explanation": ""},
                          to=IOP, source=OTHER), "RequestReleaseControl")[0]
    request_id = ask.fields["request_release_control_list"][0]["id"]
    outs = wire.send("ConfirmReleaseControl", {"release_control_list": [
        {"id": request_id, "response_code": 1}]}, to=IOP)
    assert [(o.destination, o.fields["response_code"]) for o in outs] == [(OTHER, 3)]
    wire.send("RequestHandoff", {"authority_code": 70, "explanation": ""}, to=IOP,
              source=OTHER)
    assert not named(wire.advance(19.5), "ConfirmHandoffRequest")
    outs = named(wire.advance(1.0), "ConfirmHandoffRequest")  # the hand-off timeout, 20 s
    assert [(o.destination, o.fields) for o in outs] == [(OTHER, {"id": 2, "response_code": 2})]
    assert wire.query("QueryHandoffTimeout", to=IOP).fields == {"timeout": 20}
    assert wire.query("QueryControl", to=IOP).fields["subsystem_id"] == 200


def test_no_go_zones_mark_the_cost_map_and_skid_steer_moves() -> None:
    wire = ready()
    zone = {"local_vertex_list": [{"x": -20.0, "y": -20.0}, {"x": -12.0, "y": -20.0},
                                  {"x": -12.0, "y": -12.0}]}
    before = wire.query("QueryCostMap2D", to=IOP).fields["cost_map2_d_data_var"]
    answer = wire.query("AddNoGoZone", {"request_id_rec": {"request_id": 3},
                                        "vertex_var": zone}, to=IOP)
    assert answer.fields == {"request_id": 3, "response_code": 0, "zone_id": 1}
    after = wire.query("QueryCostMap2D", to=IOP).fields["cost_map2_d_data_var"]
    blocked = lambda d: sum(c["cost"] == 254 for c in d["cost_data_list"])  # noqa: E731
    assert blocked(after) > blocked(before)
    assert len(wire.query("QueryNoGoZones", {"zone_id": 0}, to=IOP).fields[
        "no_go_zones_list"]) == 1
    wire.send("RemoveNoGoZone", {"zone_id": 1}, to=IOP)
    assert wire.query("QueryNoGoZones", {"zone_id": 0}, to=IOP).fields == {
        "no_go_zones_list": []}
    wire.send("SetSkidSteerEffort", {"left_side_propulsive_effort": 50.0,
                                     "right_side_propulsive_effort": 50.0}, to=IOP)
    wire.advance(2.0)
    assert wire.vehicle.motion.speed > 0.5
    # another client's commands are ignored
    wire.send("SetSkidSteerEffort", {"left_side_propulsive_effort": 0.0,
                                     "right_side_propulsive_effort": 0.0},
              to=IOP, source=OTHER)
    assert wire.query("QuerySkidSteerEffort", to=IOP).fields[
        "left_side_propulsive_effort"] == pytest.approx(50.0, abs=0.01)
