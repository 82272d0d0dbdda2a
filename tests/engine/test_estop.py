"""The emergency stop in the engine, on a fake clock: rules, retransmission, motion, Resume."""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.kit.actions import EMERGENCY_CLASS, PRIORITY_SAFETY

from .conftest import Harness, profile, published, sent
from .test_engine import ROBOT, VID, WRENCH, discover, keep_alive, take_control

OPERATORS = [{"id": "op1", "max_authority": 100}, {"id": "op2", "max_authority": 200},
             {"id": "op3", "max_authority": 50}]


def harness(catalogue: Any, **emergency: Any) -> Harness:
    from translators.core import CoreTranslator
    from translators.emergency import EmergencyTranslator
    from translators.mobility import MobilityTranslator

    prof = profile(operators=OPERATORS, emergency={"retry_period": 0.25, "max_attempts": 4,
                                                   **emergency})
    return Harness(catalogue, prof, [CoreTranslator(), EmergencyTranslator(),
                                     MobilityTranslator()])


def estop(h: Harness, action: str, operator: str = "op1", authority: int = 60,
          vehicle: str = VID) -> list[Any]:
    return h.sample("EmergencyCommand", {"vehicle_id": vehicle, "operator_id": operator,
                                         "action": action, "authority": authority,
                                         "reason": ""})


def last(h: Harness, topic: str) -> Any:
    return published(h.log, topic)[-1]


def test_set_goes_out_at_once_urgent_without_control_and_is_retried_until_confirmed(
        catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    out = estop(h, "SET")
    first = sent(out, "SetEmergency")
    assert [m.destination for m in first] == [h.engine.vehicle(VID).address]  # type: ignore
    assert first[0].traffic_class == EMERGENCY_CLASS and first[0].priority == PRIORITY_SAFETY
    assert first[0].fields == {"emergency_code": 1}
    assert not sent(h.log, "RequestControl"), "no control is needed"
    assert last(h, "VehicleStatus")["emergency"] is True
    assert last(h, "ControlStatus")["emergency"] is True
    # unconfirmed: again every retry_period, at most max_attempts times
    out = h.advance(2.0)
    assert len(sent(out, "SetEmergency")) == 3
    assert h.engine.counters["emergency_unconfirmed"] == 1
    # SET again starts over; a ReportStatus EMERGENCY ends it
    out = estop(h, "SET")
    assert len(sent(out, "SetEmergency")) == 1
    h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    assert not sent(h.advance(1.0), "SetEmergency")


def test_motion_refused_from_the_set_on_even_before_the_vehicle_confirms(
        catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h)
    h.sample("WrenchEffortCommand", WRENCH)
    estop(h, "SET")  # the queued command is dropped; the vehicle has not answered yet
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.5)
    assert not sent(out, "SetWrenchEffort")
    assert "refused: vehicle in EMERGENCY" in last(h, "ControlStatus")["last_rejection"]


def test_clear_rules(catalogue: Any) -> None:
    h = harness(catalogue)  # clear_by = "authority", the default
    discover(h)
    out = estop(h, "CLEAR")
    assert not sent(out, "ClearEmergency")
    assert "no emergency stop is set" in last(h, "ControlStatus")["last_rejection"]
    estop(h, "SET", "op1", 60)
    h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    for operator, authority, reason in (("op3", 50, "authority 50 below the setter's"),
                                        ("op1", 150, "authority 150 above its maximum"),
                                        ("nobody", 60, "not in the profile's")):
        out = estop(h, "CLEAR", operator, authority)
        assert not sent(out, "ClearEmergency"), operator
        assert reason in last(h, "ControlStatus")["last_rejection"]
    assert h.engine.counters["emergency_requests_refused"] == 4
    out = estop(h, "CLEAR", "op2", 60)
    assert sent(out, "ClearEmergency")[0].traffic_class == EMERGENCY_CLASS
    # the latch holds until the vehicle says it left EMERGENCY
    assert last(h, "VehicleStatus")["emergency"] is True
    h.deliver(ROBOT, "ReportStatus", {"status": 2, "reserved": 0})
    assert last(h, "VehicleStatus")["emergency"] is False
    assert h.engine.vehicle(VID).estop is None  # type: ignore[union-attr]


@pytest.mark.parametrize(("rule", "allowed"), [("setter", ["op1"]),
                                                ("operators", ["op2", "op3", "op1"])])
def test_clear_by_setter_or_any_operator(catalogue: Any, rule: str,
                                         allowed: list[str]) -> None:
    h = harness(catalogue, clear_by=rule)
    discover(h)
    estop(h, "SET", "op1", 60)
    h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    for operator in ("op2", "op3", "op1"):
        out = estop(h, "CLEAR", operator, 50)
        if operator in allowed:
            assert sent(out, "ClearEmergency"), operator
            return
        assert not sent(out, "ClearEmergency"), operator
        assert "refused" in last(h, "ControlStatus")["last_rejection"]


def test_set_by_operators_or_anyone(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    assert not sent(estop(h, "SET", "stranger"), "SetEmergency")
    assert "stranger" in last(h, "ControlStatus")["last_rejection"]
    h = harness(catalogue, set_by="anyone")
    discover(h)
    assert sent(estop(h, "SET", "stranger"), "SetEmergency")


def test_after_clear_resume_to_ready_before_any_motion(catalogue: Any) -> None:
    h = harness(catalogue)
    discover(h)
    take_control(h)
    estop(h, "SET")
    h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    # a component in EMERGENCY answers renewals NOT_AVAILABLE but keeps its controller
    h.advance(h.engine.profile.control.renewal_period + 0.1)
    h.deliver(ROBOT, "ConfirmControl", {"response_code": 1})
    assert last(h, "ControlStatus")["state"] == "CONTROLLED"
    estop(h, "CLEAR")
    out = h.deliver(ROBOT, "ReportStatus", {"status": 2, "reserved": 0})  # back in STANDBY
    assert sent(out, "Resume")
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.3)
    assert not sent(out, "SetWrenchEffort"), "motion before READY"
    h.deliver(ROBOT, "ReportStatus", {"status": 1, "reserved": 0})
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.3)
    assert sent(out, "SetWrenchEffort")


def test_set_kept_for_an_offline_or_unknown_vehicle(catalogue: Any) -> None:
    h = harness(catalogue)
    assert not sent(estop(h, "SET", vehicle=VID), "SetEmergency")  # not discovered yet
    out = discover(h)
    assert sent(out, "SetEmergency"), "not sent once discovered"
    h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    # lost (maybe rebooted): asked again once found
    out = h.advance(h.engine.profile.discovery.silence_timeout + 1.0)
    assert published(out, "VehicleStatus")[-1]["online"] is False
    assert not sent(out, "SetEmergency")
    out = h.deliver(ROBOT, "ReportHeartbeatPulse")
    assert sent(out, "SetEmergency")


def test_operator_lost_sets_the_emergency_only_with_the_option(catalogue: Any) -> None:
    for option, expected in ((False, 0), (True, 1)):
        h = harness(catalogue, on_operator_lost=option)
        discover(h)
        take_control(h, "op1", 70)
        h.engine.operator_lost("op2", h.now)  # holds nothing
        h.engine.operator_lost("op1", h.now)
        out = h.drain()
        assert len(sent(out, "SetEmergency")) == expected
        if option:
            status = last(h, "VehicleStatus")
            assert status["emergency_operator"] == "op1"
            assert "op1 vanished" in status["emergency_reason"]
            keep_alive(h, 0.5)
            # an operator of at least the vanished holder's authority may clear it
            assert sent(estop(h, "CLEAR", "op2", 70), "ClearEmergency")
