"""DdsBridge against real Cyclone DDS participants on loopback (see conftest.py).

A "relay" bridge and an "operator" bridge live in this process, each with its own
participant, as a relay and an operator station would on one host.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

from edge_vis.dds import DdsBridge, DdsError, QosSettings, model
from edge_vis.errors import EncodeError

pytestmark = pytest.mark.dds

MakeBridge = Callable[..., DdsBridge]


def pose(vehicle: str, lat: float, lon: float, t: int = 1000) -> dict[str, Any]:
    return {"vehicle_id": vehicle, "latitude": lat, "longitude": lon, "altitude": 12.5,
            "roll": 0.01, "pitch": -0.02, "yaw": 1.5, "timestamp_ms": t}


def wait_until(predicate: Callable[[], bool], timeout: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def test_two_vehicles_arrive_as_two_keyed_instances(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()
    reader = operator.reader("GlobalPose")
    assert relay.wait_for_subscribers("GlobalPose")
    relay.publish("GlobalPose", pose("ugv1", 48.1, 11.5))
    relay.publish("GlobalPose", pose("usv2", -33.9, 151.2, t=2000))
    got = {s["vehicle_id"]: s for s in reader.collect(2, timeout=3.0)}
    assert got == {"ugv1": pose("ugv1", 48.1, 11.5), "usv2": pose("usv2", -33.9, 151.2, t=2000)}


def test_a_late_joiner_sees_every_vehicles_identification(make_bridge: MakeBridge) -> None:
    relay = make_bridge()
    for vid, subsystem in (("ugv1", 126), ("uuv3", 140)):
        relay.publish("VehicleIdentification", {
            "vehicle_id": vid, "name": f"{vid.upper()} robot", "jaus_address": f"{subsystem}.1.1",
            "jaus_subsystem": subsystem, "vehicle_type": "VEHICLE",
            "services": [{"uri": "urn:jaus:jss:core:AccessControl", "version": "1.1"}],
        })
    relay.publish("VehicleStatus", {"vehicle_id": "ugv1", "state": "READY", "online": True})
    time.sleep(0.05)  # the operator station starts after the relay has published

    late = make_bridge()
    idents = {s["vehicle_id"]: s for s in late.reader("VehicleIdentification").collect(2, 3.0)}
    assert sorted(idents) == ["ugv1", "uuv3"]
    assert idents["uuv3"]["jaus_subsystem"] == 140
    assert idents["ugv1"]["services"] == [
        {"uri": "urn:jaus:jss:core:AccessControl", "version": "1.1"}
    ]
    (status,) = late.reader("VehicleStatus").collect(1, 3.0)
    assert status["state"] == "READY" and status["online"] is True


def test_a_telemetry_reader_keeps_only_the_newest_sample_per_vehicle(
    make_bridge: MakeBridge,
) -> None:
    relay, operator = make_bridge(), make_bridge()
    reader = operator.reader("GlobalPose")
    assert relay.wait_for_subscribers("GlobalPose")
    for i in range(20):
        relay.publish("GlobalPose", pose("ugv1", 48.0 + i / 100, 11.0, t=i))
    for i in range(5):
        relay.publish("GlobalPose", pose("usv2", -33.0, 151.0 + i, t=i))
    newest = {"ugv1": 19, "usv2": 4}
    assert wait_until(
        lambda: {s["vehicle_id"]: s["timestamp_ms"] for s in reader.read()} == newest
    )
    held = reader.read()
    assert len(held) == 2  # not 25: one per vehicle
    assert {s["vehicle_id"]: s["latitude"] for s in held}["ugv1"] == pytest.approx(48.19)


def test_commands_reach_the_relay_as_dicts_in_the_event_loop(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()

    async def scenario() -> list[tuple[str, dict[str, Any], bool]]:
        loop = asyncio.get_running_loop()
        received: asyncio.Queue[tuple[str, dict[str, Any], bool]] = asyncio.Queue()

        def on_sample(topic: str, sample: dict[str, Any]) -> None:
            in_loop = threading.get_ident() == loop_thread
            received.put_nowait((topic, sample, in_loop))

        loop_thread = threading.get_ident()
        relay.subscribe(None, on_sample, loop=loop)  # all command topics
        operator.open_writers(["ControlRequest", "VelocityCommand", "WaypointPlan"])
        for topic in ("ControlRequest", "VelocityCommand", "WaypointPlan"):
            assert operator.wait_for_subscribers(topic)
        operator.publish("ControlRequest", {"vehicle_id": "ugv1", "operator_id": "op1",
                                            "action": "REQUEST", "authority": 5})
        operator.publish("VelocityCommand", {"vehicle_id": "ugv1", "operator_id": "op1",
                                             "vx": 0.8, "yaw_rate": -0.1})
        operator.publish("WaypointPlan", {"vehicle_id": "ugv1", "operator_id": "op1",
                                          "plan_id": "p1", "frame": "LOCAL",
                                          "waypoints": [{"x": 5.0, "y": 1.0, "tolerance": 0.5}]})
        return [await asyncio.wait_for(received.get(), 3.0) for _ in range(3)]

    got = {topic: (sample, in_loop) for topic, sample, in_loop in asyncio.run(scenario())}
    assert got["ControlRequest"][0] == {"vehicle_id": "ugv1", "operator_id": "op1",
                                        "action": "REQUEST", "authority": 5}
    assert got["VelocityCommand"][0]["vx"] == 0.8
    assert got["VelocityCommand"][0]["vy"] == 0.0
    assert got["WaypointPlan"][0]["waypoints"][0]["x"] == 5.0
    assert all(in_loop for _, in_loop in got.values())
    assert relay.counters["received"] == 3


def test_a_command_older_than_its_lifespan_is_not_delivered(make_bridge: MakeBridge) -> None:
    settings = QosSettings(command_lifespan=0.3)
    relay, operator = make_bridge(qos=settings), make_bridge(qos=settings)
    relay.subscribe(["VelocityCommand"])  # poll mode: samples wait in the reader
    assert operator.wait_for_subscribers("VelocityCommand")
    command = {"vehicle_id": "ugv1", "operator_id": "op1", "vx": 1.0}

    operator.publish("VelocityCommand", command)
    time.sleep(0.7)  # the relay is busy for longer than the lifespan
    assert relay.take() == []

    operator.publish("VelocityCommand", {**command, "vx": 2.0})
    fresh: list[tuple[str, dict[str, Any]]] = []
    assert wait_until(lambda: bool(fresh.extend(relay.take()) or fresh), timeout=0.25)
    assert [s["vx"] for _, s in fresh] == [2.0]


def test_commands_with_an_old_source_timestamp_are_dropped_when_asked(
    make_bridge: MakeBridge,
) -> None:
    relay, operator = make_bridge(max_command_age=1.0), make_bridge()
    relay.subscribe(["VelocityCommand"])
    assert operator.wait_for_subscribers("VelocityCommand")
    writer = operator._writer("VelocityCommand")
    old = model.VelocityCommand("ugv1", "op1", vx=9.0)
    writer.write(old, timestamp=time.time_ns() - 5_000_000_000)
    operator.publish("VelocityCommand", {"vehicle_id": "ugv1", "operator_id": "op1", "vx": 1.0})
    got: list[tuple[str, dict[str, Any]]] = []
    assert wait_until(lambda: bool(got.extend(relay.take()) or got))
    assert [s["vx"] for _, s in got] == [1.0]
    assert relay.counters["stale_dropped"] == 1


def test_a_bad_dict_is_rejected_before_anything_is_written(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()
    reader = operator.reader("VehicleStatus")
    with pytest.raises(EncodeError, match="'VehicleStatus'") as caught:
        relay.publish("VehicleStatus", {"vehicle_id": "ugv1", "state": "DRIVING"})
    assert caught.value.path == "state"
    with pytest.raises(KeyError, match="unknown DDS topic"):
        relay.publish("VehicleStatu", {"vehicle_id": "ugv1"})
    relay.publish("VehicleStatus", {"vehicle_id": "ugv1", "state": "STANDBY"})
    assert [s["state"] for s in reader.collect(1, 3.0)] == ["STANDBY"]
    assert reader.take(timeout=0.1) == []  # the rejected sample never went out
    assert relay.counters["published"] == 1


def test_a_vehicle_that_leaves_is_disposed(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()
    reader = operator.reader("VehicleStatus")
    for vid in ("ugv1", "ugv2"):
        relay.publish("VehicleStatus", {"vehicle_id": vid, "state": "READY", "online": True})
    assert wait_until(lambda: len(reader.read()) == 2)
    relay.dispose("VehicleStatus", "ugv1")
    assert wait_until(
        lambda: reader.instance_states() == {("ugv1",): "disposed", ("ugv2",): "alive"}
    )


def test_a_failing_callback_is_counted_and_delivery_goes_on(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()
    seen: list[float] = []

    def on_sample(topic: str, sample: dict[str, Any]) -> None:
        if sample["vx"] < 0:
            raise RuntimeError("translator bug")
        seen.append(sample["vx"])

    relay.subscribe(["VelocityCommand"], on_sample)  # delivered in the bridge's thread
    assert operator.wait_for_subscribers("VelocityCommand")
    for vx in (-1.0, 2.0):
        operator.publish("VelocityCommand", {"vehicle_id": "ugv1", "operator_id": "o", "vx": vx})
    assert wait_until(lambda: seen == [2.0])
    assert relay.counters["callback_errors"] == 1


def test_partitions_keep_relays_apart(make_bridge: MakeBridge) -> None:
    relay_a, relay_b = make_bridge(partitions=("site-a",)), make_bridge(partitions=("site-b",))
    reader_a = make_bridge(partitions=("site-a",)).reader("VehicleStatus")
    relay_b.publish("VehicleStatus", {"vehicle_id": "other", "state": "READY"})
    relay_a.publish("VehicleStatus", {"vehicle_id": "mine", "state": "READY"})
    assert [s["vehicle_id"] for s in reader_a.collect(1, 3.0)] == ["mine"]
    assert reader_a.take(timeout=0.2) == []


def test_image_products_and_chunks(make_bridge: MakeBridge) -> None:
    relay = make_bridge()
    for n in range(3):
        relay.publish("ImageProduct", {
            "vehicle_id": "uuv3", "image_id": f"img{n}", "file_name": f"sss_{n}.png",
            "size_bytes": 3 * 65536, "sha256": "ab" * 32, "format": "png",
            "targets": [{"target_class": "mine-like", "confidence": 0.8, "depth": 30.0}],
        })
    late = make_bridge()
    products = late.reader("ImageProduct").collect(3, 3.0)
    assert sorted(p["image_id"] for p in products) == ["img0", "img1", "img2"]
    assert products[0]["targets"][0]["target_class"] == "mine-like"

    chunks = late.reader("ImageData")
    assert relay.wait_for_subscribers("ImageData")
    blob = bytes(range(256)) * 768  # 192 KiB
    for i in range(3):
        relay.publish("ImageData", {"vehicle_id": "uuv3", "image_id": "img0", "chunk_index": i,
                                    "chunk_count": 3, "data": blob[i * 65536:(i + 1) * 65536]})
    got = chunks.collect(3, 5.0)
    assert [c["chunk_index"] for c in got] == [0, 1, 2]
    assert b"".join(c["data"] for c in got) == blob


def test_close_is_idempotent_and_final(make_bridge: MakeBridge) -> None:
    bridge = make_bridge()
    bridge.subscribe(None, lambda topic, sample: None)
    bridge.publish("VehicleStatus", {"vehicle_id": "ugv1"})
    bridge.close()
    bridge.close()
    with pytest.raises(DdsError, match="closed"):
        bridge.publish("VehicleStatus", {"vehicle_id": "ugv1"})
    assert bridge._thread is not None and not bridge._thread.is_alive()


def test_absent_optional_wrench_members_stay_absent_across_dds(make_bridge: MakeBridge) -> None:
    relay, operator = make_bridge(), make_bridge()
    relay.subscribe(["WrenchEffortCommand"])
    assert operator.wait_for_subscribers("WrenchEffortCommand")
    operator.publish("WrenchEffortCommand", {"vehicle_id": "ugv1", "operator_id": "op1",
                                             "propulsive_linear_x": 35.0,
                                             "propulsive_rotational_z": -10})
    got: list[tuple[str, dict[str, Any]]] = []
    assert wait_until(lambda: bool(got.extend(relay.take()) or got))
    assert got == [("WrenchEffortCommand", {"vehicle_id": "ugv1", "operator_id": "op1",
                                            "propulsive_linear_x": 35.0,
                                            "propulsive_rotational_z": -10.0})]


def test_an_explicit_cyclone_configuration_is_used(make_bridge: MakeBridge) -> None:
    with pytest.raises(DdsError, match="cannot configure DDS domain 230"):
        make_bridge(domain_id=230, config="<CycloneDDS><Domain><Bogus/></Domain></CycloneDDS>")


def test_subscribing_to_an_unknown_or_taken_topic_fails_whole(make_bridge: MakeBridge) -> None:
    relay = make_bridge()
    with pytest.raises(KeyError, match="VelocityComand"):
        relay.subscribe(["VelocityCommand", "VelocityComand"])
    relay.subscribe(["VelocityCommand"])  # the failed call created nothing
    with pytest.raises(ValueError, match="already subscribed: VelocityCommand"):
        relay.subscribe(["ControlRequest", "VelocityCommand"])


def test_only_an_operator_whose_writers_are_gone_is_reported_gone(
        make_bridge: MakeBridge) -> None:
    """Eight live stations, then one closes: only that one is reported. Each station's
    writer has its own instance handle; about half of them have the top bit set, which the
    binding reports with two signs, so a wrong comparison would call live stations gone."""
    relay = make_bridge()
    stations = {f"op{i}": make_bridge() for i in range(8)}

    async def scenario() -> tuple[list[str], list[str]]:
        loop = asyncio.get_running_loop()
        gone: list[str] = []
        seen: set[str] = set()
        relay.watch_writers(gone.append, loop=loop)
        relay.subscribe(["ControlRequest"], lambda _t, s: seen.add(s["operator_id"]), loop=loop)
        for name, station in stations.items():
            station.open_writers(["ControlRequest"])
            assert station.wait_for_subscribers("ControlRequest")
            station.publish("ControlRequest", {"vehicle_id": "ugv1", "operator_id": name,
                                               "action": "REQUEST", "authority": 5})
        deadline = loop.time() + 3.0
        while len(seen) < len(stations) and loop.time() < deadline:
            await asyncio.sleep(0.02)
        assert seen == set(stations)
        await asyncio.sleep(0.5)  # several writer checks with every station alive
        while_alive = list(gone)
        stations["op3"].close()
        deadline = loop.time() + 3.0
        while not gone and loop.time() < deadline:
            await asyncio.sleep(0.02)
        await asyncio.sleep(0.3)
        return while_alive, gone

    while_alive, after_close = asyncio.run(scenario())
    assert while_alive == []
    assert after_close == ["op3"]
