"""Message names two service sets share (``ExecuteList``: mobility 0x041E, manipulator
0x061E) are sent with the right code: the command names its set, the engine carries it to
the SendMessage, and the runtime encodes by (name, set)."""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.errors import EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Publish, SendMessage
from edge_vis.shell.relay import _code_of

from .conftest import Harness, profile, sent

ROBOT = "150.1.1"
VID = "Arm-150"
MANIP = "urn:jaus:jss:manipulator:"
MOB = "urn:jaus:jss:mobility:"
SERVICES = ["urn:jaus:jss:core:AccessControl", "urn:jaus:jss:core:Management",
            "urn:jaus:jss:core:Liveness", "urn:jaus:jss:core:Events",
            MANIP + "ManipulatorJointPositionsListDriver", MOB + "GlobalWaypointListDriver"]


def _harness(catalogue: Any) -> Harness:
    from translators.core import CoreTranslator
    from translators.manipulator import ManipulatorTranslator
    from translators.mobility import MobilityTranslator

    h = Harness(catalogue, profile(commands={"rate": 100.0, "lifespan": 5.0,
                                             "deadman_timeout": 30.0}),
                [CoreTranslator(), ManipulatorTranslator(), MobilityTranslator()])
    h.advance(0.1)
    h.deliver(ROBOT, "ReportIdentification", {"query_type": 2, "type": 10001,
                                              "identification": "Arm"})
    h.deliver(ROBOT, "ReportServices", {"node_list": [{"node_rec": {"node_id": 1},
        "component_list": [{"component_rec": {"component_id": 1, "instance_id": 0},
                            "service_list": [{"uri": u, "major_version_number": 1,
                                              "minor_version_number": 0}
                                             for u in SERVICES]}]}]})
    h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op1", "authority": 10,
                                "action": "request"})
    h.deliver(ROBOT, "ConfirmControl", {"response_code": 0})
    h.deliver(ROBOT, "ReportStatus", {"status": 1, "reserved": 0})
    return h


def _payload(catalogue: Any, action: SendMessage) -> bytes:
    return catalogue.encode(_code_of(catalogue, action), action.fields)


def test_manipulator_execute_list_goes_out_as_0x061e(catalogue: Any) -> None:
    h = _harness(catalogue)
    out = h.sample("JointCommand", {"vehicle_id": VID, "operator_id": "op1",
                                    "device": "manipulator", "quantity": "execute_list",
                                    "values": [3.0]})
    out += h.advance(0.2)
    (send,) = sent(out, "ExecuteList", ROBOT)
    assert send.service_set == "manipulator" and dict(send.fields) == {"element_uid": 3}
    payload = _payload(catalogue, send)
    assert payload[:2] == bytes.fromhex("1e06")
    decoded = catalogue.decode(payload)
    assert decoded.code == 0x061E and decoded.fields == {"element_uid": 3}


def test_mobility_execute_list_goes_out_as_0x041e(catalogue: Any) -> None:
    h = _harness(catalogue)
    out = h.sample("WaypointPlan", {"vehicle_id": VID, "operator_id": "op1", "plan_id": "p",
                                    "frame": "GLOBAL", "speed": 2.0,
                                    "waypoints": [{"latitude": 1.0, "longitude": 2.0}]})
    out += h.advance(0.2)
    for _ in range(2):  # DeleteElement, then SetElement, each confirmed
        (request,) = [a for a in out if isinstance(a, SendMessage)
                      and a.name in ("DeleteElement", "SetElement")][-1:]
        out = h.deliver(ROBOT, "ConfirmElementRequest",
                        {"request_id": request.fields["request_id_rec"]["request_id"]})
        out += h.advance(0.2)
    (send,) = sent(out, "ExecuteList", ROBOT)
    assert send.service_set == "mobility"
    payload = _payload(catalogue, send)
    assert payload[:2] == bytes.fromhex("1e04")
    assert catalogue.decode(payload).fields["speed"] == pytest.approx(2.0, abs=0.01)


def test_unnamed_set_encodes_by_name_and_an_unknown_set_is_an_encode_error(
        catalogue: Any) -> None:
    to = JausAddress(1, 1, 1)
    assert _code_of(catalogue, SendMessage(to, "QueryStatus")) == "QueryStatus"
    with pytest.raises(EncodeError, match="'ExecuteList' in service set 'ugv'"):
        _code_of(catalogue, SendMessage(to, "ExecuteList", {}, service_set="ugv"))


def test_deadman_stop_keeps_the_service_set() -> None:
    from edge_vis.config import CommandProfile
    from edge_vis.engine.command_slots import CommandSlot
    from edge_vis.kit.actions import Command

    slot = CommandSlot(CommandProfile(rate=10.0, lifespan=0.5, deadman_timeout=1.0))
    slot.offer(Command("v", "op", "k", "ExecuteList", {"element_uid": 1}, "svc",
                       stop={"element_uid": 0}, service_set="manipulator"), 0.0)
    assert slot.take(0.0) is not None
    assert slot.arm_deadman(2.0)
    stop = slot.take(2.0)
    assert stop is not None and stop.service_set == "manipulator"
    assert dict(stop.fields) == {"element_uid": 0}


def test_one_component_with_both_list_drivers_reports_each_active_element(
        catalogue: Any) -> None:
    """Each set's ReportActiveElement is asked for with its own query and reaches the
    translator of its set; the List Manager's reports reach both."""
    h = _harness(catalogue)
    h.advance(1.0)
    creates = [catalogue.decode(a.fields["query_message"])
               for a in sent(h.log, "CreateEvent", ROBOT)]
    assert {q.code for q in creates if q.name == "QueryActiveElement"} == {0x241E, 0x261E}
    out = h.sample("ManipulatorPlan", {"vehicle_id": VID, "operator_id": "op1", "plan_id": "arm",
                                       "mode": "joint_positions",
                                       "targets": [{"values": [0.1]}, {"values": [0.2]}]})
    out += h.sample("WaypointPlan", {"vehicle_id": VID, "operator_id": "op1", "plan_id": "p",
                                     "frame": "GLOBAL", "speed": 2.0,
                                     "waypoints": [{"latitude": 1.0, "longitude": 2.0}] * 2})
    # each loader's requests answered in turn: each waits for its own request IDs
    out += h.advance(0.2)
    for _ in range(10):
        requests = [a for a in out if isinstance(a, SendMessage)
                    and a.name in ("DeleteElement", "SetElement")]
        if not requests:
            break
        out = []
        for request in requests:
            out += h.deliver(ROBOT, "ConfirmElementRequest",
                             {"request_id": request.fields["request_id_rec"]["request_id"]})
        out += h.advance(0.2)
    assert {a.service_set for a in sent(h.log, "ExecuteList", ROBOT)} == {"mobility",
                                                                         "manipulator"}
    for code, topic, member in ((0x461E, "ManipulatorPlanStatus", "active_target"),
                                (0x441E, "MissionStatus", "active_waypoint")):
        payload = catalogue.encode(code, {"element_uid": 2})
        out = h.deliver_payload(ROBOT, payload)
        assert [(a.topic, a.sample[member]) for a in out if isinstance(a, Publish)] == \
            [(topic, 1)]
    out = h.deliver(ROBOT, "ReportElementList", {"element_list": [{"element_uid": 1}]})
    assert {a.topic for a in out if isinstance(a, Publish)} == {"VehiclePlan",
                                                                "ManipulatorList"}
