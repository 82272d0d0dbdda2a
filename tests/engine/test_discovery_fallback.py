"""Discovery against robots that read the discovery wildcards their own way (fake clock).

JAUS++ answers QueryServices for node/component 255 with an empty list; the relay must ask
by explicit ID and serve the robot anyway, with no vehicle profile. The JAUS Toolset example
answers the wildcard but never QueryConfiguration; nothing extra may be asked of it.
"""

from __future__ import annotations

import logging
from typing import Any

import pytest
from discovery_peers import (
    WILDCARD_EXCHANGE,
    EnginePeers,
    JausppRobot,
    JtsExample,
    names,
)

from edge_vis.engine.discovery import MAX_ASKS
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import unpack_datagram

from .conftest import Harness, profile, published, sent

ROBOT = "150.1.1"
VID = "JausppRobot-150"
EXPLICIT_1_1 = {"node_list": [{"node_rec": {"node_id": 1},
                               "component_list": [{"component_id": 1}]}]}
WILDCARD = {"node_list": [{"node_rec": {"node_id": 255},
                           "component_list": [{"component_id": 255}]}]}


def observed(catalogue: Any) -> dict[str, Any]:
    """The observed exchange: message name -> (packet, decoded message)."""
    out = {}
    for _src, _dst, name, hexdata in WILDCARD_EXCHANGE:
        [packet] = unpack_datagram(bytes.fromhex(hexdata))
        out[name] = (packet, catalogue.decode(packet.payload))
    return out


def identify(h: Harness, name: str = "JausppRobot", query_type: int = 2) -> list[Any]:
    h.advance(0.1)
    return h.deliver(ROBOT, "ReportIdentification",
                     {"query_type": query_type, "type": 10001, "identification": name})


def services(uris: list[str], node: int = 1, component: int = 1) -> dict[str, Any]:
    return {"node_list": [{"node_rec": {"node_id": node}, "component_list": [{
        "component_rec": {"component_id": component, "instance_id": 0},
        "service_list": [{"uri": u, "major_version_number": 1, "minor_version_number": 0}
                         for u in uris]}]}]}


def configuration(*components: tuple[int, int]) -> dict[str, Any]:
    nodes: dict[int, list[int]] = {}
    for node, comp in components:
        nodes.setdefault(node, []).append(comp)
    return {"node_list": [{"node_rec": {"node_id": n}, "component_list": [
        {"component_id": c, "instance_id": 0} for c in comps]} for n, comps in nodes.items()]}


# -- the observed bytes ---------------------------------------------------------------------


def test_observed_wildcard_exchange_decodes(catalogue: Any) -> None:
    seen = observed(catalogue)
    for src, dst, name, _hex in WILDCARD_EXCHANGE:
        packet, message = seen[name]
        assert (str(packet.source), str(packet.destination)) == (src, dst)
        assert message.name == name
    assert seen["QueryServices"][1].fields == WILDCARD
    assert seen["ReportConfiguration"][1].fields == configuration((1, 1))
    assert seen["ReportServices"][1].fields == {"node_list": []}


def test_relay_and_test_robot_produce_the_observed_bytes(catalogue: Any) -> None:
    """The engine asks exactly what the relay asked; the test robot answers as JAUS++ did."""
    seen = observed(catalogue)
    h = Harness(catalogue)
    [query] = sent(identify(h), "QueryServices", ROBOT)
    assert catalogue.encode("QueryServices", query.fields) == seen["QueryServices"][0].payload
    robot = JausppRobot(catalogue)
    relay = JausAddress(42, 1, 1)
    robot.known.add(42)
    [(_to, name, fields)] = robot.handle(relay, "QueryServices",
                                         seen["QueryServices"][1].fields, 0.0)
    assert catalogue.encode(name, fields) == seen["ReportServices"][0].payload
    [(_to, name, fields)] = robot.handle(relay, "QueryConfiguration", {"query_type": 2}, 0.0)
    assert catalogue.encode(name, fields) == seen["ReportConfiguration"][0].payload
    # asked by ID, or with an empty list, it lists its 11 services
    for query_fields in (EXPLICIT_1_1, {"node_list": []}):
        [(_to, _name, fields)] = robot.handle(relay, "QueryServices", query_fields, 0.0)
        assert len(fields["node_list"][0]["component_list"][0]["service_list"]) == 11


def test_observed_empty_answer_makes_the_relay_ask_by_id(catalogue: Any) -> None:
    seen = observed(catalogue)
    h = Harness(catalogue)
    identify(h)
    h.deliver_payload(ROBOT, seen["ReportConfiguration"][0].payload)
    out = h.deliver_payload(ROBOT, seen["ReportServices"][0].payload)
    assert [q.fields for q in sent(out, "QueryServices", ROBOT)] == [EXPLICIT_1_1]
    assert not h.engine.vehicle(VID).services_known  # an empty list proves nothing
    counters = h.engine.counters
    assert counters["discovery_empty_answers"] == 1
    assert counters["discovery_fallbacks"] == 1
    assert counters["discovery_queries_sent"] == 3  # configuration, wildcard, by ID


# -- the JAUS++ robot, served without a vehicle profile -----------------------------------------


def test_jauspp_robot_fully_served_without_profile(
    catalogue: Any, caplog: pytest.LogCaptureFixture
) -> None:
    h = Harness(catalogue)
    robot = JausppRobot(catalogue)
    peers = EnginePeers(h, robot)
    with caplog.at_level(logging.DEBUG, logger="edge_vis.engine.discovery"):
        out = peers.run(3.0)

    # discovery: the wildcard came back empty, the explicit query brought the services
    asked = names(robot, "QueryServices")
    assert asked == [WILDCARD, EXPLICIT_1_1]
    ident = published(out, "VehicleIdentification")[-1]
    assert ident["vehicle_id"] == VID and ident["name"] == "JausppRobot"
    uris = {s["uri"] for s in ident["services"]}
    assert {"urn:jaus:jss:mobility:GlobalPoseSensor",
            "urn:jaus:jss:mobility:PrimitiveDriver"} <= uris
    counters = h.engine.counters
    assert counters["discovery_empty_answers"] == 1
    assert counters["discovery_fallbacks"] == 1
    assert counters["discovery_queries_sent"] == 3
    log = caplog.text
    assert "ReportServices lists no component" in log
    assert "QueryServices for 1.1 (the answer was empty)" in log
    assert "ReportServices for 1.1" in log

    # events: created, confirmed, and poses published from the Events
    assert names(robot, "CreateEvent")
    poses = published(out, "GlobalPose")
    assert poses and poses[-1]["latitude"] == pytest.approx(28.538426, abs=1e-5)
    assert {s.state for s in h.engine.snapshot().vehicles[0].subscriptions} == {"active"}

    # control: an operator takes the vehicle, the relay holds JAUS control past the
    # robot's 5 s timeout, and commands reach the primitive driver
    peers.route(h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op1",
                                            "authority": 10, "action": "request"}))
    peers.run(2.0)
    assert robot.controller == h.engine.profile.jaus_id and robot.status == 1  # READY
    assert published(h.log, "ControlStatus")[-1]["state"] == "CONTROLLED"
    peers.route(h.sample("WrenchEffortCommand", {"vehicle_id": VID, "operator_id": "op1",
                                                 "propulsive_linear_x": 40.0}))
    peers.run(8.0)
    assert robot.commands and robot.commands[0][0] == "SetWrenchEffort"
    assert robot.commands[0][1]["propulsive_linear_effort_x"] == pytest.approx(40.0, abs=0.01)
    assert robot.controller == h.engine.profile.jaus_id and robot.control_timeouts == 0
    assert len(names(robot, "QueryServices")) == 2  # nothing asked once known
    assert "OFFLINE" not in {s["state"] for s in published(h.log, "VehicleStatus")}


def test_empty_answer_before_configuration_asks_the_identified_component(
    catalogue: Any
) -> None:
    h = Harness(catalogue)
    identify(h)
    out = h.deliver(ROBOT, "ReportServices", {"node_list": []})
    assert [q.fields for q in sent(out, "QueryServices", ROBOT)] == [EXPLICIT_1_1]
    out = h.deliver(ROBOT, "ReportConfiguration", configuration((1, 1)))
    assert not sent(out, "QueryServices")  # asked for 1.1 already
    out = h.deliver(ROBOT, "ReportServices", services(["urn:jaus:jss:core:Liveness"]))
    assert h.engine.vehicle(VID).services_known
    out += h.advance(30.0)
    assert not sent(out, "QueryServices")


def test_component_left_out_of_the_wildcard_answer_is_asked_for(catalogue: Any) -> None:
    h = Harness(catalogue)
    identify(h)
    h.deliver(ROBOT, "ReportConfiguration", configuration((1, 1), (1, 2)))
    out = h.deliver(ROBOT, "ReportServices", services(["urn:jaus:jss:core:Liveness"]))
    # served with what is known at once, and the missing component asked for by ID
    assert h.engine.vehicle(VID).services_known
    assert [q.fields for q in sent(out, "QueryServices", ROBOT)] == [
        {"node_list": [{"node_rec": {"node_id": 1}, "component_list": [{"component_id": 2}]}]}]
    out = h.deliver(ROBOT, "ReportServices",
                    services(["urn:jaus:jss:mobility:GlobalPoseSensor"], component=2))
    creates = sent(out, "CreateEvent", "150.1.2")
    assert [catalogue.decode(c.fields["query_message"]).name for c in creates] == \
        ["QueryGlobalPose"]
    uris = {s["uri"] for s in published(out, "VehicleIdentification")[-1]["services"]}
    assert "urn:jaus:jss:mobility:GlobalPoseSensor" in uris
    out = h.advance(30.0)
    assert not sent(out, "QueryServices")
    assert h.engine.counters["discovery_fallbacks"] == 1


class _EmptyRobot(JausppRobot):
    """Answers every QueryServices with no node at all."""

    def services_report(self, query: Any) -> dict[str, Any]:
        return {"node_list": []}


def test_robot_answering_nothing_is_asked_a_bounded_number_of_times(
    catalogue: Any, caplog: pytest.LogCaptureFixture
) -> None:
    h = Harness(catalogue, profile(discovery={"period": 5.0, "response_timeout": 3.0}))
    robot = _EmptyRobot(catalogue)
    peers = EnginePeers(h, robot)
    with caplog.at_level(logging.WARNING):
        out = peers.run(120.0, step=0.25)
    assert len(names(robot, "QueryServices")) == MAX_ASKS
    # never "no services": nothing subscribed, and the operators see no service list
    assert not names(robot, "CreateEvent")
    assert not h.engine.vehicle(VID).services_known
    assert all(not s["services"] for s in published(out, "VehicleIdentification"))
    assert h.engine.counters["discovery_gave_up"] == 1
    assert "no services reported after 8 queries" in caplog.text
    assert h.engine.snapshot().vehicles[0].view.online

    # lost, then heard again: discovery starts over
    EnginePeers(h).run(10.0, step=0.25)
    assert not h.engine.snapshot().vehicles[0].view.online
    peers.run(6.0, step=0.25)
    assert h.engine.snapshot().vehicles[0].view.online
    assert len(names(robot, "QueryServices")) > MAX_ASKS


def test_empty_configuration_makes_the_relay_ask_the_node(catalogue: Any) -> None:
    h = Harness(catalogue)
    out = identify(h)
    assert [q.fields for q in sent(out, "QueryConfiguration", ROBOT)] == [{"query_type": 2}]
    out = h.deliver(ROBOT, "ReportConfiguration", {"node_list": []})
    assert [q.fields for q in sent(out, "QueryConfiguration", ROBOT)] == [{"query_type": 3}]
    h.deliver(ROBOT, "ReportConfiguration", configuration((1, 1), (1, 2)))
    out = h.advance(3.0)
    assert [q.fields for q in sent(out, "QueryServices", ROBOT)] == [
        {"node_list": [{"node_rec": {"node_id": 1},
                        "component_list": [{"component_id": 1}, {"component_id": 2}]}]}]
    assert not sent(out, "QueryConfiguration")  # known now
    assert h.engine.counters["discovery_empty_answers"] == 1


def test_nameless_identification_asks_the_component(catalogue: Any) -> None:
    h = Harness(catalogue)
    out = identify(h, name="")
    assert [q.fields for q in sent(out, "QueryIdentification", ROBOT)] == [{"query_type": 2}]
    h.deliver(ROBOT, "ReportIdentification", {"query_type": 2, "type": 10001,
                                              "identification": ""})
    out = h.advance(3.0)
    asked = [q.fields for q in sent(out, "QueryIdentification", ROBOT)]
    assert {"query_type": 4} in asked
    out = h.deliver(ROBOT, "ReportIdentification", {"query_type": 4, "type": 60001,
                                                    "identification": "SimRobot"})
    assert published(out, "VehicleIdentification")[-1]["name"] == "SimRobot"
    assert h.engine.counters["discovery_empty_answers"] == 2
    out = h.advance(10.0)
    assert {"query_type": 4} not in [q.fields for q in sent(out, "QueryIdentification")]


# -- the JAUS Toolset example ------------------------------------------------------------------


def test_jts_example_served_without_extra_queries(catalogue: Any) -> None:
    h = Harness(catalogue, profile(discovery={"liveness_period": 1.0}))
    jts = JtsExample()
    peers = EnginePeers(h, jts)
    out = peers.run(12.0, step=0.1)

    ident = published(out, "VehicleIdentification")[-1]
    assert ident["vehicle_id"] == "SimulatedVehicle-126"
    uris = {s["uri"] for s in ident["services"]}
    assert {"urn:jaus:jss:mobility:LocalPoseSensor",
            "urn:jaus:jss:mobility:LocalWaypointListDriver",
            "urn:jaus:jss:core:Management"} <= uris
    # the wildcard answer was complete: no configuration needed, nothing asked by ID
    assert names(jts, "QueryServices") == [WILDCARD]
    assert len(names(jts, "QueryConfiguration")) == 1
    assert h.engine.counters["discovery_fallbacks"] == 0
    # CreateEvent ignored: the pose is polled
    assert names(jts, "CreateEvent")
    assert len(published(out, "LocalPose")) >= 5
    # control works though it reports INITIALIZE forever and ignores QueryTimeout
    peers.route(h.sample("ControlRequest", {"vehicle_id": "SimulatedVehicle-126",
                                            "operator_id": "op1", "authority": 5,
                                            "action": "request"}))
    peers.run(8.0, step=0.1)
    assert jts.controller == h.engine.profile.jaus_id
    assert published(h.log, "ControlStatus")[-1]["state"] == "CONTROLLED"
    assert len(names(jts, "Resume")) == 3  # bounded, then the relay proceeds
    # it answers a component query with its subsystem identification
    [(_to, _name, answer)] = jts.handle(JausAddress(42, 1, 1), "QueryIdentification",
                                        {"query_type": 4}, 0.0)
    assert answer["query_type"] == 2 and answer["identification"] == "SimulatedVehicle"


def test_both_robots_on_one_relay(catalogue: Any) -> None:
    h = Harness(catalogue)
    robot, jts = JausppRobot(catalogue), JtsExample()
    out = EnginePeers(h, robot, jts).run(8.0)
    served = {p["vehicle_id"] for p in published(out, "GlobalPose")} | {
        p["vehicle_id"] for p in published(out, "LocalPose")}
    assert served == {VID, "SimulatedVehicle-126"}
