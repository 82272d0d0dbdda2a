"""Engine behaviour with a scripted JAUS++-like robot at 150.1.1 and a fake clock."""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import PluginConflictError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Command, DeclareVehicle, Publish, ShutdownComplete
from edge_vis.kit.contract import ReportSpec, Translator

from .conftest import Harness, profile, published, sent

ROBOT = "150.1.1"
VID = "JausppRobot-150"
SERVICES = [
    "urn:jaus:jss:core:Liveness", "urn:jaus:jss:core:Management",
    "urn:jaus:jss:mobility:GlobalPoseSensor", "urn:jaus:jss:mobility:VelocityStateSensor",
    "urn:jaus:jss:mobility:PrimitiveDriver",
]
WRENCH = {"vehicle_id": VID, "operator_id": "op1", "propulsive_linear_x": 50.0,
          "propulsive_linear_y": 0.0, "propulsive_linear_z": 0.0,
          "propulsive_rotational_x": 0.0, "propulsive_rotational_y": 0.0,
          "propulsive_rotational_z": 10.0}


def report_services(uris: list[str]) -> dict[str, Any]:
    return {"node_list": [{"node_rec": {"node_id": 1}, "component_list": [{
        "component_rec": {"component_id": 1, "instance_id": 0},
        "service_list": [{"uri": u, "major_version_number": 1, "minor_version_number": 0}
                         for u in uris]}]}]}


def discover(h: Harness, events: bool = True) -> list[Any]:
    """Identify the robot and give its services; confirm its CreateEvents if ``events``."""
    h.advance(0.1)
    h.deliver(ROBOT, "ReportIdentification",
              {"query_type": 2, "type": 10001, "identification": "JausppRobot"})
    out = h.deliver(ROBOT, "ReportServices", report_services(SERVICES))
    if events:
        for i, create in enumerate(sent(out, "CreateEvent")):
            out += h.deliver(ROBOT, "ConfirmEventRequest", {
                "request_id": create.fields["request_id"], "event_id": 0,
                "confirmed_periodic_rate": create.fields["requested_periodic_rate"]})
            assert i < 3
    return out


def take_control(h: Harness, operator: str = "op1", authority: int = 10) -> list[Any]:
    out = h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": operator,
                                      "authority": authority, "action": "request"})
    if sent(out, "RequestControl"):
        out += h.deliver(ROBOT, "ConfirmControl", {"response_code": 0})
        out += h.deliver(ROBOT, "ReportStatus", {"status": 1, "reserved": 0})
    return out


REPORTS = {"ReportGlobalPose": {"latitude": 28.5, "longitude": -81.4},
           "ReportVelocityState": {"velocity_x": 0.5}}


def keep_alive(h: Harness, seconds: float, step: float = 0.5, events: bool = False
               ) -> list[Any]:
    """Answer liveness every ``step``; with ``events``, deliver one Event per active event."""
    out: list[Any] = []
    for _ in range(int(seconds / step)):
        out += h.advance(step)
        out += h.deliver(ROBOT, "ReportHeartbeatPulse")
        if events:
            for sub in h.engine.snapshot().vehicles[0].subscriptions:
                if sub.state == "active":
                    report = h.catalogue.encode(sub.report, REPORTS[sub.report])
                    out += h.deliver(ROBOT, "Event", {"event_id": sub.event_id,
                                                      "sequence_number": 0,
                                                      "report_message": report})
    return out


# -- events -------------------------------------------------------------------------------


def test_events_created_for_wanted_reports_at_profile_rate(catalogue: Any) -> None:
    h = Harness(catalogue, profile(report_rates={"ReportGlobalPose": 2.0}))
    out = discover(h, events=False)
    creates = {catalogue.decode(c.fields["query_message"]).name: c for c in
               sent(out, "CreateEvent", ROBOT)}
    assert set(creates) == {"QueryGlobalPose", "QueryVelocityState"}
    assert creates["QueryGlobalPose"].fields["requested_periodic_rate"] == 2.0
    assert creates["QueryVelocityState"].fields["requested_periodic_rate"] == 5.0


def test_event_refreshed_at_half_the_reported_timeout(catalogue: Any) -> None:
    h = Harness(catalogue)
    out = discover(h)
    assert len(sent(out, "QueryEventTimeout", ROBOT)) == 1
    h.deliver(ROBOT, "ReportEventTimeout", {"timeout": 1})  # one minute
    out = keep_alive(h, 29.0, events=True)
    assert not sent(out, "CreateEvent")
    out = keep_alive(h, 2.0, events=True)
    assert len(sent(out, "CreateEvent", ROBOT)) == 2  # both subscriptions refreshed
    assert len(published(out, "GlobalPose")) == 4


def test_quiet_event_is_created_again_then_polled(catalogue: Any) -> None:
    """A provider that restarted within the silence timeout lost our events."""
    h = Harness(catalogue)
    discover(h)
    out = keep_alive(h, 5.5, events=True)
    assert not sent(out, "CreateEvent")
    # the robot restarts quickly: heartbeats go on, Events stop
    out = keep_alive(h, 6.5)
    recreated = sent(out, "CreateEvent", ROBOT)
    assert len(recreated) == 2
    for create in recreated:  # it confirms again ...
        h.deliver(ROBOT, "ConfirmEventRequest", {
            "request_id": create.fields["request_id"], "event_id": 1,
            "confirmed_periodic_rate": 5.0})
    out = keep_alive(h, 6.5, events=True)  # ... and delivers: no more re-creation
    assert not sent(out, "CreateEvent")
    assert published(out, "GlobalPose")
    # a provider that confirms but never delivers ends up polled
    for _ in range(3):
        out = keep_alive(h, 6.5)
        for create in sent(out, "CreateEvent", ROBOT):
            h.deliver(ROBOT, "ConfirmEventRequest", {
                "request_id": create.fields["request_id"], "event_id": 1,
                "confirmed_periodic_rate": 5.0})
    out = keep_alive(h, 1.0)
    assert sent(out, "QueryGlobalPose", ROBOT)
    subs = h.engine.snapshot().vehicles[0].subscriptions
    assert {s.state for s in subs} == {"polling"}
    assert subs[0].reason == "confirmed events never arrive"


def test_rejected_event_falls_back_to_polling(catalogue: Any) -> None:
    h = Harness(catalogue)
    out = discover(h, events=False)
    for create in sent(out, "CreateEvent"):
        h.deliver(ROBOT, "RejectEventRequest", {"request_id": create.fields["request_id"],
                                                "response_code": 1})
    out = keep_alive(h, 2.0)
    polls = sent(out, "QueryGlobalPose", ROBOT)
    assert 9 <= len(polls) <= 11  # 5 Hz
    assert polls[0].fields == {"presence_vector": 0x1FF}
    out = h.deliver(ROBOT, "ReportGlobalPose", {"latitude": 28.5, "longitude": -81.4})
    pose = published(out, "GlobalPose")[0]
    assert pose["latitude"] == pytest.approx(28.5, abs=1e-6)


def test_unanswered_event_falls_back_to_polling(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h, events=False)
    out = keep_alive(h, 5.5)
    assert len(sent(out, "CreateEvent", ROBOT)) == 2  # one retry each
    assert not sent(out, "QueryGlobalPose")
    out = keep_alive(h, 2.0)
    assert sent(out, "QueryGlobalPose", ROBOT)
    subs = h.engine.snapshot().vehicles[0].subscriptions
    assert {s.state for s in subs} == {"polling"}
    assert "no answer" in subs[0].reason


def test_jauspp_event_id_reuse_and_burst(catalogue: Any) -> None:
    """JAUS++ gives EventID 0 to both subscriptions and bursts 4 Events after a confirm."""
    h = Harness(catalogue)
    discover(h)
    pose = catalogue.encode("ReportGlobalPose", {"latitude": 28.538426, "yaw": 0.5})
    vel = catalogue.encode("ReportVelocityState", {"velocity_x": 0.5, "yaw_rate": 0.0})
    out: list[Any] = []
    for seq in range(4):  # the burst
        out += h.deliver(ROBOT, "Event", {"event_id": 0, "sequence_number": seq,
                                          "report_message": pose})
    out += h.deliver(ROBOT, "Event", {"event_id": 0, "sequence_number": 0,
                                      "report_message": vel})
    poses = published(out, "GlobalPose")
    assert len(poses) == 4
    assert poses[0]["latitude"] == pytest.approx(28.538426, abs=1e-6)
    assert poses[0]["longitude"] != poses[0]["longitude"]  # not reported -> NaN
    velocity = published(out, "Velocity")
    assert velocity[0]["vx"] == pytest.approx(0.5, abs=1e-3)
    subs = {s.report: s for s in h.engine.snapshot().vehicles[0].subscriptions}
    assert subs["ReportGlobalPose"].events_received == 4
    assert subs["ReportVelocityState"].events_received == 1
    assert h.engine.counters["events_unmatched"] == 0


def test_gaps_in_event_sequence_numbers_are_counted_as_missed(catalogue: Any) -> None:
    """A link that loses Events shows up as missed Events; repeats and wrap-around do not."""
    h = Harness(catalogue)
    discover(h)
    pose = catalogue.encode("ReportGlobalPose", {"latitude": 28.5, "yaw": 0.5})
    for seq in (250, 251, 251, 254, 255, 0, 3, 2):  # 2 lost, a repeat, wrap, 2 lost, one late
        h.deliver(ROBOT, "Event", {"event_id": 0, "sequence_number": seq,
                                   "report_message": pose})
    subs = {s.report: s for s in h.engine.snapshot().vehicles[0].subscriptions}
    assert subs["ReportGlobalPose"].events_received == 8
    assert subs["ReportGlobalPose"].events_missed == 4
    assert h.engine.counters["events_missed"] == 4


def test_the_captured_jauspp_event_bytes_are_unwrapped(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    # Event from captures-jauspp.md: EventID 0, seq 0, ReportVelocityState vx 0.5 m/s
    payload = bytes.fromhex("f1410000" "0e000000" "04444101" "32803280" "0080" "8a39d1b2")
    out = h.deliver_payload(ROBOT, payload)
    assert published(out, "Velocity")[0]["vx"] == pytest.approx(0.5, abs=1e-3)


# -- control ------------------------------------------------------------------------------


def test_control_renewed_before_reported_timeout(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    out = take_control(h)
    assert sent(out, "RequestControl", ROBOT)[0].fields == {"authority_code": 100}
    assert sent(out, "QueryTimeout", ROBOT)
    h.deliver(ROBOT, "ReportTimeout", {"timeout": 5})
    out = keep_alive(h, 10.0)
    renewals = sent(out, "RequestControl", ROBOT)
    assert len(renewals) == 4  # every 2.5 s


def test_refused_control_is_retried(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op1", "authority": 1,
                                "action": "request"})
    h.deliver(ROBOT, "ConfirmControl", {"response_code": 2})
    assert published(h.log, "ControlStatus")[-1]["state"] == "REJECTED"
    out = keep_alive(h, 5.5)
    assert len(sent(out, "RequestControl", ROBOT)) == 1


def test_emergency_blocks_motion_and_is_reported(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h)
    out = h.deliver(ROBOT, "ReportStatus", {"status": 5, "reserved": 0})
    assert published(out, "VehicleStatus")[-1]["state"] == "EMERGENCY"
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.2)
    assert not sent(out, "SetWrenchEffort")
    status = published(h.log, "ControlStatus")[-1]
    assert status["rejected_commands"] == 1 and "EMERGENCY" in status["last_rejection"]


# -- commands -----------------------------------------------------------------------------


def test_commands_throttled_latest_wins(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h)
    out: list[Any] = []
    for i in range(100):  # 100 Hz for one second
        out += h.sample("WrenchEffortCommand", {**WRENCH, "propulsive_linear_x": float(i)})
        out += h.advance(0.01)
    out += h.advance(0.1)
    cmds = sent(out, "SetWrenchEffort", ROBOT)
    assert 10 <= len(cmds) <= 11
    assert cmds[-1].fields["propulsive_linear_effort_x"] == 99.0  # the latest, not a stale one
    assert h.engine.vehicle(VID).commands["wrench_effort"].coalesced >= 85


def test_commands_wait_for_control_and_expire(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op1", "authority": 10,
                                "action": "request"})
    h.sample("WrenchEffortCommand", WRENCH)
    h.advance(0.6)  # longer than the 0.5 s lifespan, still not confirmed
    out = h.deliver(ROBOT, "ConfirmControl", {"response_code": 0})
    out += h.deliver(ROBOT, "ReportStatus", {"status": 1, "reserved": 0})
    out += h.advance(0.3)
    assert not sent(out, "SetWrenchEffort")
    assert h.engine.counters["commands_expired"] == 1
    # a fresh command goes once control is there
    out = h.sample("WrenchEffortCommand", WRENCH)
    assert sent(out, "SetWrenchEffort", ROBOT)


def test_deadman_sends_stop_once(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h)
    out = h.sample("WrenchEffortCommand", WRENCH)
    assert sent(out, "SetWrenchEffort")[0].fields["propulsive_linear_effort_x"] == 50.0
    out = keep_alive(h, 0.5)
    assert not sent(out, "SetWrenchEffort")
    out = keep_alive(h, 1.0)
    stops = sent(out, "SetWrenchEffort", ROBOT)
    assert len(stops) == 1
    assert set(stops[0].fields.values()) == {0.0}
    out = keep_alive(h, 3.0)
    assert not sent(out, "SetWrenchEffort")


# -- arbitration --------------------------------------------------------------------------


def test_arbitration_preemption_and_refusal(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h, "op1", 10)
    # op2 with lower authority is refused, its commands are not sent and are reported
    h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op2", "authority": 5,
                                "action": "request"})
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op1"
    out = h.sample("WrenchEffortCommand", {**WRENCH, "operator_id": "op2"})
    assert not sent(out, "SetWrenchEffort")
    status = published(out, "ControlStatus")[-1]
    assert status["rejected_commands"] == 1
    assert "op2" in status["last_rejection"] and "op1" in status["last_rejection"]
    # op3 with higher authority preempts; op1 is now refused
    h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op3", "authority": 50,
                                "action": "request"})
    assert published(h.log, "ControlStatus")[-1]["operator_id"] == "op3"
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.2)
    assert not sent(out, "SetWrenchEffort")
    out = h.sample("WrenchEffortCommand", {**WRENCH, "operator_id": "op3"})
    assert sent(out, "SetWrenchEffort", ROBOT)
    # last holder releases: the relay releases JAUS control
    out = h.sample("ControlRequest", {"vehicle_id": VID, "operator_id": "op3",
                                      "action": "release"})
    assert sent(out, "ReleaseControl", ROBOT)
    h.deliver(ROBOT, "RejectControl", {"response_code": 0})
    assert published(h.log, "ControlStatus")[-1]["state"] == "NOT_CONTROLLED"


# -- liveness -----------------------------------------------------------------------------


def test_lost_and_found_again_reestablishes_events_and_control(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h)
    out = keep_alive(h, 2.0)
    assert sent(out, "QueryHeartbeatPulse", ROBOT)
    out = h.advance(3.5)  # silence: 3 liveness periods
    assert published(out, "VehicleStatus")[-1]["online"] is False
    assert published(out, "VehicleStatus")[-1]["state"] == "OFFLINE"
    out = h.sample("WrenchEffortCommand", WRENCH) + h.advance(0.2)
    assert not sent(out, "SetWrenchEffort")
    # it answers again: events and control come back by themselves
    out = h.deliver(ROBOT, "ReportHeartbeatPulse")
    assert published(out, "VehicleStatus")[-1]["online"] is True
    assert len(sent(out, "CreateEvent", ROBOT)) == 2
    assert sent(out, "RequestControl", ROBOT)
    assert h.engine.snapshot().vehicles[0].view.controller == "op1"


def test_silent_vehicle_is_still_probed_and_rediscovered_after_restart(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    out = h.advance(10.0)
    assert sent(out, "QueryIdentification", "65535.255.255")  # discovery broadcast goes on
    assert sent(out, "QueryHeartbeatPulse", ROBOT)
    out = h.advance(20.0)  # while lost, probed once per discovery period (5 s)
    assert len(sent(out, "QueryHeartbeatPulse", ROBOT)) == 4
    out = h.deliver(ROBOT, "ReportIdentification",
                    {"query_type": 2, "type": 10001, "identification": "JausppRobot"})
    assert published(out, "VehicleStatus")[-1]["online"] is True


# -- shutdown -----------------------------------------------------------------------------


def test_shutdown_cancels_events_and_releases_control(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    take_control(h)
    h.engine.shutdown(h.now)
    out = h.drain()
    cancels = sent(out, "CancelEvent", ROBOT)
    assert len(cancels) == 2
    assert sent(out, "ReleaseControl", ROBOT)
    assert not any(isinstance(a, ShutdownComplete) for a in out)
    for cancel in cancels:
        h.deliver(ROBOT, "ConfirmEventRequest", {"request_id": cancel.fields["request_id"],
                                                 "event_id": 0, "confirmed_periodic_rate": 0})
    out = h.deliver(ROBOT, "RejectControl", {"response_code": 0})
    assert out[-1] == ShutdownComplete(0)
    assert h.engine.next_deadline() is None


def test_shutdown_completes_after_timeout_when_unanswered(catalogue: Any) -> None:
    h = Harness(catalogue)
    discover(h)
    h.engine.shutdown(h.now)
    h.drain()
    out = h.advance(5.0)
    assert ShutdownComplete(2) in out


# -- static vehicles, hello hook, manager ---------------------------------------------------


def test_static_vehicle_from_profile(catalogue: Any) -> None:
    prof = profile(vehicles=[{"vehicle_id": "ugv1", "address": ROBOT,
                              "services": SERVICES}])
    h = Harness(catalogue, prof)
    out = h.advance(1.1)
    assert published(out, "VehicleIdentification")[0]["vehicle_id"] == "ugv1"
    assert sent(out, "QueryHeartbeatPulse", ROBOT)
    out = h.deliver(ROBOT, "ReportHeartbeatPulse")
    assert len(sent(out, "CreateEvent", ROBOT)) == 2


def test_translator_can_declare_a_vehicle(catalogue: Any) -> None:
    class Declarer(Translator):
        name = "declarer"
        subscribes = ("Hello",)

        def on_sample(self, topic: str, sample: Any, ctx: Any) -> list[Any]:
            addr = JausAddress.parse(sample["address"])
            return [DeclareVehicle(sample["vehicle_id"],
                                   {addr: (("urn:jaus:jss:mobility:GlobalPoseSensor", "1.0"),)},
                                   name="hello")]

    from translators.core import CoreTranslator
    from translators.mobility import MobilityTranslator

    h = Harness(catalogue, translators=[CoreTranslator(), MobilityTranslator(), Declarer()])
    out = h.sample("Hello", {"vehicle_id": "custom1", "address": "77.1.5"})
    assert published(out, "VehicleIdentification")[0]["vehicle_id"] == "custom1"
    assert sent(out, "CreateEvent", "77.1.5")


class HelloTranslator(Translator):
    """Plays a vendor hello: a vehicle without JAUS discovery announces itself with a
    ReportTime (any message the translator claims would do)."""

    name = "hello"
    messages = ("ReportTime",)

    def on_message(self, name: str, fields: Any, ctx: Any) -> list[Any]:
        if ctx.vehicle is not None:
            return []
        return [DeclareVehicle("vendor-uuv", {ctx.source: (
            ("urn:jaus:jss:mobility:GlobalPoseSensor", "1.0"),
            ("urn:jaus:jss:mobility:PrimitiveDriver", "1.0"))}, name="Vendor UUV",
            vehicle_type="UUV")]


def test_custom_hello_declares_a_vehicle(catalogue: Any) -> None:
    from translators.core import CoreTranslator
    from translators.mobility import MobilityTranslator

    h = Harness(catalogue, translators=[CoreTranslator(), MobilityTranslator(),
                                        HelloTranslator()])
    h.advance(0.1)
    out = h.deliver("88.1.3", "ReportTime", {})
    ident = published(out, "VehicleIdentification")
    assert [i["vehicle_id"] for i in ident] == ["vendor-uuv"]
    assert ident[0]["jaus_address"] == "88.1.3" and ident[0]["vehicle_type"] == "UUV"
    assert published(out, "VehicleStatus")[-1]["online"] is True
    assert len(sent(out, "CreateEvent", "88.1.3")) == 1  # GlobalPose from the declared service
    # the next hello changes nothing and is not republished
    out = h.deliver("88.1.3", "ReportTime", {})
    assert not published(out, "VehicleIdentification")
    # and the vehicle can be commanded like any other
    out = h.sample("ControlRequest", {"vehicle_id": "vendor-uuv", "operator_id": "op",
                                      "authority": 1, "action": "REQUEST"})
    assert sent(out, "RequestControl", "88.1.3")


def test_conflicting_translators_are_refused_naming_both() -> None:
    class A(Translator):
        name = "alpha"
        messages = ("ReportGlobalPose",)

    class B(Translator):
        name = "beta"
        messages = ("ReportGlobalPose",)

    with pytest.raises(PluginConflictError, match=r"alpha.*beta"):
        TranslationManager([A(), B()])

    class C(Translator):
        name = "gamma"
        subscribes = ("ControlRequest",)

    with pytest.raises(PluginConflictError, match=r"engine.*gamma"):
        TranslationManager([C()])


def test_report_must_be_listed_in_messages() -> None:
    from edge_vis.errors import PluginLoadError

    class D(Translator):
        name = "delta"
        reports = (ReportSpec("ReportGlobalPose", "QueryGlobalPose", "urn:x"),)

    with pytest.raises(PluginLoadError, match="delta"):
        TranslationManager([D()])


def test_translators_selected_by_profile_without_code_change() -> None:
    from edge_vis.config import TranslatorSelection

    manager = TranslationManager.from_selection(TranslatorSelection(("*",), ("mobility",)))
    names = [t.name for t in manager.translators]
    assert "core" in names and "mobility" not in names
    manager = TranslationManager.from_selection(TranslatorSelection(("mobility",), ()))
    assert [t.name for t in manager.translators] == ["mobility"]


def test_engine_actions_are_values() -> None:
    a = Publish("GlobalPose", {"vehicle_id": "x"})
    assert a == Publish("GlobalPose", {"vehicle_id": "x"})
    c = Command("v", "o", "k", "SetWrenchEffort", {}, "urn:x")
    with pytest.raises(AttributeError):
        c.kind = "other"  # type: ignore[misc]


def test_services_asked_for_all_then_for_explicit_components(catalogue: Any) -> None:
    h = Harness(catalogue)
    h.advance(0.1)
    out = h.deliver("126.1.199", "ReportIdentification",
                    {"query_type": 2, "type": 10001, "identification": "SimulatedVehicle"})
    first = sent(out, "QueryServices", "126.1.199")[0].fields
    assert first == {"node_list": [{"node_rec": {"node_id": 255},
                                    "component_list": [{"component_id": 255}]}]}
    assert sent(out, "QueryConfiguration", "126.1.199")[0].fields == {"query_type": 2}
    h.deliver("126.1.199", "ReportConfiguration", {"node_list": [
        {"node_rec": {"node_id": 1}, "component_list": [
            {"component_id": 1, "instance_id": 0}, {"component_id": 199, "instance_id": 0}]}]})
    out = h.advance(3.0)
    second = sent(out, "QueryServices", "126.1.199")[0].fields
    assert second == {"node_list": [{"node_rec": {"node_id": 1}, "component_list": [
        {"component_id": 199}, {"component_id": 1}]}]}
    # the JTS answer lists node 1 twice: both services land on 126.1.199
    out = h.deliver("126.1.199", "ReportServices", {"node_list": [
        {"node_rec": {"node_id": 1}, "component_list": [{
            "component_rec": {"component_id": 199, "instance_id": 0},
            "service_list": [{"uri": "urn:jaus:jss:mobility:LocalPoseSensor",
                              "major_version_number": 1, "minor_version_number": 0}]}]},
        {"node_rec": {"node_id": 1}, "component_list": [{
            "component_rec": {"component_id": 199, "instance_id": 0},
            "service_list": [{"uri": "urn:jaus:jss:mobility:LocalWaypointListDriver",
                              "major_version_number": 1, "minor_version_number": 0}]}]}]})
    components = h.engine.snapshot().vehicles[0].view.components
    assert list(components) == [JausAddress(126, 1, 199)]
    uris = {uri for uri, _ in components[JausAddress(126, 1, 199)]}
    assert "urn:jaus:jss:mobility:LocalWaypointListDriver" in uris
    assert "urn:jaus:jss:core:AccessControl" in uris
    out = h.advance(10.0)
    assert not sent(out, "QueryServices")  # known now: no more asking
