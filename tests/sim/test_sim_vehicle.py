"""Discovery, sensors, the waypoint list driver and injected faults (sans-I/O, fake clock)."""

from __future__ import annotations

import hashlib
import math

from conftest import NODE_MANAGER, OCU, PLATFORM, SENSORS, Wire, named, spec

from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.tools.sim.images import PNG_SIGNATURE
from edge_vis.tools.sim.kinematics import Origin


def test_discovery_answers_like_a_subsystem(wire: Wire) -> None:
    outs = wire.send("QueryIdentification", {"query_type": 2}, to=BROADCAST)
    assert [(o.source, o.name, o.fields) for o in outs] == [(NODE_MANAGER, "ReportIdentification", {
        "query_type": 2, "type": 10001, "identification": "ugv-test"})]
    config = wire.query("QueryConfiguration", {"query_type": 2}, to=NODE_MANAGER).fields
    assert [c["component_id"] for c in config["node_list"][0]["component_list"]] == [1, 2, 3]
    services = wire.query("QueryServices", {"node_list": [{
        "node_rec": {"node_id": 255}, "component_list": [{"component_id": 3}]}]},
        to=NODE_MANAGER).fields
    (comp,) = services["node_list"][0]["component_list"]
    assert comp["component_rec"] == {"component_id": 3, "instance_id": 0}
    assert {"uri": "urn:jaus:jss:environmentSensing:StillImage", "major_version_number": 1,
            "minor_version_number": 0} in comp["service_list"]
    listed = wire.query("QueryServiceList", {"subsystem_list": [{
        "subsystem_rec": {"subsystem_id": 65535}, "node_list": [{
            "node_rec": {"node_id": 255}, "component_list": [
                {"component_id": 255, "search_filter": "Driver"}]}]}]},
        to=NODE_MANAGER).fields
    uris = [s["uri"] for n in listed["subsystem_list"][0]["node_list"]
            for c in n["component_list"] for s in c["service_list"]]
    assert uris == ["urn:jaus:jss:mobility:PrimitiveDriver",
                    "urn:jaus:jss:mobility:GlobalWaypointListDriver",
                    "urn:jaus:jss:mobility:GlobalPathSegmentDriver",
                    "urn:jaus:jss:mobility:LocalPathSegmentDriver"]
    # a component that does not offer Discovery stays silent, as real ones do
    assert wire.send("QueryIdentification", {"query_type": 2}, to=PLATFORM) == []


def waypoint(origin: Origin, x: float, y: float) -> dict:
    lat, lon = origin.to_geodetic(x, y)
    return {"latitude": lat, "longitude": lon, "waypoint_tolerance": 1.0}


def element(wire: Wire, uid: int, prev: int, nxt: int, wp: dict) -> dict:
    return {"element_uid": uid, "previous_uid": prev, "next_uid": nxt,
            "element_data": {"format": 0, "data": wire.payload("SetGlobalWaypoint", wp)}}


def test_waypoint_list_is_driven_to_the_last_waypoint(wire: Wire) -> None:
    origin = wire.vehicle.spec.origin
    wire.ready()
    plan = [(20.0, 0.0), (20.0, 20.0), (0.0, 25.0)]
    elements = [element(wire, 10 + i, 10 + i - 1 if i else 0, 10 + i + 1 if i < 2 else 0,
                        waypoint(origin, *p)) for i, p in enumerate(plan)]
    out = wire.query("SetElement", {"request_id_rec": {"request_id": 3},
                                    "element_list": elements})
    assert (out.name, out.fields) == ("ConfirmElementRequest", {"request_id": 3})
    assert wire.query("QueryElementList").fields == {"element_list": [
        {"element_uid": 10}, {"element_uid": 11}, {"element_uid": 12}]}
    assert wire.query("QueryElementCount").fields == {"element_count": 3}
    wire.send("ExecuteList", {"speed": 2.0})
    assert abs(wire.query("QueryTravelSpeed").fields["speed"] - 2.0) < 0.001
    active = []
    for _ in range(60):  # one minute, keeping control alive
        wire.take_control()
        wire.advance(1.0, step=0.1)
        active.append(wire.query("QueryActiveElement").fields["element_uid"])
    assert active[0] == 10 and 11 in active and 12 in active and active[-1] == 0
    assert active.index(11) < active.index(12)
    pose = wire.query("QueryLocalPose", {"presence_vector": 3}).fields
    assert math.hypot(pose["x"] - 0.0, pose["y"] - 25.0) <= 1.0
    assert wire.vehicle.waypoints.reached == [10, 11, 12]
    assert abs(wire.vehicle.motion.speed) < 0.05


def test_list_manager_refuses_bad_requests(wire: Wire) -> None:
    origin = wire.vehicle.spec.origin
    wire.ready()
    out = wire.query("SetElement", {"request_id_rec": {"request_id": 1}, "element_list": [
        element(wire, 5, 4, 0, waypoint(origin, 1, 1))]})
    assert (out.name, out.fields["response_code"]) == ("RejectElementRequest", 2)
    bad = element(wire, 5, 0, 0, waypoint(origin, 1, 1))
    bad["element_data"] = {"format": 0, "data": wire.payload("QueryStatus")}
    out = wire.query("SetElement", {"request_id_rec": {"request_id": 2}, "element_list": [bad]})
    assert out.fields["response_code"] == 4
    assert wire.query("QueryElementCount").fields == {"element_count": 0}
    out = wire.query("DeleteElement", {"request_id_rec": {"request_id": 3},
                                       "delete_element_list": [{"element_uid": 9}]})
    assert out.fields["response_code"] == 5
    # from someone who does not control the vehicle: silently ignored
    assert wire.send("SetElement", {"request_id_rec": {"request_id": 4}, "element_list": [
        element(wire, 5, 0, 0, waypoint(origin, 1, 1))]},
        source=JausAddress(9, 1, 1)) == []


def test_range_scan_and_still_image(wire: Wire) -> None:
    scan = wire.query("QueryRangeSensorData", {"query_range_sensor_data_list": [
        {"sensor_id": 1, "report_coordinate_system": 0, "query_presence_vector": 0}]},
        to=SENSORS).fields["range_sensor_data_list"][0]["range_sensor_data_seq"]
    points = scan["range_sensor_data_point_list"]
    assert len(points) == 181
    ahead = points[90]
    assert abs(ahead["bearing"]) < 1e-6 and abs(ahead["range"] - 40.0) < 0.01  # the wall
    image = wire.query("QueryStillImageData", {"query_still_image_data_list": [
        {"sensor_id": 1, "report_coordinate_system": 0, "query_presence_vector": 0}]},
        to=SENSORS).fields["still_image_data_list"][0]["image_frame"]
    assert image["format"] == 2 and image["data"].startswith(PNG_SIGNATURE)
    assert len(image["data"]) > 2 * 4079  # a large data set on any JAUS link


def test_uuv_announces_itself_and_ignores_discovery() -> None:
    wire = Wire(spec(kind="uuv", subsystem=300, atr_period=5.0, hello_period=2.0,
                     environment_period=1.0))
    vehicle = JausAddress(300, 1, 1)
    assert wire.send("QueryIdentification", {"query_type": 2}, to=BROADCAST) == []
    assert wire.send("QueryServices", {"node_list": []}, to=vehicle) == []
    outs = wire.advance(10.5)
    hellos = named(outs, "VendorHello")
    assert len(hellos) == 6 and {h.destination for h in hellos} == {BROADCAST}
    assert hellos[0].fields["vehicle_name"] == "ugv-test"
    assert hellos[0].fields["jaus_id"] == {"subsystem": 300, "node": 1, "component": 1}
    assert any(s["uri"] == "urn:edge-vis:uuv:OceanEnvironmentSensor"
               for s in hellos[0].fields["services"])
    assert len(named(outs, "ReportOceanEnvironment")) == 10
    notices = named(outs, "ReportAtrImageAvailable")
    assert len(notices) == 2
    for notice in notices:
        data = wire.vehicle.atr_image(notice.fields["image_id"])
        assert notice.fields["size_bytes"] == len(data)
        assert notice.fields["sha256"] == hashlib.sha256(data).digest()
    env = wire.query("QueryOceanEnvironment", {"presence_vector": 0b101}, to=vehicle).fields
    assert set(env) == {"water_temperature", "depth"}
    assert wire.query("QueryGlobalPose", {"presence_vector": 4}, to=vehicle).fields[
        "altitude"] < -10  # under water


def test_dropout_with_reboot_loses_control_events_and_list() -> None:
    wire = Wire(spec(faults={"dropout_every": 20.0, "dropout_duration": 5.0,
                             "dropout_reboot": True}))
    wire.ready()
    wire.send("CreateEvent", {"request_id": 1, "event_type": 0, "requested_periodic_rate": 2.0,
                              "query_message": wire.payload("QueryHeartbeatPulse")})
    for _ in range(9):
        wire.take_control()
        assert named(wire.advance(2.0), "Event")
    # t = 19: the drop-out starts at 20
    outs = wire.advance(2.0)  # t = 21
    assert len(named(outs, "Event")) <= 2
    assert wire.send("QueryStatus") == []  # silence
    assert wire.advance(3.5) == []  # t = 24.5
    assert wire.restarts == 0
    outs = wire.advance(1.0)  # back at 25, rebooted
    assert wire.restarts == 1 and named(outs, "Event") == []
    assert named(outs, "RejectControl") == []  # a reboot does not say goodbye
    assert wire.query("QueryStatus").fields["status"] == 0
    assert wire.query("QueryControl").fields["subsystem_id"] == 0
    wire.advance(1.0)
    assert wire.query("QueryStatus").fields["status"] == 2
    assert wire.vehicle.counters["dropouts"] == 1
    # and it happens again 20 s after the first one started
    wire.advance(15.0)  # t = 41.5
    assert wire.send("QueryStatus") == []


def test_malformed_frames_at_the_configured_rate() -> None:
    wire = Wire(spec(faults={"malformed_rate": 2.0}))
    wire.vehicle.on_timer(0.0)
    actions = []
    now = 0.0
    for _ in range(3000):
        now += 0.02
        actions += wire.vehicle.on_timer(now)
    corrupt = [a for a in actions if getattr(a, "corrupt", "")]
    assert 90 <= len(corrupt) <= 150  # ~2 per second over 60 s
    assert {a.corrupt for a in corrupt} == {"truncated", "bad_size", "bad_body", "bad_version"}


def test_runs_are_reproducible() -> None:
    def run() -> list:
        wire = Wire(spec(kind="uuv", atr_period=3.0, faults={"malformed_rate": 1.0}))
        return [(o.name, o.fields.get("target_class"), o.fields.get("sha256"))
                for o in wire.advance(12.0)]
    assert run() == run()


def test_ocu_address_in_reports(wire: Wire) -> None:
    assert wire.query("QueryHeartbeatPulse", to=NODE_MANAGER).destination == OCU


def test_sensor_capabilities_and_configuration_are_answered(wire: Wire) -> None:
    for query, list_key in (
            ("QueryRangeSensorCapabilities", "range_sensor_capabilities_list"),
            ("QueryRangeSensorConfiguration", "range_sensor_configuration_list"),
            ("QueryVisualSensorCapabilities", "query_visual_sensor_capabilities_list"),
            ("QueryVisualSensorConfiguration", "query_visual_sensor_configuration_list"),
            ("QueryStillImageSensorCapabilities", "query_still_image_sensor_capabilities_list"),
            ("QueryStillImageSensorConfiguration",
             "query_still_image_sensor_configuration_list")):
        defn = wire.catalogue.by_name(query)
        (field,) = defn.body.fields
        out = wire.query(query, {field.name: []}, to=SENSORS)
        assert out.name == query.replace("Query", "Report", 1)
        (items,) = out.fields.values()
        assert items[0]["sensor_id"] == 1, list_key


def test_first_dropout_time_can_be_given() -> None:
    wire = Wire(spec(faults={"dropout_every": 60.0, "dropout_duration": 2.0,
                             "dropout_first": 3.0}))
    wire.advance(2.9)
    assert wire.send("QueryStatus") != []
    wire.advance(0.2)
    assert wire.send("QueryStatus") == []
    wire.advance(2.0)
    assert wire.send("QueryStatus") != []


def test_a_silent_vehicle_does_not_ask_to_be_woken_in_the_past() -> None:
    wire = Wire(spec(faults={"dropout_every": 30.0, "dropout_duration": 5.0}))
    wire.ready()
    wire.send("CreateEvent", {"request_id": 1, "event_type": 0, "requested_periodic_rate": 20.0,
                              "query_message": wire.payload("QueryHeartbeatPulse")})
    wire.advance(28.0)
    wire.take_control()  # t = 29: control would time out at 34, inside the drop-out
    wire.advance(1.5)  # down since t = 30
    assert wire.vehicle.down
    for _ in range(40):
        wire.now += 0.1
        wire.vehicle.on_timer(wire.now)
        deadline = wire.vehicle.next_deadline()
        assert deadline is not None and deadline > wire.now
