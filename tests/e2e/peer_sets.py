"""A scriptable JAUS vehicle on a real UDP socket for end-to-end tests.

Written independently of the engine: it answers discovery (or stays silent and sends a
vendor hello instead), access control, management and liveness, and for the service sets
under test it answers every query named in ``reports`` - directly, or as Event messages at
the confirmed rate once the relay created an event (each event numbering its own Events),
or, with ``confirm_events=False``, never confirming an event, like the JAUS Toolset's
example component. A report larger than ``mtu`` goes out as an AS5669A large data set
(FIRST/MIDDLE/LAST fragments). ``on_command`` scripts answers to commands (a
ConfirmElementRequest for a SetElement). Everything received is recorded with its source
and arrival time. :func:`pose_peer` is the plain vehicle most relay tests need.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import fragment
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

CORE = ("urn:jaus:jss:core:Transport", "urn:jaus:jss:core:Events",
        "urn:jaus:jss:core:AccessControl", "urn:jaus:jss:core:Management",
        "urn:jaus:jss:core:Liveness", "urn:jaus:jss:core:Discovery")

Report = Callable[[dict[str, Any]], tuple[str, dict[str, Any]]]
Replies = Callable[[dict[str, Any]], list[tuple[str, dict[str, Any]]]]


@dataclass
class Received:
    at: float
    name: str | None
    fields: dict[str, Any]
    source: JausAddress | None = None


class SetPeer(asyncio.DatagramProtocol):
    """One JAUS component offering ``services`` and answering the queries in ``reports``.

    ``reports`` maps a query name to a function of the query's fields giving the report
    ``(name, fields)``; ``version`` is what it reports for ``services``.
    ``discoverable=False`` ignores QueryIdentification/QueryServices (a vehicle that only
    says hello).
    """

    def __init__(self, address: JausAddress, services: tuple[str, ...],
                 reports: dict[str, Report], *, name: str = "SetBot",
                 catalogue: Catalogue | None = None, mtu: int = 1400,
                 discoverable: bool = True, confirm_events: bool = True,
                 on_command: dict[str, Replies] | None = None,
                 version: tuple[int, int] = (1, 0)) -> None:
        self.address = address
        self.services = CORE + services
        #: the version it reports for ``services`` (the core ones are 1.0)
        self.versions = {u: (1, 0) for u in CORE} | {u: version for u in services}
        self.reports = reports
        self.name = name
        self.catalogue = catalogue or default_catalogue()
        self.mtu = mtu
        self.discoverable = discoverable
        self.confirm_events = confirm_events
        self.on_command = on_command or {}
        self.received: list[Received] = []
        self.transport: asyncio.DatagramTransport | None = None
        self.relay: tuple[str, int] | None = None
        self.controller: JausAddress | None = None
        self.status = 2  # STANDBY until Resume
        self.events: dict[int, tuple[JausAddress, str, dict[str, Any], float]] = {}
        self._seq = 1
        self._tasks: list[asyncio.Task[None]] = []

    # -- plumbing ------------------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self._tasks.append(asyncio.get_running_loop().create_task(self._event_loop()))

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.relay = addr
        for packet in unpack_datagram(data):
            if packet.message_code is None:
                continue
            message = self.catalogue.decode(packet.payload)
            fields = message.fields or {}
            self.received.append(Received(time.monotonic(), message.name, fields,
                                          packet.source))
            if packet.destination.matches(self.address):
                self.handle(packet.source, message.name, fields)

    def send(self, to: JausAddress, name: str, fields: dict[str, Any]) -> None:
        payload = self.catalogue.encode(name, fields)
        self.send_payload(to, payload)

    def send_payload(self, to: JausAddress, payload: bytes) -> None:
        if self.transport is None or self.relay is None:
            return
        packets = fragment(Packet(to, self.address, payload, sequence=self._seq), self.mtu)
        self._seq = (self._seq + len(packets)) % 0x10000
        for packet in packets:
            self.transport.sendto(pack_datagram([packet]), self.relay)

    def close(self) -> None:
        for task in self._tasks:
            task.cancel()
        if self.transport:
            self.transport.close()

    def start_hello(self, relay: tuple[str, int], to: JausAddress, fields: dict[str, Any],
                    period: float = 0.3) -> None:
        """Send a VendorHello to the relay every ``period`` seconds."""
        self.relay = relay

        async def loop() -> None:
            while True:
                self.send(to, "VendorHello", fields)
                await asyncio.sleep(period)

        self._tasks.append(asyncio.get_running_loop().create_task(loop()))

    # -- behaviour -----------------------------------------------------------------------
    def handle(self, src: JausAddress, name: str | None, fields: dict[str, Any]) -> None:
        reply = lambda n, f=None: self.send(src, n, f or {})  # noqa: E731
        if name in ("QueryIdentification", "QueryConfiguration", "QueryServices") \
                and not self.discoverable:
            return
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
                    "service_list": [{"uri": u, "major_version_number": self.versions[u][0],
                                      "minor_version_number": self.versions[u][1]}
                                     for u in self.services],
                }]}]})
        elif name == "RequestControl":
            self.controller = src
            reply("ConfirmControl", {"response_code": 0})
        elif name == "ReleaseControl":
            self.controller, self.status = None, 2
            reply("RejectControl", {"response_code": 0})
        elif name == "QueryControl":
            c = self.controller or JausAddress(0, 0, 0)
            reply("ReportControl", {"subsystem_id": c.subsystem, "node_id": c.node,
                                    "component_id": c.component, "authority_code": 0})
        elif name == "QueryTimeout":
            reply("ReportTimeout", {"timeout": 5})
        elif name == "Resume" and src == self.controller:
            self.status = 1
        elif name == "QueryStatus":
            reply("ReportStatus", {"status": self.status, "reserved": 0})
        elif name == "QueryHeartbeatPulse":
            reply("ReportHeartbeatPulse")
        elif name == "CreateEvent" and not self.confirm_events:
            return  # neither confirmed nor rejected: the relay must fall back to polling
        elif name == "CreateEvent":
            query = self.catalogue.decode(fields["query_message"])
            if query.name not in self.reports:
                reply("RejectEventRequest", {"request_id": fields["request_id"],
                                             "response_code": 1})
                return
            event_id = len(self.events) + 1
            rate = float(fields["requested_periodic_rate"]) or 5.0
            self.events[event_id] = (src, query.name or "", query.fields or {}, rate)
            reply("ConfirmEventRequest", {"request_id": fields["request_id"],
                                          "event_id": event_id,
                                          "confirmed_periodic_rate": rate})
        elif name == "CancelEvent":
            self.events.pop(fields["event_id"], None)
            reply("ConfirmEventRequest", {"request_id": fields["request_id"],
                                          "event_id": fields["event_id"],
                                          "confirmed_periodic_rate": 0})
        elif name in self.reports:
            reply(*self.reports[name](fields))
        elif name in self.on_command:
            for answer in self.on_command[name](fields):
                reply(*answer)

    async def _event_loop(self) -> None:
        sequences: dict[int, int] = {}  # per event, as the Events service numbers them
        due: dict[int, float] = {}
        while True:
            await asyncio.sleep(0.05)
            now = time.monotonic()
            for event_id, (dest, query, fields, rate) in list(self.events.items()):
                if now < due.get(event_id, 0.0):
                    continue
                due[event_id] = now + 1.0 / min(max(rate, 0.5), 10.0)
                name, report = self.reports[query](fields)
                inner = self.catalogue.encode(name, report)
                sequence = sequences.get(event_id, 0)
                self.send_payload(dest, self.catalogue.wrap_event(event_id, sequence, inner))
                sequences[event_id] = (sequence + 1) % 256

    def names(self, name: str) -> list[Received]:
        return [r for r in self.received if r.name == name]


MOBILITY = ("urn:jaus:jss:mobility:GlobalPoseSensor", "urn:jaus:jss:mobility:PrimitiveDriver")
#: where :func:`pose_peer` says it is
POSE = {"latitude": 28.5, "longitude": -81.25, "altitude": 12.5, "yaw": 0.25}


def pose_peer(address: JausAddress, name: str = "TestBot", *,
              confirm_events: bool = True) -> SetPeer:
    """A vehicle with a global pose sensor and a primitive driver that reports :data:`POSE`."""
    return SetPeer(address, MOBILITY, {"QueryGlobalPose": lambda f: ("ReportGlobalPose", POSE)},
                   name=name, confirm_events=confirm_events)
