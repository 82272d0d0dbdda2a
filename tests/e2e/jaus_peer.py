"""A small scripted JAUS vehicle for end-to-end tests, written independently of the engine.

It is one JAUS component on a real UDP socket that answers discovery, access control,
management, liveness and pose queries, confirms CreateEvent (or ignores it, like the JAUS
Toolset example component) and records every message it receives with its arrival time.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field
from typing import Any

from edge_vis.catalogue import default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

SERVICES = (
    ("urn:jaus:jss:core:Transport", 1, 0),
    ("urn:jaus:jss:core:Events", 1, 0),
    ("urn:jaus:jss:core:AccessControl", 1, 0),
    ("urn:jaus:jss:core:Management", 1, 0),
    ("urn:jaus:jss:core:Liveness", 1, 0),
    ("urn:jaus:jss:core:Discovery", 1, 0),
    ("urn:jaus:jss:mobility:GlobalPoseSensor", 1, 0),
    ("urn:jaus:jss:mobility:PrimitiveDriver", 1, 0),
)


@dataclass
class Received:
    at: float
    source: JausAddress
    name: str | None
    fields: dict[str, Any] | None


@dataclass
class PeerState:
    controller: JausAddress | None = None
    status: int = 2  # STANDBY
    events: dict[int, tuple[JausAddress, bytes, float]] = field(default_factory=dict)
    latitude: float = 28.5
    longitude: float = -81.25


class JausPeer(asyncio.DatagramProtocol):
    """Answer like a JAUS vehicle; ``confirm_events=False`` ignores CreateEvent."""

    def __init__(self, address: JausAddress, name: str = "TestBot", *,
                 confirm_events: bool = True) -> None:
        self.address = address
        self.name = name
        self.confirm_events = confirm_events
        self.catalogue = default_catalogue()
        self.state = PeerState()
        self.received: list[Received] = []
        self.transport: asyncio.DatagramTransport | None = None
        self._seq = 1
        self._event_task: asyncio.Task[None] | None = None
        self._last_peer: tuple[str, int] | None = None

    # -- asyncio plumbing --------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self._event_task = asyncio.get_running_loop().create_task(self._events())

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self._last_peer = addr
        for packet in unpack_datagram(data):
            if packet.message_code is None:
                continue
            message = self.catalogue.decode(packet.payload)
            self.received.append(Received(time.monotonic(), packet.source, message.name,
                                          message.fields))
            if packet.destination.matches(self.address):
                self.handle(packet.source, message.name, message.fields or {}, addr)

    def send(self, to: JausAddress, name: str, fields: dict[str, Any],
             addr: tuple[str, int]) -> None:
        payload = self.catalogue.encode(name, fields)
        packet = Packet(to, self.address, payload, sequence=self._seq)
        self._seq += 1
        assert self.transport is not None
        self.transport.sendto(pack_datagram([packet]), addr)

    def close(self) -> None:
        if self._event_task:
            self._event_task.cancel()
        if self.transport:
            self.transport.close()

    # -- behaviour ---------------------------------------------------------------------
    def handle(self, src: JausAddress, name: str | None, fields: dict[str, Any],
               addr: tuple[str, int]) -> None:
        st = self.state
        reply = lambda n, f=None: self.send(src, n, f or {}, addr)  # noqa: E731
        if name == "QueryIdentification":
            reply("ReportIdentification", {"query_type": 2, "type": 10001,
                                           "identification": self.name})
        elif name == "QueryConfiguration":
            reply("ReportConfiguration", {"node_list": [{
                "node_rec": {"node_id": self.address.node},
                "component_list": [{"component_id": self.address.component,
                                    "instance_id": 0}]}]})
        elif name == "QueryServices":
            reply("ReportServices", {"node_list": [{
                "node_rec": {"node_id": self.address.node},
                "component_list": [{
                    "component_rec": {"component_id": self.address.component,
                                      "instance_id": 0},
                    "service_list": [{"uri": u, "major_version_number": a,
                                      "minor_version_number": b} for u, a, b in SERVICES],
                }]}]})
        elif name == "RequestControl":
            st.controller = src
            reply("ConfirmControl", {"response_code": 0})
        elif name == "ReleaseControl":
            st.controller = None
            st.status = 2
            reply("RejectControl", {"response_code": 0})
        elif name == "QueryControl":
            c = st.controller or JausAddress(0, 0, 0)
            reply("ReportControl", {"subsystem_id": c.subsystem, "node_id": c.node,
                                    "component_id": c.component, "authority_code": 0})
        elif name == "QueryTimeout":
            reply("ReportTimeout", {"timeout": 5})
        elif name == "Resume" and src == st.controller:
            st.status = 1
        elif name == "QueryStatus":
            reply("ReportStatus", {"status": st.status, "reserved": 0})
        elif name == "QueryHeartbeatPulse":
            reply("ReportHeartbeatPulse")
        elif name == "QueryGlobalPose":
            reply("ReportGlobalPose", self.pose())
        elif name == "CreateEvent" and self.confirm_events:
            event_id = len(st.events)
            rate = fields["requested_periodic_rate"]
            st.events[event_id] = (src, fields["query_message"], rate)
            reply("ConfirmEventRequest", {"request_id": fields["request_id"],
                                          "event_id": event_id,
                                          "confirmed_periodic_rate": rate})
        elif name == "CancelEvent":
            st.events.pop(fields["event_id"], None)
            reply("ConfirmEventRequest", {"request_id": fields["request_id"],
                                          "event_id": fields["event_id"],
                                          "confirmed_periodic_rate": 0})

    def pose(self) -> dict[str, Any]:
        return {"latitude": self.state.latitude, "longitude": self.state.longitude,
                "altitude": 12.5, "yaw": 0.25}

    async def _events(self) -> None:
        sequence = 0
        while True:
            await asyncio.sleep(0.1)
            for event_id, (dest, query, _rate) in list(self.state.events.items()):
                if query[:2] != b"\x02\x24" or self._last_peer is None:
                    continue
                report = self.catalogue.encode("ReportGlobalPose", self.pose())
                self.send(dest, "Event", {"event_id": event_id, "sequence_number": sequence,
                                          "report_message": report}, self._last_peer)
                sequence = (sequence + 1) % 256

    def names(self, name: str) -> list[Received]:
        return [r for r in self.received if r.name == name]
