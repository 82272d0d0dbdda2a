"""The operator monitor: its view model, its keys, and its plain-text output over real DDS."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
import time
import uuid

import pytest

from edge_vis.tools.monitor_view import FleetView, Operator, waypoint_plan


def _fleet(view: FleetView, now: float) -> None:
    view.ingest("VehicleIdentification", {"vehicle_id": "ugv-a", "name": "ugv-a",
                                          "vehicle_type": "UGV", "jaus_address": "101.1.1"}, now)
    view.ingest("VehicleStatus", {"vehicle_id": "ugv-a", "state": "READY", "online": True,
                                  "link": "lan"}, now)
    view.ingest("ControlStatus", {"vehicle_id": "ugv-a", "state": "CONTROLLED",
                                  "operator_id": "alice", "authority": 120}, now)
    view.ingest("VehicleStatus", {"vehicle_id": "uuv-b", "state": "STANDBY", "online": True},
                now)
    view.ingest("LinkStatus", {"link": "radio", "up": True, "budget_bps": 9600.0,
                               "measured_bps": 4800.0, "messages_in": 10, "messages_out": 4,
                               "drops": [{"traffic_class": "telemetry", "count": 3}]}, now)
    for i in range(50):  # 10 Hz of pose for 5 s
        t = now + i * 0.1
        view.ingest("GlobalPose", {"vehicle_id": "ugv-a", "latitude": 36.6, "longitude":
                                   -121.9, "yaw": 0.0}, t)
        view.ingest("Velocity", {"vehicle_id": "ugv-a", "vx": 1.2, "vy": 0.0}, t)
    view.ingest("ImageProduct", {"vehicle_id": "uuv-b", "image_id": "atr-1",
                                 "file_name": "atr-1.png", "size_bytes": 74000}, now + 5)


def test_view_lists_vehicles_with_position_control_rates_links_and_images() -> None:
    view = FleetView()
    _fleet(view, 100.0)
    text = "\n".join(view.render(105.0))
    assert all(len(line) <= 80 for line in text.splitlines())
    (alpha,) = [line for line in text.splitlines() if "ugv-a" in line]
    assert "READY" in alpha and "36.60000,-121.90000" in alpha and "alice" in alpha
    assert " 1.2 " in alpha  # speed
    assert "20.0" in alpha  # 10 Hz GlobalPose + 10 Hz Velocity
    assert "uuv-b" in text and "image atr-1.png (72 KiB)" in text
    (radio,) = [line for line in text.splitlines() if line.startswith("radio")]
    assert "50.0%" in radio and radio.split()[-1] == "3"


def test_rows_fit_an_80_column_screen_and_show_heading_and_units() -> None:
    view = FleetView()
    _fleet(view, 100.0)
    view.row("ugv-a").controller = "operator-12345"
    view.ingest("GlobalPose", {"vehicle_id": "ugv-a", "latitude": -36.6, "longitude": -121.9,
                               "yaw": -math.pi / 2}, 105.0)  # facing west
    view.ingest("LinkStatus", {"link": "lan", "up": True, "budget_bps": 0.0,
                               "measured_bps": 96_200.0}, 105.0)
    lines = view.render(105.0)
    # curses draws width - 1 columns: every table row must fit 79
    assert all(len(line) <= 79 for line in lines)
    head = lines[0]
    (alpha,) = [line for line in lines if line.startswith(" ugv-a")]
    assert head.split()[:7] == ["VEHICLE", "TYPE", "STATE", "POSITION", "HDG", "M/S",
                                "CONTROL"]
    assert alpha[head.index("HDG"):head.index("HDG") + 3] == "270"  # degrees from north
    assert "-36.60000,-121.90000" in alpha
    link_head = next(line for line in lines if line.startswith("LINK"))
    assert "USE kb/s" in link_head and "BUDGET kb/s" in link_head and "LOAD" in link_head
    (lan,) = [line for line in lines if line.startswith("lan")]
    assert lan.split()[2:5] == ["96.2", "unlimited", "-"]
    (radio,) = [line for line in lines if line.startswith("radio")]
    assert radio.split()[2:5] == ["4.8", "9.6", "50.0%"]


def test_mission_line_names_the_waypoint_only_while_one_is_active() -> None:
    view = FleetView()
    view.ingest("MissionStatus", {"vehicle_id": "v", "state": "MISSION_EXECUTING",
                                  "active_waypoint": 1}, 0.0)
    assert any("mission executing wp 1" in line for line in view.render(0.0))
    view.ingest("MissionStatus", {"vehicle_id": "v", "state": "MISSION_COMPLETED",
                                  "active_waypoint": -1}, 1.0)
    text = "\n".join(view.render(1.0))
    assert "mission completed" in text and "wp -1" not in text


def test_the_plan_held_and_the_spooled_mission_are_shown() -> None:
    view = FleetView()
    wp = {"message": "SetGlobalWaypoint"}
    view.ingest("VehiclePlan", {"vehicle_id": "v", "component": "1.1.2", "element_count": 3,
                                "elements": [wp], "complete": False}, 0.0)
    assert any("holds 1/3 waypoints" in line for line in view.render(0.0))
    view.ingest("VehiclePlan", {"vehicle_id": "v", "component": "1.1.2", "element_count": 2,
                                "elements": [wp, {"message": "SetGlobalPathSegment"}],
                                "complete": True}, 1.0)
    view.ingest("SpoolerStatus", {"vehicle_id": "v", "scope": "MISSION", "id": 7,
                                  "status": "PAUSED"}, 1.0)
    view.ingest("SpoolerStatus", {"vehicle_id": "v", "scope": "COMMAND", "id": 7,
                                  "status": "REFUSED"}, 1.0)
    text = "\n".join(view.render(1.0))
    assert "holds 2 elements" in text
    assert "spooled mission 7 paused" in text and "refused" not in text
    assert all(len(line) <= 80 for line in view.render(1.0))


def test_dropouts_and_recoveries_are_counted() -> None:
    view = FleetView()
    for state, online in (("READY", True), ("OFFLINE", False), ("STANDBY", True),
                          ("OFFLINE", False)):
        view.ingest("VehicleStatus", {"vehicle_id": "v", "state": state, "online": online}, 0)
    row = view.vehicles["v"]
    assert (row.went_offline, row.recovered) == (2, 1)
    assert view.summary()["faults_recovered"] == 1
    assert "OFFLINE" in view.render(1.0)[1]


def test_who_holds_each_component_and_the_clock_offset_are_shown() -> None:
    view = FleetView()
    view.ingest("ControlStatus", {"vehicle_id": "v", "state": "REJECTED", "holders": [
        {"component": "60.1.1", "controller": "9.1.5", "authority": 120, "is_relay": False},
        {"component": "60.1.2", "controller": "200.1.1", "authority": 90, "is_relay": True},
        {"component": "60.1.3", "controller": "", "authority": 0, "is_relay": False}]}, 0.0)
    view.ingest("VehicleClock", {"vehicle_id": "v", "offset_ms": -2480.0}, 0.0)
    text = "\n".join(view.render(1.0))
    assert "held 60.1.1 by 9.1.5(120) 60.1.2 by relay(90)" in text
    assert "60.1.3" not in text  # nobody holds it
    assert "clock -2.48 s" in text
    view.ingest("VehicleClock", {"vehicle_id": "v", "offset_ms": math.nan}, 2.0)
    assert "clock" not in "\n".join(view.render(2.0))


def test_camera_stream_state_is_shown_per_camera() -> None:
    view = FleetView()
    view.ingest("SensorState", {"vehicle_id": "v", "sensor_id": 1, "configuration": "x=1"},
                0.0)
    assert "camera" not in "\n".join(view.render(0.0))  # no stream asked for yet
    view.ingest("SensorState", {"vehicle_id": "v", "sensor_id": 2, "stream": "PLAY"}, 0.0)
    view.ingest("SensorState", {"vehicle_id": "v", "sensor_id": 1, "stream": "PAUSE"}, 1.0)
    assert "camera 1:pause 2:play" in "\n".join(view.render(1.0))
    view.ingest("SensorState", {"vehicle_id": "v", "sensor_id": 2, "stream": "STOP"}, 2.0)
    assert "camera 1:pause 2:stop" in "\n".join(view.render(2.0))


def test_operator_keys_make_commands() -> None:
    view = FleetView()
    _fleet(view, 0.0)
    op = Operator("alice", 150)
    assert op.key("DOWN", view) == [] and op.selected == "uuv-b"
    op.key("UP", view)
    assert op.selected == "ugv-a"
    [(topic, sample)] = op.key("c", view)
    assert topic == "ControlRequest"
    assert sample == {"vehicle_id": "ugv-a", "operator_id": "alice", "action": "REQUEST",
                      "authority": 150}
    op.key("d", view)
    op.key("UP", view)
    [(topic, sample)] = op.key("RIGHT", view)
    assert topic == "WrenchEffortCommand"
    assert (sample["propulsive_linear_x"], sample["propulsive_rotational_z"]) == (10.0, 10.0)
    assert op.drive()[0][1]["propulsive_linear_x"] == 10.0  # repeated while driving
    assert op.key(" ", view)[0][1]["propulsive_linear_x"] == 0.0
    [(topic, plan)] = op.key("w", view)
    assert topic == "WaypointPlan" and len(plan["waypoints"]) == 3
    [(topic, sample)] = op.key("r", view)
    assert sample["action"] == "RELEASE" and not op.driving
    op.key("q", view)
    assert op.quit


def test_e_stops_at_once_and_clearing_asks_first() -> None:
    view = FleetView()
    _fleet(view, 0.0)
    op = Operator("alice", 150)
    op.key("d", view)  # driving ugv-a
    [(topic, sample)] = op.key("e", view)
    assert topic == "EmergencyCommand" and not op.driving
    assert (sample["vehicle_id"], sample["action"], sample["authority"]) == ("ugv-a", "SET", 150)
    view.ingest("VehicleStatus", {"vehicle_id": "ugv-a", "state": "EMERGENCY", "online": True,
                                  "emergency": True, "emergency_operator": "alice",
                                  "emergency_reason": "monitor of alice"}, 1.0)
    lines = view.render(1.0, selected="ugv-a")
    assert "!E-STOP!" in lines[1]
    assert lines[2].strip() == "*** EMERGENCY STOP set by alice: monitor of alice ***"
    assert op.key("e", view) == [] and "CLEAR" in op.message  # asks
    assert op.key("x", view) == [] and "kept" in op.message  # anything else keeps it
    assert op.key("e", view) == []
    [(topic, sample)] = op.key("y", view)
    assert (topic, sample["action"]) == ("EmergencyCommand", "CLEAR")
    assert op.key("y", view) == []  # a second y clears nothing more


def test_waypoint_triangle_starts_ahead_of_the_vehicle() -> None:
    plan = waypoint_plan("v", "op", 36.6, -121.9, 0.0, side=100.0)
    first, second, third = plan["waypoints"]
    assert first["latitude"] > 36.6 and abs(first["longitude"] + 121.9) < 1e-9  # north
    assert second["longitude"] > -121.9  # then east
    assert abs(third["latitude"] - 36.6) < 1e-9


@pytest.mark.dds
def test_plain_output_lists_the_vehicles_published_on_dds() -> None:
    pytest.importorskip("cyclonedds")
    from edge_vis.dds import DdsBridge, loopback_config

    config = loopback_config()
    domain = 180 + os.getpid() % 40
    partition = f"monitor-test-{uuid.uuid4().hex[:10]}"
    bridge = DdsBridge(domain, [partition], config=config)
    stop = threading.Event()

    def relay() -> None:  # what a relay would publish, at 10 Hz
        bridge.publish("VehicleIdentification", {"vehicle_id": "ugv-alpha-101",
                                                 "name": "ugv-alpha", "vehicle_type": "UGV"})
        bridge.publish("VehicleIdentification", {"vehicle_id": "uuv-delta-300",
                                                 "name": "uuv-delta", "vehicle_type": "AUV"})
        while not stop.is_set():
            for vid, lat in (("ugv-alpha-101", 36.6002), ("uuv-delta-300", 36.62)):
                bridge.publish("VehicleStatus", {"vehicle_id": vid, "state": "STANDBY",
                                                 "online": True})
                bridge.publish("GlobalPose", {"vehicle_id": vid, "latitude": lat,
                                              "longitude": -121.9, "altitude": 0.0,
                                              "roll": 0.0, "pitch": 0.0, "yaw": 0.0,
                                              "timestamp_ms": int(time.time() * 1000)})
            stop.wait(0.1)

    thread = threading.Thread(target=relay, daemon=True)
    thread.start()
    try:
        env = dict(os.environ, CYCLONEDDS_URI=config)
        done = subprocess.run(
            [sys.executable, "-m", "edge_vis", "monitor", "--domain", str(domain),
             "--partition", partition, "--once", "--wait", "3", "--summary"],
            capture_output=True, text=True, timeout=60, env=env)
    finally:
        stop.set()
        thread.join()
        bridge.close()
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    (alpha,) = [line for line in lines if line.startswith(" ugv-alpha-101")]
    (delta,) = [line for line in lines if line.startswith(" uuv-delta-300")]
    assert "UGV" in alpha and "STANDBY" in alpha and "36.60020,-121.90000" in alpha
    assert "AUV" in delta and "36.62000" in delta
    assert '"GlobalPose"' in done.stdout  # the JSON summary counts samples per topic


def test_the_serving_relay_and_take_overs_are_shown_and_links_per_relay() -> None:
    view = FleetView()
    view.ingest("VehicleStatus", {"vehicle_id": "v", "state": "READY", "online": True,
                                  "relay": "201.1.1"}, 0.0)
    assert any("relay 201.1.1" in line for line in view.render(0.0))
    view.ingest("VehicleStatus", {"vehicle_id": "v", "state": "READY", "online": True,
                                  "relay": "202.1.1"}, 1.0)
    assert any("relay 202.1.1 (taken over 1x)" in line for line in view.render(1.0))
    for relay in ("201.1.1", "202.1.1"):
        view.ingest("LinkStatus", {"link": "radio", "relay": relay, "up": True}, 1.0)
    rows = [line for line in view.render(1.0) if line.startswith("radio")]
    assert [row.split()[-1] for row in rows] == ["201.1.1", "202.1.1"]
    assert all(len(line) <= 79 for line in view.render(1.0))


def test_handoff_requests_are_shown_and_answered_by_keys() -> None:
    view = FleetView()
    _fleet(view, 0.0)
    view.ingest("HandoffStatus", {"vehicle_id": "ugv-a", "holder": "alice", "requests": [
        {"request_id": 3, "requester": "bob", "authority": 90, "state": "PENDING",
         "explanation": "my sector"},
        {"request_id": 2, "requester": "carol", "authority": 10, "state": "DENIED"}]}, 1.0)
    lines = view.render(1.0)
    assert "   HAND-OFF #3 to bob (90) 'my sector' pending: a = grant, n = refuse" in lines
    assert not any("carol" in line for line in lines)  # decided: not asked again
    assert all(len(line) <= 80 for line in lines)
    alice = Operator("alice", 150)
    alice.select(view, 0)
    [(topic, sample)] = alice.key("a", view)
    assert (topic, sample) == ("HandoffResponse", {"vehicle_id": "ugv-a", "operator_id":
                                                   "alice", "request_id": 3,
                                                   "response": "GRANTED"})
    assert alice.key("n", view)[0][1]["response"] == "DENIED"
    bob = Operator("bob", 90)
    bob.select(view, 0)
    [(topic, sample)] = bob.key("h", view)
    assert topic == "HandoffRequest" and sample["authority"] == 90
    view.ingest("HandoffStatus", {"vehicle_id": "ugv-a", "holder": "bob", "requests": [
        {"request_id": 3, "requester": "bob", "authority": 90, "state": "GRANTED"}]}, 2.0)
    assert alice.key("a", view) == [] and "no hand-off request" in alice.message
