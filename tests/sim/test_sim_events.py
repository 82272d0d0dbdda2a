"""The Events service of a simulated vehicle (sans-I/O, fake clock)."""

from __future__ import annotations

from conftest import OCU, OTHER, PLATFORM, SENSORS, Wire, named, spec

PERIODIC, EVERY_CHANGE = 0, 1


def create(wire: Wire, query: str, qfields: dict, *, event_type: int = PERIODIC,
           rate: float = 0.0, request_id: int = 7, to=PLATFORM, source=OCU):
    return wire.send("CreateEvent", {
        "request_id": request_id, "event_type": event_type, "requested_periodic_rate": rate,
        "query_message": wire.payload(query, qfields)}, to=to, source=source)


def test_periodic_event_arrives_at_the_confirmed_rate(wire: Wire) -> None:
    outs = create(wire, "QueryGlobalPose", {"presence_vector": 0x03}, rate=5.0)
    confirm = outs[0]
    assert confirm.name == "ConfirmEventRequest"
    assert confirm.fields["request_id"] == 7
    assert abs(confirm.fields["confirmed_periodic_rate"] - 5.0) < 0.01
    event_id = confirm.fields["event_id"]
    events = named(wire.advance(10.0), "Event")
    assert 49 <= len(events) <= 51
    assert {e.fields["event_id"] for e in events} == {event_id}
    assert [e.fields["sequence_number"] for e in events] == list(range(len(events)))
    assert {e.report.name for e in events} == {"ReportGlobalPose"}
    assert set(events[0].report.fields) == {"latitude", "longitude"}  # the query's PV
    assert {e.destination for e in events} == {OCU}


def test_rate_above_the_maximum_is_confirmed_lower() -> None:
    wire = Wire(spec(max_event_rate=10.0))
    confirm = create(wire, "QueryHeartbeatPulse", {}, rate=50.0)[0]
    assert abs(confirm.fields["confirmed_periodic_rate"] - 10.0) < 0.02
    assert 19 <= len(named(wire.advance(2.0), "Event")) <= 21


def test_every_change_event_fires_only_on_change(wire: Wire) -> None:
    outs = create(wire, "QueryStatus", {}, event_type=EVERY_CHANGE)
    assert [o.name for o in outs] == ["ConfirmEventRequest", "Event"]  # current value first
    assert outs[0].fields["confirmed_periodic_rate"] == 0
    assert outs[1].report.fields["status"] == 0
    outs = wire.advance(2.0)  # INITIALIZE -> STANDBY after 0.5 s, then nothing
    assert [o.report.fields["status"] for o in named(outs, "Event")] == [2]
    assert named(wire.advance(3.0), "Event") == []
    wire.take_control()
    outs = wire.send("Resume")
    assert [(o.report.fields["status"], o.fields["sequence_number"]) for o in outs] == [(1, 2)]


def test_same_query_again_updates_the_existing_event(wire: Wire) -> None:
    first = create(wire, "QueryVelocityState", {"presence_vector": 1}, rate=2.0)[0]
    again = create(wire, "QueryVelocityState", {"presence_vector": 3}, rate=4.0,
                   request_id=8)[0]
    assert again.fields["event_id"] == first.fields["event_id"]
    assert again.fields["request_id"] == 8
    events = named(wire.advance(5.0), "Event")
    assert 19 <= len(events) <= 21
    assert set(events[-1].report.fields) == {"velocity_x", "velocity_y"}
    other = create(wire, "QueryVelocityState", {"presence_vector": 1}, rate=2.0,
                   source=OTHER)[0]
    assert other.fields["event_id"] != first.fields["event_id"]


def test_update_and_cancel(wire: Wire) -> None:
    event_id = create(wire, "QueryLocalPose", {"presence_vector": 1}, rate=1.0)[0].fields[
        "event_id"]
    out = wire.query("UpdateEvent", {
        "request_id": 9, "event_type": PERIODIC, "requested_periodic_rate": 10.0,
        "event_id": event_id, "query_message": wire.payload("QueryLocalPose",
                                                            {"presence_vector": 1})})
    assert (out.name, out.fields["event_id"]) == ("ConfirmEventRequest", event_id)
    assert 9 <= len(named(wire.advance(1.0), "Event")) <= 11
    listed = wire.query("QueryEvents", {"query_events_var": {"event_id_rec": {
        "event_id": event_id}}}).fields["event_list"]
    assert [e["event_id"] for e in listed] == [event_id]
    out = wire.query("CancelEvent", {"request_id": 10, "event_id": event_id})
    assert (out.name, out.fields["event_id"]) == ("ConfirmEventRequest", event_id)
    assert named(wire.advance(2.0), "Event") == []
    out = wire.query("CancelEvent", {"request_id": 11, "event_id": event_id})
    assert (out.name, out.fields["response_code"]) == ("RejectEventRequest", 6)


def test_unsupported_or_bad_event_requests_are_rejected(wire: Wire) -> None:
    # the platform component has no range sensor
    out = create(wire, "QueryRangeSensorData", {"query_range_sensor_data_list": []}, rate=1)[0]
    assert (out.name, out.fields["response_code"]) == ("RejectEventRequest", 5)
    out = create(wire, "QueryGlobalPose", {"presence_vector": 1}, rate=0.0)[0]
    assert (out.name, out.fields["response_code"]) == ("RejectEventRequest", 4)
    ok = create(wire, "QueryRangeSensorData", {"query_range_sensor_data_list": [
        {"sensor_id": 1, "report_coordinate_system": 0, "query_presence_vector": 0}]},
        rate=1.0, to=SENSORS)
    assert ok[0].name == "ConfirmEventRequest"


def test_events_expire_when_not_renewed() -> None:
    wire = Wire(spec(event_timeout=1))
    assert wire.query("QueryEventTimeout").fields == {"timeout": 1}
    create(wire, "QueryHeartbeatPulse", {}, rate=1.0)
    create(wire, "QueryStatus", {}, rate=1.0)
    for _ in range(3):  # renew the status event every 40 s
        wire.advance(40.0, step=0.25)
        create(wire, "QueryStatus", {}, rate=1.0)
    outs = wire.advance(5.0, step=0.25)
    assert {o.report.name for o in named(outs, "Event")} == {"ReportStatus"}
    assert wire.vehicle.component(2).events.expired == 1


def test_reject_events_fault() -> None:
    wire = Wire(spec(faults={"reject_events": frozenset({"QueryGlobalPose"})}))
    out = create(wire, "QueryGlobalPose", {"presence_vector": 1}, rate=1.0)[0]
    assert (out.name, out.fields["response_code"]) == ("RejectEventRequest", 3)
    assert create(wire, "QueryLocalPose", {"presence_vector": 1},
                  rate=1.0)[0].name == "ConfirmEventRequest"


def test_sequence_numbers_wrap_per_event(wire: Wire) -> None:
    create(wire, "QueryHeartbeatPulse", {}, rate=25.0)
    create(wire, "QueryStatus", {}, rate=1.0)
    events = named(wire.advance(12.0, step=0.01), "Event")
    pulses = [e.fields["sequence_number"] for e in events if e.report.name ==
              "ReportHeartbeatPulse"]
    status = [e.fields["sequence_number"] for e in events if e.report.name == "ReportStatus"]
    assert pulses[255:258] == [255, 0, 1]
    assert status == list(range(len(status)))
