"""Access control and management of a simulated vehicle (sans-I/O, fake clock)."""

from __future__ import annotations

from conftest import OCU, OTHER, PLATFORM, Wire, named, spec

INSUFFICIENT_AUTHORITY = 2
NOT_AVAILABLE = 1


def test_control_is_granted_reported_and_released(wire: Wire) -> None:
    wire.advance(1.0)
    assert wire.query("QueryControl").fields == {
        "subsystem_id": 0, "node_id": 0, "component_id": 0, "authority_code": 0}
    wire.take_control(authority=80)
    assert wire.query("QueryControl").fields == {
        "subsystem_id": 200, "node_id": 1, "component_id": 1, "authority_code": 80}
    assert wire.query("QueryAuthority").fields == {"authority_code": 80}
    assert wire.query("QueryTimeout").fields == {"timeout": 5}
    out = wire.query("ReleaseControl")
    assert (out.name, out.destination, out.fields) == ("RejectControl", OCU,
                                                        {"response_code": 0})
    assert wire.query("QueryControl").fields["subsystem_id"] == 0


def test_lower_or_equal_authority_is_refused_higher_preempts(wire: Wire) -> None:
    wire.advance(1.0)
    wire.take_control(authority=100)
    for authority in (50, 100):
        out = wire.query("RequestControl", {"authority_code": authority}, source=OTHER)
        assert (out.name, out.destination) == ("ConfirmControl", OTHER)
        assert out.fields["response_code"] == INSUFFICIENT_AUTHORITY
    outs = wire.send("RequestControl", {"authority_code": 150}, source=OTHER)
    assert [(o.name, o.destination, o.fields["response_code"]) for o in outs] == [
        ("RejectControl", OCU, 0), ("ConfirmControl", OTHER, 0)]
    assert wire.query("QueryControl").fields["subsystem_id"] == 201


def test_default_authority_is_enforced() -> None:
    wire = Wire(spec(default_authority=60))
    wire.advance(1.0)
    out = wire.query("RequestControl", {"authority_code": 59})
    assert out.fields["response_code"] == INSUFFICIENT_AUTHORITY
    wire.take_control(authority=60)


def test_control_times_out_unless_renewed(wire: Wire) -> None:
    wire.advance(1.0)
    wire.take_control()
    for _ in range(4):  # renewing every 3 s keeps control for 12 s
        assert named(wire.advance(3.0), "RejectControl") == []
        wire.take_control()
    outs = wire.advance(4.9)
    assert named(outs, "RejectControl") == []
    outs = wire.advance(0.2)
    rejects = named(outs, "RejectControl")
    assert [(o.destination, o.fields) for o in rejects] == [(OCU, {"response_code": 0})]
    assert wire.query("QueryControl").fields["subsystem_id"] == 0
    assert wire.vehicle.counters["control_timeouts"] == 1


def test_standby_resume_only_from_the_controller(wire: Wire) -> None:
    assert wire.query("QueryStatus").fields["status"] == 0  # INITIALIZE
    wire.advance(1.0)
    assert wire.query("QueryStatus").fields["status"] == 2  # STANDBY
    wire.send("Resume")  # not controlled: ignored
    assert wire.query("QueryStatus").fields["status"] == 2
    wire.take_control()
    wire.send("Resume", source=OTHER)
    assert wire.query("QueryStatus").fields["status"] == 2
    wire.send("Resume")
    assert wire.query("QueryStatus").fields["status"] == 1  # READY
    wire.send("Standby")
    assert wire.query("QueryStatus").fields["status"] == 2


def test_emergency_from_anyone_blocks_control_and_motion(wire: Wire) -> None:
    wire.ready()
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 50.0})
    wire.advance(2.0)
    assert wire.vehicle.motion.speed > 1.0
    wire.send("SetEmergency", {"emergency_code": 1}, source=OTHER)
    assert wire.query("QueryStatus").fields["status"] == 5
    wire.advance(2.0)
    assert abs(wire.vehicle.motion.speed) < 0.01
    out = wire.query("RequestControl", {"authority_code": 200}, source=OTHER)
    assert out.fields["response_code"] == NOT_AVAILABLE
    wire.send("ClearEmergency", {"emergency_code": 1})  # not the one who set it
    assert wire.query("QueryStatus").fields["status"] == 5
    wire.send("ClearEmergency", {"emergency_code": 1}, source=OTHER)
    assert wire.query("QueryStatus").fields["status"] == 1


def test_emergency_keeps_its_controller_as_the_management_jsidl_says(wire: Wire) -> None:
    """Receiving.Ready.Controlled.NotAvailable.Emergency: RequestControl gets NOT_AVAILABLE
    even from the controller, ReleaseControl gets RejectControl NOT_AVAILABLE, control does
    not time out, Resume/Standby/Reset/Shutdown/SetAuthority are ignored; every client that
    set an emergency must clear it, then the component pops back to where it was."""
    wire.ready()
    wire.send("SetEmergency", {"emergency_code": 1})
    wire.send("SetEmergency", {"emergency_code": 1}, source=OTHER)
    out = wire.query("RequestControl", {"authority_code": 100})  # the controller renews
    assert (out.name, out.fields["response_code"]) == ("ConfirmControl", NOT_AVAILABLE)
    out = wire.query("ReleaseControl")
    assert (out.name, out.fields["response_code"]) == ("RejectControl", NOT_AVAILABLE)
    for name in ("Resume", "Standby", "Reset", "Shutdown"):
        assert wire.send(name) == []
    wire.send("SetAuthority", {"authority_code": 90})
    assert named(wire.advance(12.0), "RejectControl") == []  # 5 s timeout: not in EMERGENCY
    assert wire.query("QueryControl").fields["subsystem_id"] == 200
    assert wire.query("QueryAuthority").fields["authority_code"] == 100
    wire.send("ClearEmergency", {"emergency_code": 1})
    assert wire.query("QueryStatus").fields["status"] == 5  # OTHER's is still set
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 50.0})
    wire.send("ClearEmergency", {"emergency_code": 1}, source=OTHER)
    assert wire.query("QueryStatus").fields["status"] == 1  # back to READY, controlled
    assert wire.vehicle.counters["emergency_clears_ignored"] == 0
    wire.send("ClearEmergency", {"emergency_code": 1})  # nothing stored any more
    assert wire.vehicle.counters["emergency_clears_ignored"] == 1
    assert named(wire.advance(4.0), "RejectControl") == []  # a full timeout after the pop
    assert wire.query("QueryControl").fields["subsystem_id"] == 200
    assert abs(wire.vehicle.motion.speed) < 0.01  # the effort sent in EMERGENCY was ignored


def test_wrench_effort_drives_only_from_controller_in_ready(wire: Wire) -> None:
    wire.advance(1.0)
    wire.take_control()
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 100.0})  # STANDBY: ignored
    wire.advance(1.0)
    assert wire.vehicle.motion.speed == 0.0
    wire.send("Resume")
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 100.0}, source=OTHER)
    wire.advance(1.0)
    assert wire.vehicle.motion.speed == 0.0
    assert wire.vehicle.counters["commands_ignored"] == 2
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 50.0,
                                  "propulsive_rotational_effort_z": 20.0})
    wire.take_control()  # renew within the 5 s control timeout
    wire.advance(4.0)
    wire.take_control()
    velocity = wire.query("QueryVelocityState", {"presence_vector": 0xFFFF}).fields
    assert abs(velocity["velocity_x"] - 1.5) < 0.05  # 50 % of 3 m/s
    assert abs(velocity["yaw_rate"] - 0.2) < 0.01  # 20 % of 1 rad/s, turning right
    pose = wire.query("QueryLocalPose", {"presence_vector": 0xFFFF}).fields
    assert pose["x"] > 3.0 and pose["y"] > 0.5  # went north, curving east
    effort = wire.query("QueryWrenchEffort", {"presence_vector": 0xFFFF}).fields
    assert set(effort) == {"propulsive_linear_effort_x", "propulsive_rotational_effort_z"}
    assert abs(effort["propulsive_linear_effort_x"] - 50.0) < 0.01
    wire.send("ReleaseControl")  # losing control stops the vehicle
    wire.advance(3.0)
    assert abs(wire.vehicle.motion.speed) < 0.01
    assert wire.query("QueryStatus").fields["status"] == 2


def test_query_presence_vector_selects_report_fields(wire: Wire) -> None:
    pose = wire.query("QueryGlobalPose", {"presence_vector": 0b1000011}).fields
    assert set(pose) == {"latitude", "longitude", "yaw"}
    assert abs(pose["latitude"] - 36.5965) < 1e-6


def test_refuse_control_fault() -> None:
    wire = Wire(spec(faults={"refuse_control": True}))
    wire.advance(1.0)
    out = wire.query("RequestControl", {"authority_code": 255})
    assert out.fields["response_code"] == NOT_AVAILABLE


def test_jts_example_quirks_initialize_forever_but_accepts_control() -> None:
    wire = Wire(spec(faults={"jts_example": True}))
    wire.advance(5.0)
    assert wire.query("QueryStatus").fields["status"] == 0
    assert wire.send("QueryTimeout") == []
    assert wire.send("QueryEventTimeout") == []
    query = wire.payload("QueryGlobalPose", {"presence_vector": 3})
    assert wire.send("CreateEvent", {"request_id": 1, "event_type": 0,
                                     "requested_periodic_rate": 5.0,
                                     "query_message": query}) == []
    wire.take_control()
    wire.send("Resume")
    assert wire.query("QueryStatus").fields["status"] == 0
    wire.send("SetWrenchEffort", {"propulsive_linear_effort_x": 50.0})
    wire.advance(2.0)
    assert wire.vehicle.motion.speed > 1.0
    assert wire.query("QueryHeartbeatPulse", to=PLATFORM).name == "ReportHeartbeatPulse"
