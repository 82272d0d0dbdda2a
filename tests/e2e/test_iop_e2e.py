"""IOP hand-off, cost maps and UGV drive commands end to end: a vehicle on real UDP, the
relay, and operator stations as separate Cyclone DDS participants.

Two operator stations ask each other for a vehicle: the holder confirms (the other one
drives from then on), refuses (nothing changes) or does not answer in time (TIMEOUT).
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .peer_sets import SetPeer
from .test_translators_e2e import collect, command_until, relay_with, take_control, wait_for

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

IOP = "urn:jaus:jss:iop:"
UGV = "urn:jaus:jss:ugv:"
VID = "Handy-86"
RELAY_ID = JausAddress(200, 1, 1)


def vehicle() -> SetPeer:
    return SetPeer(JausAddress(86, 1, 1), (IOP + "EnhancedAccessControl", UGV + "SkidSteerDriver"),
                   {"QueryHandoffTimeout": lambda f: ("ReportHandoffTimeout", {"timeout": 20}),
                    "QueryEnhancedTimeout": lambda f: ("ReportEnhancedTimeout",
                                                       {"timeout": 0})},
                   name="Handy")


def skid(operator_id: str, effort: float) -> dict[str, Any]:
    return {"vehicle_id": VID, "operator_id": operator_id, "left_effort": effort,
            "right_effort": effort}


async def drive_reaches(station: Any, peer: SetPeer, operator_id: str, effort: float,
                        seconds: float = 1.5) -> bool:
    """Whether ``operator_id``'s skid-steer command with ``effort`` reaches the vehicle."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        station.publish("SkidSteerCommand", skid(operator_id, effort))
        await asyncio.sleep(0.1)
        if any(r.fields.get("left_side_propulsive_effort") == pytest.approx(effort, abs=0.01)
               for r in peer.names("SetSkidSteerEffort")):
            return True
    return False


async def pending_request(station: Any, requester: str) -> dict[str, Any]:
    status = await collect(station, "HandoffStatus", lambda s: any(
        r["requester"] == requester and r["state"] == "PENDING" for r in s["requests"]))
    return next(r for r in status["requests"] if r["requester"] == requester)


def with_two_stations(domain: int, partition: str, body: Any, **control: Any) -> None:
    peer = vehicle()

    async def run(runtime: Runtime, op1: Any) -> None:
        op2 = dds.DdsBridge(domain, (partition,))
        try:
            await take_control(op1, peer, VID)
            await body(peer, op1, op2)
        finally:
            op2.close()

    asyncio.run(relay_with(peer, 233, domain, partition, run,
                           extra={"control": {"handoff_timeout": 20.0, **control}}))


def test_handoff_granted_the_other_station_drives(domain_id: int, partition: str) -> None:
    async def body(peer: SetPeer, op1: Any, op2: Any) -> None:
        assert await drive_reaches(op1, peer, "op1", 11.0)
        op2.publish("HandoffRequest", {"vehicle_id": VID, "operator_id": "op2",
                                       "authority": 60, "explanation": "my sector"})
        request = await pending_request(op1, "op2")  # the holder sees it
        assert request["explanation"] == "my sector" and request["authority"] == 60
        op1.publish("HandoffResponse", {"vehicle_id": VID, "operator_id": "op1",
                                        "request_id": request["request_id"],
                                        "response": "GRANTED"})
        await collect(op2, "ControlStatus", lambda s: s["operator_id"] == "op2")
        granted = await collect(op2, "HandoffStatus", lambda s: s["holder"] == "op2")
        assert granted["requests"][0]["state"] == "GRANTED"
        assert await drive_reaches(op2, peer, "op2", 22.0)
        assert not await drive_reaches(op1, peer, "op1", 33.0, seconds=0.8)
        assert not peer.names("ReleaseControl")  # the relay kept control throughout

    with_two_stations(domain_id, partition, body)


def test_handoff_refused_changes_nothing(domain_id: int, partition: str) -> None:
    async def body(peer: SetPeer, op1: Any, op2: Any) -> None:
        op2.publish("HandoffRequest", {"vehicle_id": VID, "operator_id": "op2",
                                       "authority": 60})
        request = await pending_request(op1, "op2")
        op1.publish("HandoffResponse", {"vehicle_id": VID, "operator_id": "op1",
                                        "request_id": request["request_id"],
                                        "response": "DENIED"})
        denied = await collect(op2, "HandoffStatus", lambda s: any(
            r["state"] == "DENIED" for r in s["requests"]))
        assert denied["holder"] == "op1"
        assert not await drive_reaches(op2, peer, "op2", 44.0, seconds=0.8)
        assert await drive_reaches(op1, peer, "op1", 55.0)

    with_two_stations(domain_id, partition, body)


def test_handoff_unanswered_times_out(domain_id: int, partition: str) -> None:
    async def body(peer: SetPeer, op1: Any, op2: Any) -> None:
        op2.publish("HandoffRequest", {"vehicle_id": VID, "operator_id": "op2",
                                       "authority": 60})
        await pending_request(op1, "op2")
        lapsed = await collect(op2, "HandoffStatus", lambda s: any(
            r["state"] == "TIMEOUT" for r in s["requests"]), timeout=6.0)
        assert lapsed["holder"] == "op1" and lapsed["handoff_timeout"] == 1.0
        assert lapsed["vehicle_handoff_timeout"] == 20.0  # asked of the vehicle
        assert await drive_reaches(op1, peer, "op1", 66.0)

    with_two_stations(domain_id, partition, body, handoff_timeout=1.0)


def test_another_jaus_client_asks_through_the_vehicle(domain_id: int, partition: str) -> None:
    async def body(peer: SetPeer, op1: Any, op2: Any) -> None:
        relay = peer.controller
        assert relay is not None
        await wait_for(lambda: peer.relay, 2, "the relay's address")
        peer.send(relay, "RequestReleaseControl", {"request_release_control_list": [
            {"id": 3, "src_subsystem_id": 300, "src_node_id": 1, "src_component_id": 9,
             "authority_code": 90, "explanation": "base station"}]})
        request = await pending_request(op1, "jaus:300.1.9")
        assert request["via"] == "86.1.1"
        op1.publish("HandoffResponse", {"vehicle_id": VID, "operator_id": "op1",
                                        "request_id": request["request_id"],
                                        "response": "DENIED"})
        answer = await wait_for(lambda: peer.names("ConfirmReleaseControl"), 5,
                                "ConfirmReleaseControl")
        assert answer[-1].fields["release_control_list"] == [{"id": 3, "response_code": 1}]

    with_two_stations(domain_id, partition, body)


def test_operator_asks_a_vehicle_another_ocu_holds(domain_id: int, partition: str) -> None:
    other = JausAddress(300, 1, 9)
    peer = vehicle()
    peer.controller = other  # another operator control unit holds it

    def decide(fields: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
        if fields["authority_code"] < 100:  # not enough for the other OCU to let go
            return [("ConfirmHandoffRequest", {"id": 4, "response_code": 3})]
        peer.controller = RELAY_ID  # the other OCU let go: the requester's relay holds it
        return [("ConfirmHandoffRequest", {"id": 4, "response_code": 0})]

    peer.on_command = {"RequestHandoff": decide}

    async def body(runtime: Runtime, op1: Any) -> None:
        await wait_for(lambda: peer.names("QueryControl"), 5, "who holds it asked")
        await asyncio.sleep(0.3)
        ask = {"vehicle_id": VID, "operator_id": "op1", "authority": 50,
               "explanation": "convoy"}
        denied = None
        deadline = time.monotonic() + 6
        while denied is None and time.monotonic() < deadline:
            op1.publish("HandoffRequest", ask)
            denied = next((s for s in await asyncio.to_thread(
                op1.reader("HandoffStatus").take, 0.3) if any(
                r["state"] == "DENIED" for r in s["requests"])), None)
        assert denied is not None, "the vehicle's refusal never reached the operator"
        assert peer.names("RequestHandoff")[0].fields["explanation"] == "convoy"
        await asyncio.sleep(1.0)  # the answers to the repeated requests are all in
        op1.publish("HandoffRequest", {**ask, "authority": 120})
        await collect(op1, "HandoffStatus", lambda s: any(
            r["state"] == "GRANTED" for r in s["requests"]))
        await collect(op1, "ControlStatus", lambda s: s["operator_id"] == "op1")
        assert await drive_reaches(op1, peer, "op1", 12.0, seconds=5.0)

    asyncio.run(relay_with(peer, 239, domain_id, partition, body))


# ------------------------------------------------------------------------------ cost map

COSTS = [0, 20, 254, 255, 100, 3]
ZONE = [{"latitude": 48.10, "longitude": 11.50}, {"latitude": 48.11, "longitude": 11.50},
        {"latitude": 48.10, "longitude": 11.52}]


def test_cost_map_and_no_go_zones_both_ways(domain_id: int, partition: str) -> None:
    zones: list[dict[str, Any]] = []

    def add(fields: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
        zones.append({"zone_id_rec": {"zone_id": 40 + len(zones)},
                      "vertex_var": fields["vertex_var"]})
        return [("AddNoGoZoneResponse", {"request_id": fields["request_id_rec"]["request_id"],
                                         "response_code": 0, "zone_id": 39 + len(zones)})]

    cost_map = {"cost_map2_d_rec": {"number_of_rows": 2, "number_of_columns": 3,
                                    "map_width": 60.0, "map_height": 40.0},
                "cost_map2_d_pose_var": {"cost_map2_d_global_pose_rec": {
                    "map_center_latitude": 48.1, "map_center_longitude": 11.5,
                    "map_rotation": 0.0}},
                "cost_map2_d_data_var": {"cost_data_list": [{"cost": c} for c in COSTS]}}
    peer = SetPeer(JausAddress(87, 1, 1), (IOP + "CostMap2D",),
                   {"QueryCostMap2D": lambda f: ("ReportCostMap2D", cost_map),
                    "QueryNoGoZones": lambda f: ("ReportNoGoZones",
                                                 {"no_go_zones_list": list(zones)})},
                   name="Mapper", on_command={"AddNoGoZone": add})

    async def body(runtime: Runtime, operator: Any) -> None:
        got = await collect(operator, "CostMap", lambda s: s["vehicle_id"] == "Mapper-87")
        assert (got["rows"], got["columns"], list(got["costs"])) == (2, 3, COSTS)
        assert got["center_latitude"] == pytest.approx(48.1, abs=1e-6)
        # a region: a query, no control needed
        operator.publish("CostMapRequest", {"vehicle_id": "Mapper-87", "operator_id": "op1",
                                            "max_width": 30.0, "max_height": 30.0,
                                            "center_latitude": 48.2,
                                            "center_longitude": 11.6})
        asked = await wait_for(lambda: [r for r in peer.names("QueryCostMap2D")
                                        if r.fields.get("query_cost_map2_d_center_var")], 5,
                               "the region query")
        centre = asked[-1].fields["query_cost_map2_d_center_var"]["cost_map2_d_global_pose_rec"]
        assert centre["map_center_latitude"] == pytest.approx(48.2, abs=1e-6)
        # a no-go zone in, its id and the zone out
        await take_control(operator, peer, "Mapper-87")
        await command_until(operator, peer, "NoGoZoneCommand", {
            "vehicle_id": "Mapper-87", "operator_id": "op1", "action": "ADD",
            "request_id": 5, "vertices": ZONE}, "AddNoGoZone")
        result = await collect(operator, "RequestResult", lambda s: s["request"] == "AddNoGoZone")
        assert (result["request_id"], result["result"], result["id"]) == (5, "Success", 40)
        listed = await collect(operator, "NoGoZones", lambda s: len(s["zones"]) == 1)
        vertices = listed["zones"][0]["vertices"]
        assert [v["latitude"] for v in vertices] == pytest.approx([48.10, 48.11, 48.10],
                                                                   abs=1e-6)

    asyncio.run(relay_with(peer, 235, domain_id, partition, body))


# ------------------------------------------------------------------------------ ugv drive


def test_ugv_drive_commands_and_capabilities(domain_id: int, partition: str) -> None:
    peer = SetPeer(JausAddress(88, 1, 1), (UGV + "SkidSteerDriver", UGV + "AckermannDriver",
                                           UGV + "IlluminationService"),
                   {"QueryIlluminationConfiguration": lambda f: (
                       "ReportIlluminationConfiguration",
                       {"types": {"headlights": 1, "hazard_lights": 1}})},
                   name="Tracks")

    async def body(runtime: Runtime, operator: Any) -> None:
        fitted = await collect(operator, "DeviceCapabilities",
                               lambda s: s["device"] == "illumination")
        assert list(fitted["supported"]) == ["headlights", "hazard_lights"]
        await take_control(operator, peer, "Tracks-88")
        fields = await command_until(operator, peer, "SkidSteerCommand", {
            "vehicle_id": "Tracks-88", "operator_id": "op1", "left_effort": 40.0,
            "right_effort": -150.0}, "SetSkidSteerEffort")
        assert (fields["left_side_propulsive_effort"], fields["right_side_propulsive_effort"]
                ) == (pytest.approx(40.0, abs=0.01), pytest.approx(-100.0, abs=0.01))
        fields = await command_until(operator, peer, "AckermannCommand", {
            "vehicle_id": "Tracks-88", "operator_id": "op1", "steering_angle": 0.25,
            "throttle_effort": 30.0, "brake_effort": 0.0}, "SetAckermannConfiguration")
        assert fields["steering_angle"] == pytest.approx(0.25, abs=1e-3)
        assert "max_steering_rate" not in fields

    asyncio.run(relay_with(peer, 237, domain_id, partition, body))


# ------------------------------------------------------------------------------ the sim


class ForeignOcu(asyncio.DatagramProtocol):
    """Another operator control unit on the JAUS network (not behind the relay)."""

    def __init__(self, address: JausAddress) -> None:
        from edge_vis.catalogue import default_catalogue

        self.address = address
        self.catalogue = default_catalogue()
        self.transport: Any = None
        self.received: list[tuple[str, dict[str, Any]]] = []

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr: Any) -> None:
        from edge_vis.jaus.transport import unpack_datagram

        for packet in unpack_datagram(data):
            if packet.message_code is not None:
                message = self.catalogue.decode(packet.payload)
                self.received.append((message.name or "", message.fields or {}))

    def send(self, to: JausAddress, where: tuple[str, int], name: str,
             fields: dict[str, Any]) -> None:
        from edge_vis.jaus.transport import Packet, pack_datagram

        payload = self.catalogue.encode(name, fields)
        self.transport.sendto(pack_datagram([Packet(to, self.address, payload)]), where)


def test_sim_is_handed_to_another_ocu_by_the_holder(domain_id: int, partition: str) -> None:
    from edge_vis.config import from_mapping
    from edge_vis.tools.sim.profile import VehicleSpec
    from edge_vis.tools.sim.runner import UdpVehicle

    relay_ip, sim_ip, ocu_ip = "127.0.0.241", "127.0.0.242", "127.0.0.243"
    profile = from_mapping({
        "relay": {"jaus_id": "200.1.1"},
        "links": {"lan": {"url": f"udp://{relay_ip}:3794?peers={sim_ip}:3794"}},
        "dds": {"domain": domain_id, "partitions": [partition]},
        "discovery": {"period": 0.5, "liveness_period": 0.5},
        "commands": {"rate": 10.0, "lifespan": 2.0, "deadman_timeout": 30.0},
    }, file="iop-sim-e2e.toml")
    vid = "ugv-iop-161"
    iop_component = JausAddress(161, 1, 4)

    async def main() -> None:
        sim = UdpVehicle(VehicleSpec("ugv-iop", 161, f"udp://{sim_ip}:3794", init_time=0.1,
                                     iop=True))
        await sim.start()
        loop = asyncio.get_running_loop()
        ocu = ForeignOcu(JausAddress(300, 1, 9))
        await loop.create_datagram_endpoint(lambda: ocu, local_addr=(ocu_ip, 3794))
        runtime = Runtime(profile)
        await runtime.start()
        operator = dds.DdsBridge(domain_id, (partition,))
        try:
            vehicle = sim.vehicle
            assert vehicle is not None
            cost_map = await collect(operator, "CostMap", lambda s: s["vehicle_id"] == vid,
                                     timeout=15.0)
            assert (cost_map["rows"], cost_map["frame"]) == (20, "LOCAL")
            assert 254 in cost_map["costs"]  # the posts
            request = {"vehicle_id": vid, "operator_id": "op1", "authority": 50,
                       "action": "request"}
            deadline = time.monotonic() + 10
            while vehicle.component(4).controller is None or vehicle.component(4).state != 1:
                assert time.monotonic() < deadline, "the relay never readied the Iop component"
                operator.publish("ControlRequest", request)
                await asyncio.sleep(0.2)
            deadline = time.monotonic() + 5
            while vehicle.motion.speed < 0.3:  # the relay's skid-steer command drives it
                assert time.monotonic() < deadline, "skid-steer never drove the sim"
                operator.publish("SkidSteerCommand", {"vehicle_id": vid, "operator_id": "op1",
                                                      "left_effort": 40.0,
                                                      "right_effort": 40.0})
                await asyncio.sleep(0.1)
            # another OCU asks the sim for a hand-off; the holder sees it and grants it
            ocu.send(iop_component, (sim_ip, 3794), "RequestHandoff",
                     {"authority_code": 80, "explanation": "take over"})
            pending = await pending_request(operator, "jaus:300.1.9")
            assert pending["explanation"] == "take over"
            operator.publish("HandoffResponse", {"vehicle_id": vid, "operator_id": "op1",
                                                 "request_id": pending["request_id"],
                                                 "response": "GRANTED"})
            await wait_for(lambda: ("ConfirmHandoffRequest", {"id": 1, "response_code": 0})
                           in ocu.received, 5, "the grant at the other OCU")
            assert vehicle.component(4).controller == JausAddress(300, 1, 9)
            status = await collect(operator, "ControlStatus", lambda s: s["vehicle_id"] == vid
                                   and s["operator_id"] == "")
            assert status["operator_id"] == ""
            assert ("ConfirmHandoffRequest", {"id": 1, "response_code": 4}) in ocu.received
        finally:
            operator.close()
            await runtime.stop()
            ocu.transport.close()
            await sim.stop()

    asyncio.run(main())


# ------------------------------------------------------------------------------ CBRN, resources


def test_cbrn_payload_and_digital_resources(domain_id: int, partition: str) -> None:
    peer = SetPeer(JausAddress(89, 1, 1), (IOP + "CBRNSensor", IOP + "DigitalResourceDiscovery"),
                   {"QueryCBRNOperatingState": lambda f: ("CBRNOperatingState", {
                       "station_number": 4, "payload_state": 2, "battery_remaining": 61.0}),
                    "QueryCBRN4": lambda f: ("CBRN4", {"station_number": 4,
                                                       "detection_type": 1,
                                                       "cbrn4": "ALFA/CAM-3//"})},
                   name="Sniffer", on_command={
                       "RegisterDigitalResourceEndpoint": lambda f: [(
                           "ConfirmDigitalResourceEndpoint",
                           {"id": 31, "request_id": f["request_id_rec"]["request_id"]})]})

    async def body(runtime: Runtime, operator: Any) -> None:
        status = await collect(operator, "CbrnStatus", lambda s: s["vehicle_id"] == "Sniffer-89")
        assert (status["station"], status["payload_state"]) == (3, "Above Threshold")
        detection = await collect(operator, "CbrnDetection", lambda s: s["kind"] == "CBRN4")
        assert (detection["detection"], detection["text"]) == ("Above Threshold", "ALFA/CAM-3//")
        await take_control(operator, peer, "Sniffer-89")
        fields = await command_until(operator, peer, "CbrnCommand", {
            "vehicle_id": "Sniffer-89", "operator_id": "op1", "station": 3, "kind": "COMMAND",
            "settings": [{"name": "set_sampling_mode", "text": "Start Sampling",
                          "number": float("nan")}]}, "CBRNCommand")
        assert (fields["station_number"], fields["set_sampling_mode"]) == (4, 1)
        fields = await command_until(operator, peer, "DigitalResourceCommand", {
            "vehicle_id": "Sniffer-89", "operator_id": "op1", "action": "REGISTER",
            "request_id": 7, "url": "rtsp://10.1.1.2/cam", "server_type": "RTSP"},
            "RegisterDigitalResourceEndpoint")
        assert fields["digital_resource_endpoint_rec"]["server_url"] == "rtsp://10.1.1.2/cam"
        result = await collect(operator, "RequestResult",
                               lambda s: s["request"] == "DigitalResourceEndpoint")
        assert (result["request_id"], result["id"]) == (7, 31)

    asyncio.run(relay_with(peer, 231, domain_id, partition, body))
