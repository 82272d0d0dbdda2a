"""The engine applies the bandwidth plan: planned rates in CreateEvent, UpdateEvent when a
vehicle joins or leaves, nothing orphaned when a report is dropped. Sans-I/O, fake clock."""

from __future__ import annotations

from typing import Any

from edge_vis.bandwidth.demands import FleetPlanner
from edge_vis.catalogue import default_catalogue
from edge_vis.config import from_mapping
from edge_vis.engine.engine import Engine
from edge_vis.engine.subscriptions import SubscriptionState
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import SendMessage
from translators.mobility import MobilityTranslator

CAT = default_catalogue()
POSE_SENSOR = "urn:jaus:jss:mobility:GlobalPoseSensor"
LIVENESS = "urn:jaus:jss:core:Liveness"


def relay(vehicles: int = 3, bit_rate: int = 9600) -> Any:
    return from_mapping({
        "links": {"radio": {"url": "serial:///dev/null", "bit_rate": bit_rate,
                            "bits_per_byte": 10, "reserve": 0.0, "budget": 0.8}},
        "report_rates": {"ReportGlobalPose": {"desired": 10.0, "minimum": 1.0}},
        "vehicles": [{"vehicle_id": f"v{i}", "address": f"{101 + i}.1.1", "link": "radio",
                      "services": [POSE_SENSOR, LIVENESS]} for i in range(vehicles)],
    })


def engine(profile: Any) -> Engine:
    specs = {lp.name: lp.spec for lp in profile.links}
    return Engine(profile, [MobilityTranslator()], catalogue=CAT,
                  planner=FleetPlanner(profile, specs, CAT))


def hello(e: Engine, address: JausAddress, now: float) -> None:
    e.receive_message(address, CAT.decode(CAT.encode("ReportHeartbeatPulse", {})), now)


def sent(e: Engine, name: str) -> list[SendMessage]:
    return [a for a in e.drain_actions() if isinstance(a, SendMessage) and a.name == name]


def confirm(e: Engine, create: SendMessage, event_id: int, now: float) -> None:
    e.receive_message(create.destination, CAT.decode(CAT.encode("ConfirmEventRequest", {
        "request_id": create.fields["request_id"], "event_id": event_id,
        "confirmed_periodic_rate": create.fields["requested_periodic_rate"]})), now)


def test_vehicles_of_the_profile_share_the_link_from_the_first_createevent() -> None:
    e = engine(relay(3))
    e.on_timer(0.0)
    e.drain_actions()
    hello(e, JausAddress(101, 1, 1), 0.1)
    [create] = sent(e, "CreateEvent")
    # 9600 bit/s x 80% = 768 B/s for three vehicles (two not heard yet): not 10 Hz
    rate = create.fields["requested_periodic_rate"]
    assert 1.0 <= rate < 4.0
    assert create.traffic_class == "telemetry"


def test_a_vehicle_leaving_gives_its_share_back_with_updateevent() -> None:
    profile = relay(2)
    e = engine(profile)
    e.on_timer(0.0)
    creates = []
    for i in range(2):
        hello(e, JausAddress(101 + i, 1, 1), 0.1)
        creates += sent(e, "CreateEvent")
    for i, create in enumerate(creates):
        confirm(e, create, 7 + i, 0.2)
    e.drain_actions()
    before = e.vehicle("v0").subscriptions  # type: ignore[union-attr]
    [sub] = [s for s in before.values() if s.report == "ReportGlobalPose"]
    old_rate = sub.rate
    # v1 goes silent; v0 keeps talking
    now = 0.2
    while now < 6.0:
        now += 0.5
        hello(e, JausAddress(101, 1, 1), now)
        e.on_timer(now)
    updates = [a for a in e.drain_actions()
               if isinstance(a, SendMessage) and a.name == "UpdateEvent"]
    assert not e.vehicle("v1").online  # type: ignore[union-attr]
    assert updates and updates[-1].destination == JausAddress(101, 1, 1)
    assert updates[-1].fields["event_id"] == 7  # the same event, updated in place
    assert updates[-1].fields["requested_periodic_rate"] > old_rate
    assert sub.state is SubscriptionState.ACTIVE


def test_a_report_dropped_while_createevent_is_in_flight_is_cancelled_once_confirmed() -> None:
    from edge_vis.config import EventsProfile
    from edge_vis.engine.subscriptions import Subscription

    ids = iter(range(1, 100))
    sub = Subscription(JausAddress(101, 1, 1), "ReportGlobalPose", "QueryGlobalPose", {},
                       2.0, False, EventsProfile(), lambda n, f: b"\x02\x24", lambda: next(ids))
    [create] = sub.start(0.0)
    assert create.name == "CreateEvent"
    assert sub.cancel(0.1) == []  # nothing to cancel yet
    [cancel] = sub.on_confirm(event_id=9, rate=2.0, now=0.2)
    assert cancel.name == "CancelEvent" and cancel.fields["event_id"] == 9
    sub.on_confirm(event_id=9, rate=0.0, now=0.3)
    assert sub.state is SubscriptionState.DONE


def test_update_rejected_means_create_again_and_plan_while_creating_updates_after() -> None:
    from edge_vis.config import EventsProfile
    from edge_vis.engine.subscriptions import Subscription

    ids = iter(range(1, 100))
    sub = Subscription(JausAddress(101, 1, 1), "ReportGlobalPose", "QueryGlobalPose", {},
                       2.0, False, EventsProfile(), lambda n, f: b"\x02\x24", lambda: next(ids))
    sub.start(0.0)
    assert sub.update_rate(5.0, 0.1) == []  # in flight: remembered
    [update] = sub.on_confirm(event_id=4, rate=2.0, now=0.2)
    assert update.name == "UpdateEvent" and update.fields["requested_periodic_rate"] == 5.0
    [again] = sub.on_reject(code=6, now=0.3)  # provider does not update events
    assert again.name == "CreateEvent" and again.fields["requested_periodic_rate"] == 5.0
    assert sub.state is SubscriptionState.ACTIVE  # never fell back to polling
