"""Hand-off between operators (IOP EnhancedAccessControl / HandoffController), on the
engine with a fake clock: the holder sees each request and decides; timeouts as the
service defines them; never two holders."""

from __future__ import annotations

from typing import Any

import pytest

from translators.core import CoreTranslator
from translators.iop import IopTranslator
from translators.mobility import MobilityTranslator

from .conftest import Harness, profile, published, sent
from .test_engine import (
    ROBOT,
    VID,
    WRENCH,
    discover,
    keep_alive,
    report_services,
    take_control,
)

EAC = "urn:jaus:jss:iop:EnhancedAccessControl"


def harness(catalogue: Any, **control: Any) -> Harness:
    prof = profile(control={"handoff_timeout": 5.0, **control})
    return Harness(catalogue, prof, [CoreTranslator(), MobilityTranslator(), IopTranslator()])


def ask(h: Harness, operator: str, authority: int = 10, action: str = "REQUEST",
        why: str = "my turn") -> list[Any]:
    return h.sample("HandoffRequest", {"vehicle_id": VID, "operator_id": operator,
                                       "authority": authority, "explanation": why,
                                       "action": action})


def answer(h: Harness, operator: str, request_id: int, response: str) -> list[Any]:
    return h.sample("HandoffResponse", {"vehicle_id": VID, "operator_id": operator,
                                        "request_id": request_id, "response": response})


def status(h: Harness) -> dict[str, Any]:
    return dict(published(h.log, "HandoffStatus")[-1])


def drives(h: Harness, operator: str) -> bool:
    out = h.sample("WrenchEffortCommand", {**WRENCH, "operator_id": operator})
    out += h.advance(0.2)
    return bool(sent(out, "SetWrenchEffort", ROBOT))


def test_holder_sees_the_request_and_grants_it(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    ask(h, "op2", 20, why="take over the survey")
    seen = status(h)
    assert seen["holder"] == "op1" and seen["handoff_timeout"] == 5.0
    (request,) = seen["requests"]
    assert (request["requester"], request["authority"], request["explanation"],
            request["state"]) == ("op2", 20, "take over the survey", "PENDING")
    # the requester cannot answer its own request, nor drive yet
    answer(h, "op2", request["request_id"], "GRANTED")
    assert status(h)["requests"][0]["state"] == "PENDING"
    assert not drives(h, "op2")
    out = answer(h, "op1", request["request_id"], "GRANTED")
    assert not sent(out, "ReleaseControl")  # the relay keeps JAUS control: no gap
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op2"
    assert status(h)["holder"] == "op2"
    assert status(h)["requests"][0]["state"] == "GRANTED"
    assert drives(h, "op2") and not drives(h, "op1")


def test_refused_request_changes_nothing(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    ask(h, "op2")
    request_id = status(h)["requests"][0]["request_id"]
    answer(h, "op1", request_id, "DENIED")
    assert status(h)["requests"][0]["state"] == "DENIED"
    assert "op1" in status(h)["requests"][0]["reason"]
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op1"
    assert drives(h, "op1") and not drives(h, "op2")
    # a decided request cannot be granted afterwards
    answer(h, "op1", request_id, "GRANTED")
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op1"


def test_unanswered_request_times_out_and_wait_restarts_the_timer(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    ask(h, "op2")
    request_id = status(h)["requests"][0]["request_id"]
    keep_alive(h, 4.0)
    answer(h, "op1", request_id, "WAIT")
    assert status(h)["requests"][0]["state"] == "DEFERRED"
    keep_alive(h, 4.0)  # 8 s after the request, 4 s after WAIT: still open
    assert status(h)["requests"][0]["state"] == "DEFERRED"
    keep_alive(h, 1.5)
    entry = status(h)["requests"][0]
    assert entry["state"] == "TIMEOUT" and "did not answer" in entry["reason"]
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op1"
    assert drives(h, "op1")


def test_requester_must_reassert_within_the_enhanced_timeout(catalogue: Any) -> None:
    h = harness(catalogue, handoff_timeout=0.0, handoff_reassert_timeout=2.0)
    discover(h)
    take_control(h, "op1", 10)
    ask(h, "op2")
    keep_alive(h, 1.5)
    ask(h, "op2")  # renewed: the same request
    keep_alive(h, 1.5)
    (entry,) = status(h)["requests"]
    assert entry["state"] == "PENDING"
    keep_alive(h, 1.0)
    entry = status(h)["requests"][0]
    assert entry["state"] == "TIMEOUT" and "did not ask again" in entry["reason"]


def test_one_grant_denies_the_others_and_cancel_withdraws(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    ask(h, "op2")
    ask(h, "op3")
    ask(h, "op4")
    ask(h, "op4", action="CANCEL")
    by = {e["requester"]: e for e in status(h)["requests"]}
    assert by["op4"]["state"] == "CANCELLED"
    answer(h, "op1", by["op3"]["request_id"], "GRANTED")
    by = {e["requester"]: e for e in status(h)["requests"]}
    assert (by["op2"]["state"], by["op3"]["state"]) == ("DENIED", "GRANTED")
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op3"


def test_free_vehicle_and_operator_allowlist(catalogue: Any) -> None:
    prof = profile(control={"handoff_timeout": 5.0},
                   operators=[{"id": "op1", "max_authority": 50},
                              {"id": "op2", "max_authority": 5}])
    h = Harness(catalogue, prof, [CoreTranslator(), MobilityTranslator(), IopTranslator()])
    discover(h)
    ask(h, "op2", 1)  # nobody holds it: take it with ControlRequest instead
    assert status(h)["requests"][0]["state"] == "DENIED"
    take_control(h, "op1", 10)
    ask(h, "op2", 40)
    entry = status(h)["requests"][-1]
    assert entry["state"] == "INSUFFICIENT_AUTHORITY"


def test_another_jaus_client_asks_through_the_vehicle(catalogue: Any) -> None:
    h = harness(catalogue)
    keep_alive(h, 0.1)
    h.deliver(ROBOT, "ReportIdentification",
              {"query_type": 2, "type": 10001, "identification": "JausppRobot"})
    out = h.deliver(ROBOT, "ReportServices", report_services([
        "urn:jaus:jss:core:Liveness", "urn:jaus:jss:core:Management", EAC,
        "urn:jaus:jss:mobility:PrimitiveDriver"]))
    out += h.advance(0.1)
    assert sent(out, "QueryHandoffTimeout", ROBOT) and sent(out, "QueryEnhancedTimeout", ROBOT)
    h.deliver(ROBOT, "ReportHandoffTimeout", {"timeout": 3})
    take_control(h, "op1", 10)
    h.deliver(ROBOT, "RequestReleaseControl", {"request_release_control_list": [
        {"id": 7, "src_subsystem_id": 300, "src_node_id": 1, "src_component_id": 5,
         "authority_code": 30, "explanation": "convoy lead"}]})
    seen = status(h)
    assert seen["vehicle_handoff_timeout"] == 3.0
    (entry,) = seen["requests"]
    assert (entry["requester"], entry["via"], entry["authority"]) == (
        "jaus:300.1.5", ROBOT, 30)
    out = answer(h, "op1", entry["request_id"], "WAIT")
    (confirm,) = sent(out, "ConfirmReleaseControl", ROBOT)
    assert confirm.fields == {"release_control_list": [{"id": 7, "response_code": 2}]}
    out = answer(h, "op1", entry["request_id"], "GRANTED")
    (confirm,) = sent(out, "ConfirmReleaseControl", ROBOT)
    assert confirm.fields["release_control_list"][0]["response_code"] == 0
    # the vehicle is the other client's now: nobody here holds it, the relay lets go
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == ""
    assert sent(out, "ReleaseControl", ROBOT)
    assert not drives(h, "op1")


@pytest.mark.parametrize("response", ["DENIED", "TIMEOUT"])
def test_jaus_request_refused_or_lapsed(catalogue: Any, response: str) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    listing = {"request_release_control_list": [
        {"id": 2, "src_subsystem_id": 300, "src_node_id": 1, "src_component_id": 5,
         "authority_code": 30, "explanation": ""}]}
    h.deliver(ROBOT, "RequestReleaseControl", listing)
    h.deliver(ROBOT, "RequestReleaseControl", listing)  # listed again: one request
    (entry,) = status(h)["requests"]
    if response == "DENIED":
        out = answer(h, "op1", entry["request_id"], "DENIED")
        assert sent(out, "ConfirmReleaseControl")[0].fields["release_control_list"] == [
            {"id": 2, "response_code": 1}]
    else:
        keep_alive(h, 5.5)
    assert status(h)["requests"][0]["state"] == response
    assert drives(h, "op1")
    # the vehicle stops listing a request: withdrawn
    h.deliver(ROBOT, "RequestReleaseControl", listing)
    h.deliver(ROBOT, "RequestReleaseControl", {"request_release_control_list": []})
    assert status(h)["requests"][-1]["state"] == "CANCELLED"


def test_operator_asks_a_vehicle_another_client_holds(catalogue: Any) -> None:
    h = harness(catalogue)
    h.advance(0.1)
    h.deliver(ROBOT, "ReportIdentification",
              {"query_type": 2, "type": 10001, "identification": "JausppRobot"})
    h.deliver(ROBOT, "ReportServices", report_services([
        "urn:jaus:jss:core:Liveness", "urn:jaus:jss:core:Management", EAC,
        "urn:jaus:jss:mobility:PrimitiveDriver"]))
    h.deliver(ROBOT, "ReportControl", {"subsystem_id": 300, "node_id": 1, "component_id": 9,
                                       "authority_code": 120})
    out = ask(h, "op1", 90, why="need it")
    (request,) = sent(out, "RequestHandoff", ROBOT)
    assert request.fields == {"authority_code": 90, "explanation": "need it"}
    assert not sent(out, "RequestControl")
    h.deliver(ROBOT, "ConfirmHandoffRequest", {"id": 6, "response_code": 4})  # QUEUED
    (entry,) = status(h)["requests"]
    assert (entry["requester"], entry["state"], entry["via"]) == ("op1", "PENDING", ROBOT)
    # the holder here is nobody: no operator may answer in the vehicle's place
    answer(h, "op1", entry["request_id"], "GRANTED")
    assert status(h)["requests"][0]["state"] == "PENDING"
    out = ask(h, "op1", action="CANCEL")
    assert sent(out, "RemoveHandoffRequest", ROBOT)[0].fields == {"id": 6}
    assert status(h)["requests"][0]["state"] == "CANCELLED"
    ask(h, "op1", 90)
    h.deliver(ROBOT, "ConfirmHandoffRequest", {"id": 7, "response_code": 3})  # DENIED
    assert status(h)["requests"][-1]["state"] == "DENIED"
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == ""
    ask(h, "op1", 90)
    out = h.deliver(ROBOT, "ConfirmHandoffRequest", {"id": 8, "response_code": 0})
    assert status(h)["requests"][-1]["state"] == "GRANTED"
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op1"
    assert sent(out, "RequestControl", ROBOT)  # the relay confirms the control it was given
