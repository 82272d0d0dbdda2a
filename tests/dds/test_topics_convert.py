"""Topic registry, QoS kinds and dict <-> sample conversion; one plugin topic over DDS."""

from dataclasses import dataclass
from typing import Any

import pytest
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import key
from cyclonedds.idl.types import float64
from cyclonedds.qos import Policy

from edge_vis.dds import model
from edge_vis.dds.convert import converter_for
from edge_vis.dds.qos import QosSettings, topic_qos
from edge_vis.dds.topics import TopicKind, TopicRegistry, TopicSpec
from edge_vis.errors import EncodeError, PluginConflictError

# No ``from __future__ import annotations`` here: cyclonedds evaluates the annotations of
# the IdlStruct types below and cannot resolve postponed ones.

pytestmark = pytest.mark.dds


@dataclass
class SonarContact(IdlStruct, typename="acme::SonarContact"):
    vehicle_id: str
    key("vehicle_id")
    bearing: float64


@dataclass
class OtherPose(IdlStruct, typename="acme::OtherPose"):
    vehicle_id: str
    key("vehicle_id")
    x: float64


REQUIRED_TOPICS = {
    "VehicleIdentification": {"vehicle_id", "name", "jaus_subsystem", "vehicle_type", "services",
                              "jaus_address"},
    "VehicleStatus": {"vehicle_id", "state", "link", "online", "last_seen_ms"},
    "GlobalPose": {"vehicle_id", "latitude", "longitude", "altitude", "roll", "pitch", "yaw",
                   "timestamp_ms"},
    "LocalPose": {"vehicle_id", "x", "y", "z", "roll", "pitch", "yaw", "timestamp_ms"},
    "Velocity": {"vehicle_id", "vx", "vy", "vz", "roll_rate", "pitch_rate", "yaw_rate",
                 "timestamp_ms"},
    "ControlRequest": {"vehicle_id", "operator_id", "authority", "action"},
    "ControlStatus": {"vehicle_id", "operator_id", "authority", "state", "rejected_commands",
                      "last_rejection"},
    "WrenchEffortCommand": {"vehicle_id", "operator_id", "propulsive_linear_x",
                            "propulsive_rotational_z", "resistive_linear_x"},
    "VelocityCommand": {"vehicle_id", "operator_id", "vx", "vy", "vz", "roll_rate",
                        "pitch_rate", "yaw_rate"},
    "WaypointPlan": {"vehicle_id", "operator_id", "plan_id", "frame", "waypoints", "speed"},
    "MissionStatus": {"vehicle_id", "plan_id", "active_waypoint", "state", "travel_speed"},
    "LinkStatus": {"link", "vehicle_id", "budget_bps", "measured_bps", "queue_depth", "drops",
                   "bytes_in", "bytes_out", "messages_in", "messages_out"},
    "HealthStatus": {"vehicle_id"},
    "RangeScan": {"vehicle_id"},
    "SensorInfo": {"vehicle_id"},
    "ImageProduct": {"image_id", "transfer_id", "vehicle_id", "file_name", "size_bytes",
                     "sha256", "format", "capture_time_ms", "targets"},
    "ImageData": {"image_id", "chunk_index", "chunk_count", "data"},
    "TransferStatus": {"transfer_id", "vehicle_id", "bytes_done", "bytes_total", "rate_bps",
                       "state"},
    "EnvironmentalData": {"vehicle_id", "water_temperature", "salinity", "depth",
                          "current_speed", "current_direction"},
}


def test_the_standard_registry_has_every_topic_with_its_members() -> None:
    registry = TopicRegistry.standard()
    for name, members in REQUIRED_TOPICS.items():
        spec = registry.get(name)
        assert members <= converter_for(spec.type).names, name


def test_kinds_decide_direction() -> None:
    registry = TopicRegistry.standard()
    assert set(registry.inbound()) == {
        "ControlRequest", "WrenchEffortCommand", "VelocityCommand", "WaypointPlan",
        "JointCommand", "EndEffectorCommand", "DeviceCommand", "PlatformCommand",
        "VectorCommand", "AccelerationLimitCommand", "PoseCommand", "EmergencyCommand",
        "ManagementCommand",
        "PlanQuery", "PathSegmentPlan", "MissionSpoolCommand", "ManipulatorPlan",
        "SensorCommand",
        # IOP and UGV
        "HandoffRequest", "HandoffResponse", "CostMapRequest", "NoGoZoneCommand",
        "DigitalResourceCommand", "CbrnCommand", "SkidSteerCommand", "AckermannCommand",
    }
    assert registry.get("EmergencyCommand").kind is TopicKind.EMERGENCY
    assert registry.get("VehicleClock").kind is TopicKind.STATE
    assert registry.get("GlobalPose").kind is TopicKind.TELEMETRY
    assert registry.get("VehicleIdentification").kind is TopicKind.STATE
    assert registry.get("ControlStatus").kind is TopicKind.STATE
    assert registry.get("ImageProduct").kind is TopicKind.PRODUCT
    assert registry.get("ImageData").kind is TopicKind.BULK


def test_qos_per_kind() -> None:
    telemetry = topic_qos(TopicKind.TELEMETRY)
    assert telemetry[Policy.Reliability] == Policy.Reliability.BestEffort
    assert telemetry[Policy.History] == Policy.History.KeepLast(1)
    state = topic_qos(TopicKind.STATE)
    assert state[Policy.Durability] == Policy.Durability.TransientLocal
    assert state[Policy.History] == Policy.History.KeepLast(1)
    command = topic_qos(TopicKind.COMMAND, QosSettings(command_lifespan=0.25))
    assert command[Policy.Lifespan] == Policy.Lifespan(250_000_000)
    emergency = topic_qos(TopicKind.EMERGENCY)  # a late stop is still a stop
    assert Policy.Lifespan not in emergency
    assert emergency[Policy.History] == Policy.History.KeepAll
    assert command[Policy.Durability] == Policy.Durability.Volatile
    assert topic_qos(TopicKind.PRODUCT)[Policy.History] == Policy.History.KeepAll
    with pytest.raises(ValueError, match="command_lifespan"):
        QosSettings(command_lifespan=0)


def test_a_plugin_topic_registers_and_the_same_registration_is_a_no_op() -> None:
    registry = TopicRegistry.standard()
    spec = TopicSpec("SonarContact", SonarContact, TopicKind.TELEMETRY, owner="acme")
    assert registry.register(spec) is spec
    assert registry.register(TopicSpec("SonarContact", SonarContact, TopicKind.TELEMETRY))
    assert registry.get("SonarContact").owner == "acme"


def test_a_topic_name_claimed_with_another_type_is_a_conflict_naming_both() -> None:
    registry = TopicRegistry.standard()
    with pytest.raises(PluginConflictError, match=r"'GlobalPose'.*'acme'.*'edge_vis'"):
        registry.register(TopicSpec("GlobalPose", OtherPose, TopicKind.TELEMETRY, owner="acme"))
    registry.register(TopicSpec("SonarContact", SonarContact, TopicKind.TELEMETRY, owner="acme"))
    with pytest.raises(PluginConflictError, match="already registered"):
        registry.register(TopicSpec("SonarContact", SonarContact, TopicKind.STATE, owner="b"))


def test_register_all_stamps_the_owner_for_conflict_messages() -> None:
    registry = TopicRegistry.standard()
    registry.register_all([TopicSpec("SonarContact", SonarContact, TopicKind.STATE)], owner="acme")
    assert registry.get("SonarContact").owner == "acme"
    with pytest.raises(PluginConflictError, match=r"'rival'.*'acme'"):
        registry.register_all([TopicSpec("SonarContact", OtherPose, TopicKind.STATE)],
                              owner="rival")


def test_unknown_topic_lists_the_known_ones() -> None:
    with pytest.raises(KeyError, match="GlobalPose"):
        TopicRegistry.standard().get("GlobalPos")


def _plan(**overrides: Any) -> dict[str, Any]:
    plan = {
        "vehicle_id": "ugv1",
        "operator_id": "op1",
        "plan_id": "p7",
        "frame": "GLOBAL",
        "waypoints": [
            {"latitude": 48.1, "longitude": 11.5, "altitude": 500.0, "tolerance": 2.0},
            {"latitude": 48.2, "longitude": 11.6, "altitude": 501, "tolerance": 2.0},
        ],
        "speed": 1.5,
    }
    plan.update(overrides)
    return plan


def test_nested_dicts_round_trip() -> None:
    convert = converter_for(model.WaypointPlan)
    sample = convert.to_struct(_plan(), "WaypointPlan")
    assert isinstance(sample.waypoints[1], model.Waypoint)
    assert sample.waypoints[1].altitude == 501.0
    back = convert.to_dict(sample)
    assert back["frame"] == "GLOBAL"
    assert back["waypoints"][0]["latitude"] == 48.1
    assert back["waypoints"][0]["x"] == 0.0  # defaulted member
    assert convert.to_dict(convert.to_struct(back, "WaypointPlan")) == back


@pytest.mark.parametrize(
    ("bad", "path", "words"),
    [
        (_plan(waypoints=[{"latitude": 1.0}, {"latitude": "north"}]), "waypoints[1].latitude",
         "expected a number, got str 'north'"),
        (_plan(frame="UP"), "frame", "expected one of GLOBAL, LOCAL"),
        (_plan(speed=True), "speed", "expected a number, got bool"),
        (_plan(waypoints={"latitude": 1.0}), "waypoints", "expected a list"),
        (_plan(plan_id=7), "plan_id", "expected a string"),
        ({"vehicle_id": "ugv1", "operator_id": "op1", "plan_id": "p"}, "waypoints",
         "required member is missing"),
        (_plan(sped=2.0), "", "unknown member(s) sped"),
        (_plan(waypoints=[{"latitud": 1.0}]), "waypoints[0]", "unknown member(s) latitud"),
    ],
)
def test_a_bad_dict_is_an_encode_error_naming_topic_and_member(
    bad: dict[str, Any], path: str, words: str
) -> None:
    with pytest.raises(EncodeError) as caught:
        converter_for(model.WaypointPlan).to_struct(bad, "WaypointPlan")
    assert caught.value.path == path
    assert words in str(caught.value)
    assert "'WaypointPlan'" in str(caught.value)


def test_integers_are_range_checked() -> None:
    convert = converter_for(model.ControlRequest)
    ok = {"vehicle_id": "u", "operator_id": "o", "action": "REQUEST", "authority": 255}
    assert convert.to_struct(ok).authority == 255
    with pytest.raises(EncodeError, match="256 is outside the uint8 range") as caught:
        convert.to_struct({**ok, "authority": 256}, "ControlRequest")
    assert caught.value.path == "authority"
    with pytest.raises(EncodeError, match="expected an integer"):
        convert.to_struct({**ok, "authority": 1.5}, "ControlRequest")


def test_enums_accept_names_with_or_without_prefix_values_and_members() -> None:
    convert = converter_for(model.MissionStatus)
    for value in ("MISSION_EXECUTING", "executing", 2, model.MissionState.MISSION_EXECUTING):
        sample = convert.to_struct({"vehicle_id": "u", "state": value})
        assert sample.state is model.MissionState.MISSION_EXECUTING
        assert convert.to_dict(sample)["state"] == "MISSION_EXECUTING"


def test_optional_members_and_bytes() -> None:
    wrench = converter_for(model.WrenchEffortCommand)
    sample = wrench.to_struct({"vehicle_id": "u", "operator_id": "o", "propulsive_linear_x": 40})
    assert sample.propulsive_linear_x == 40.0
    assert sample.propulsive_rotational_z is None
    assert model.WrenchEffortCommand.deserialize(sample.serialize()) == sample
    assert wrench.to_dict(sample) == {"vehicle_id": "u", "operator_id": "o",
                                      "propulsive_linear_x": 40.0}  # absent = missing key
    chunk = converter_for(model.ImageData)
    data = chunk.to_struct({"vehicle_id": "u", "image_id": "i", "chunk_index": 0,
                            "chunk_count": 1, "data": bytearray(b"\x00\xff")})
    assert chunk.to_dict(data)["data"] == b"\x00\xff"


def test_key_of_builds_a_key_only_sample() -> None:
    pose = converter_for(model.GlobalPose).key_of("ugv1", "GlobalPose")
    assert pose.vehicle_id == "ugv1"
    link = converter_for(model.LinkStatus)
    assert link.key_of({"link": "radio", "vehicle_id": "", "relay": "201.1.1"}).link == "radio"
    with pytest.raises(EncodeError, match="give them as a dict"):
        link.key_of("radio", "LinkStatus")


def test_a_plugin_topic_travels_through_the_bridge(make_bridge: Any) -> None:
    registry = TopicRegistry.standard()
    registry.register(TopicSpec("SonarContact", SonarContact, TopicKind.STATE, owner="acme"))
    relay = make_bridge(topics=registry)
    relay.publish("SonarContact", {"vehicle_id": "uuv3", "bearing": 0.5})
    reader = make_bridge(topics=registry).reader("SonarContact")
    assert reader.collect(1, 3.0) == [{"vehicle_id": "uuv3", "bearing": 0.5}]
