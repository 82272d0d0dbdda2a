"""Replay the JTS example component (126.1.199) from captures.md section 1 against the engine.

The capture pairs each request of a hand-written client with the datagrams the JTS
component answered. A responder built from those pairs plays the vehicle: it answers the
engine's requests with the captured bytes, and stays silent where the real component was
silent (QueryConfiguration, QueryTimeout, QueryHeartbeatPulse, CreateEvent, ...).
"""

from __future__ import annotations

import re
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import unpack_datagram
from edge_vis.kit.actions import SendMessage

from .conftest import SHARED, Harness, profile, published, sent

CAPTURES = SHARED / "jaus" / "captures.md"
CLIENT = JausAddress(42, 1, 1)
VEHICLE = JausAddress(126, 1, 199)


def _section1() -> list[Any]:
    text = CAPTURES.read_text(encoding="utf-8")
    section = text.split("## 1.", 1)[1].split("## 2.", 1)[0]
    packets = []
    for hexdata in re.findall(r"\| `([0-9a-f]+)` \|", section):
        packets.extend(unpack_datagram(bytes.fromhex(hexdata)))
    return packets


@pytest.fixture(scope="module")
def responder(catalogue: Any) -> dict[str, list[bytes]]:
    """Request message name -> payloads the JTS component answered with."""
    if not CAPTURES.exists():
        pytest.skip("shared captures not available")
    answers: dict[str, list[bytes]] = {}
    current = None
    for packet in _section1():
        if packet.source == CLIENT:
            current = catalogue.decode(packet.payload).name
            answers.setdefault(current, [])
        elif packet.source == VEHICLE and packet.payload and packet.ack_nak == 0:
            assert current is not None
            answers[current].append(packet.payload)
    return answers


@pytest.fixture(scope="module")
def client_payloads(catalogue: Any) -> dict[str, bytes]:
    """Request name -> the client's payload bytes in the capture."""
    return {catalogue.decode(p.payload).name: p.payload
            for p in _section1() if p.source == CLIENT}


class JtsVehicle:
    """Plays 126.1.199 from the capture."""

    def __init__(self, harness: Harness, answers: dict[str, list[bytes]]) -> None:
        self.h = harness
        self.answers = answers
        self.requests: list[SendMessage] = []

    def step(self, seconds: float) -> list[Any]:
        """Advance time; answer every request addressed to the vehicle as JTS did."""
        out = self.h.advance(seconds)
        pending = list(out)
        while pending:
            action = pending.pop(0)
            if not isinstance(action, SendMessage):
                continue
            if not (action.destination == VEHICLE or action.destination.is_broadcast):
                continue
            self.requests.append(action)
            for payload in self.answers.get(action.name, []):
                replies = self.h.deliver_payload(str(VEHICLE), payload)
                out.extend(replies)
                pending.extend(replies)
        return out


def run(h: Harness, vehicle: JtsVehicle, seconds: float, step: float = 0.25) -> list[Any]:
    out: list[Any] = []
    for _ in range(int(seconds / step)):
        out.extend(vehicle.step(step))
    return out


def test_discovers_polls_and_controls_the_jts_example(
    catalogue: Any, responder: dict[str, list[bytes]], client_payloads: dict[str, bytes]
) -> None:
    h = Harness(catalogue, profile(discovery={"liveness_period": 1.0}))
    jts = JtsVehicle(h, responder)
    out = run(h, jts, 12.0)

    # discovery: identified from the broadcast, services from the doubled node list
    ident = published(out, "VehicleIdentification")[-1]
    assert ident["vehicle_id"] == "SimulatedVehicle-126"
    assert ident["jaus_address"] == "126.1.199"
    uris = {s["uri"] for s in ident["services"]}
    assert {"urn:jaus:jss:mobility:LocalPoseSensor",
            "urn:jaus:jss:mobility:LocalWaypointListDriver"} <= uris
    assert "urn:jaus:jss:core:Management" in uris  # inherited, though JTS does not list it

    # events: CreateEvent went unanswered, so the pose is polled and published
    # (the waypoint list driver's active element and travel speed are asked for too)
    creates = [a for a in jts.requests if a.name == "CreateEvent"
               and a.fields["query_message"][:2] == bytes.fromhex("0324")]
    assert len(creates) == 2
    polls = [a for a in jts.requests if a.name == "QueryLocalPose"]
    assert len(polls) >= 5
    poses = published(out, "LocalPose")
    assert len(poses) >= 5
    assert poses[-1]["vehicle_id"] == "SimulatedVehicle-126"
    assert poses[-1]["x"] == pytest.approx(0.0, abs=1e-3)
    assert poses[-1]["yaw"] == pytest.approx(0.0, abs=1e-3)
    snap = h.engine.snapshot().vehicles[0]
    assert snap.subscriptions[0].state == "polling"
    # the captured ReportStatus bytes say 2 (STANDBY), whatever the prose says
    assert snap.view.online and snap.view.state == "STANDBY"

    # control: the operator asks, the relay sends exactly the captured RequestControl(100)
    out = h.sample("ControlRequest", {"vehicle_id": "SimulatedVehicle-126",
                                      "operator_id": "op1", "authority": 5,
                                      "action": "request"})
    requests = sent(out, "RequestControl", str(VEHICLE))
    assert len(requests) == 1
    assert catalogue.encode("RequestControl", requests[0].fields) == \
        client_payloads["RequestControl"]
    for payload in responder["RequestControl"]:
        h.deliver_payload(str(VEHICLE), payload)
    out = run(h, jts, 8.0)
    assert published(h.log, "ControlStatus")[-1]["state"] == "CONTROLLED"
    # QueryTimeout is ignored by JTS: control is renewed at the default period (2 s)
    renewals = sent(out, "RequestControl", str(VEHICLE))
    assert 3 <= len(renewals) <= 5
    # JTS ignores Resume and never reports READY: after bounded attempts the relay
    # proceeds, and says so
    resumes = sent(h.log, "Resume", str(VEHICLE))
    assert len(resumes) == 3
    view = h.engine.snapshot().vehicles[0].view
    assert any("status 2" in note for note in view.notes)

    # release: ReleaseControl exactly as captured; JTS answers RejectControl(0)
    out = h.sample("ControlRequest", {"vehicle_id": "SimulatedVehicle-126",
                                      "operator_id": "op1", "action": "release"})
    releases = sent(out, "ReleaseControl", str(VEHICLE))
    assert [catalogue.encode("ReleaseControl", r.fields) for r in releases] == \
        [client_payloads["ReleaseControl"]]
    for payload in responder["ReleaseControl"]:
        h.deliver_payload(str(VEHICLE), payload)
    assert h.engine.snapshot().vehicles[0].controls[VEHICLE] == "idle"
    assert published(h.log, "ControlStatus")[-1]["state"] == "NOT_CONTROLLED"
    out = run(h, jts, 4.0)
    assert not sent(out, "RequestControl")
    # the vehicle stayed online all along (QueryStatus answers keep it alive)
    assert "OFFLINE" not in {s["state"] for s in published(h.log, "VehicleStatus")}
