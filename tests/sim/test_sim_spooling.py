"""The simulated vehicle's Mission Spooler and Global Path Segment Driver, through the real
catalogue: who may send what in which state, as the JSIDL protocol says."""

from __future__ import annotations

import math

from conftest import OTHER, PLATFORM, Wire

from edge_vis.tools.sim.kinematics import Origin

INIT, RUNNING, PAUSED, ABORTED, FINISHED = 0, 1, 3, 5, 7


def message(wire: Wire, uid: int, speed: float, blocking: int = 0) -> dict:
    return {"uid": uid, "destination_id": {"subsystem_id": 101, "node_id": 1,
                                           "component_id": 2},
            "jaus_message": wire.payload("SetTravelSpeed", {"speed": speed}),
            "blocking": blocking}


def mission(wire: Wire, mission_id: int = 7) -> dict:
    root = {"task_data": {"task_info": {"task_id": 1}, "jaus_messages": [
        message(wire, 1, 1.0), message(wire, 2, 2.0, blocking=1)]},
        "sub_tasks": [{"child_task_index": 1}]}
    child = {"task_data": {"task_info": {"task_id": 2}, "jaus_messages": [
        message(wire, 3, 3.0)]}, "sub_tasks": []}
    return {"mission_info": {"mission_id": mission_id, "source_id": {
        "subsystem_id": 200, "node_id": 1, "component_id": 1}}, "mission_plan": [root, child]}


def status(wire: Wire) -> tuple[int, int, int]:
    fields = wire.query("QueryMissionStatus").fields
    return fields["id"], fields["status"], fields["secondary_status"]


def keep(wire: Wire, seconds: float) -> None:
    for _ in range(int(seconds)):
        wire.take_control()
        wire.advance(1.0, step=0.1)


def test_a_spooled_mission_runs_pauses_resumes_and_finishes(wire: Wire) -> None:
    wire.ready()
    assert status(wire) == (0, INIT, 0)
    # only the controlling client may spool
    wire.send("SpoolMission", mission(wire), source=OTHER)
    assert wire.query("QueryStoredMissions").fields == {"mission_list": []}
    wire.send("SpoolMission", mission(wire))
    assert wire.query("QueryStoredMissions").fields == {"mission_list": [{
        "mission_id": 7, "creator_id": {"subsystem_id": 200, "node_id": 1,
                                        "component_id": 1}}]}
    plan = wire.query("QueryMissionPlan", {"mission_id": 7}).fields
    assert plan["task"]["task_data"]["task_info"]["task_id"] == 1
    assert wire.send("QueryMissionPlan", {"mission_id": 8}) == []
    # a second mission is not taken while one is held; RESUME is ignored before RUN
    wire.send("SpoolMission", mission(wire, 9))
    wire.send("ResumeMission", {"mission_id": 7})
    assert status(wire) == (7, INIT, 0)
    wire.send("RunMission", {"mission_id": 7})
    assert status(wire)[1] == RUNNING
    keep(wire, 1)
    assert wire.vehicle.spooler.executed == [(7, 1, 1)]
    wire.send("PauseMission", {"mission_id": 7})
    assert status(wire)[1] == PAUSED
    keep(wire, 3)
    assert len(wire.vehicle.spooler.executed) == 1  # nothing runs while paused
    # while paused: remove the blocking message, add one after the first
    wire.send("RemoveMessages", {"mission_info": {"mission_id": 7, "task_id": 1},
                                 "message_list": [{"uid": 2}]})
    wire.send("InsertMessages", {"mission_and_task_info": {
        "mission_id": 7, "task_id": 1, "uid": 1, "insert_location": 1},
        "insert_message_list": [message(wire, 5, 5.0)]})
    wire.send("ResumeMission", {"mission_id": 7})
    assert status(wire)[1] == RUNNING
    keep(wire, 4)
    assert wire.vehicle.spooler.executed == [(7, 1, 1), (7, 1, 5), (7, 2, 3)]
    assert status(wire) == (7, FINISHED, 0)
    assert wire.query("QueryStoredMissions").fields == {"mission_list": []}


def test_abort_clears_and_losing_control_pauses(wire: Wire) -> None:
    wire.ready()
    wire.send("SpoolMission", mission(wire))
    wire.send("RunMission", {"mission_id": 7, "task_id": 2})
    assert wire.vehicle.spooler.queue[0][0] == 2  # from task 2 on
    wire.send("ReleaseControl", to=PLATFORM)
    assert status(wire) == (7, PAUSED, 1)  # lost component control
    wire.ready()
    wire.send("AbortMission", {"mission_id": 7}, source=OTHER)  # not the controller
    assert status(wire)[1] == PAUSED
    wire.send("AbortMission", {"mission_id": 7})
    assert status(wire)[1] == ABORTED
    assert wire.query("QueryStoredMissions").fields == {"mission_list": []}
    # an event on every change of the status reaches the subscriber
    outs = wire.send("CreateEvent", {"request_id": 1, "event_type": 1,
                                     "requested_periodic_rate": 0,
                                     "query_message": wire.payload("QueryMissionStatus")})
    assert outs[0].name == "ConfirmEventRequest"
    wire.send("SpoolMission", mission(wire, 8))
    events = [o for o in wire.send("RunMission", {"mission_id": 8}) if o.name == "Event"]
    assert events and events[-1].report is not None
    assert events[-1].report.fields["status"] == RUNNING


def test_path_segments_are_driven_and_reported(wire: Wire) -> None:
    origin: Origin = wire.vehicle.spec.origin
    wire.ready()
    lat, lon = origin.to_geodetic(15.0, 0.0)
    segment = {"p1_latitude": lat, "p1_longitude": lon, "p2_latitude": lat,
               "p2_longitude": lon, "weighting_factor": 0.0, "path_tolerance": 1.0}
    out = wire.query("SetElement", {"request_id_rec": {"request_id": 1}, "element_list": [{
        "element_uid": 1, "previous_uid": 0, "next_uid": 0,
        "element_data": {"format": 0, "data": wire.payload("SetGlobalPathSegment", segment)}}]})
    assert out.name == "ConfirmElementRequest"
    assert wire.send("QueryGlobalPathSegment", {"presence_vector": 7}) == []  # none active
    wire.send("ExecuteList", {"speed": 2.0, "element_uid": 1})
    reported = wire.query("QueryGlobalPathSegment", {"presence_vector": 7}).fields
    assert math.isclose(reported["p2_latitude"], lat, abs_tol=1e-6)
    assert wire.query("QueryActiveElement").fields == {"element_uid": 1}
    keep(wire, 30)
    pose = wire.query("QueryLocalPose", {"presence_vector": 3}).fields
    assert math.hypot(pose["x"] - 15.0, pose["y"]) <= 1.5
    assert wire.vehicle.waypoints.reached == [1]
