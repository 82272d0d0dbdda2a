"""Two real robots' ways of answering discovery, as test peers written from their captures.

* :class:`JausppRobot` plays the JAUS++ robot 150.1.1 of ``captures-jauspp.md``: it honours
  the QueryIdentification type, answers QueryConfiguration, and in QueryServices looks node
  and component IDs up *literally* (255 finds nothing, an empty node list means "all"); it
  lists core services at v1.0, numbers event IDs per report type, gives control with a
  5 s timeout (released when not renewed), goes READY on Resume from its controller and
  sends Events periodically or on every change (its simulation updates at 25 Hz). On
  first contact it asks the stranger QueryIdentification(2) and QueryConfiguration(2).
* :class:`JtsExample` plays the JAUS Toolset example component 126.1.199 of
  ``captures.md`` / ``wire-facts.md``: a type-2 ReportIdentification whatever the type
  asked, node 1 listed once per service in ReportServices, INITIALIZE forever, and no
  answer to QueryConfiguration, CreateEvent, QueryControl, QueryTimeout,
  QueryHeartbeatPulse or Resume.

Both are sans-I/O: ``handle(source, name, fields, now)`` returns the replies as
``(destination, name, fields)`` and ``tick(now)`` what the robot sends by itself.
:class:`EnginePeers` plays them against an engine on a fake clock; :class:`UdpPeer` puts
one on a real UDP socket. Only the catalogue (the wire codec) is shared with the product.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

#: What JAUS++ (150.1.1) and a relay (42.1.1) exchanged on real UDP when the relay asked
#: QueryServices with node and component 255 (JUDP datagrams, hex): JAUS++ found no node
#: 255 and reported no node at all.
WILDCARD_EXCHANGE: tuple[tuple[str, str, str, str], ...] = (
    ("42.1.1", "150.1.1", "QueryServices", "02001400010101960001012a00032b01ff01ff0400"),
    ("150.1.1", "42.1.1", "ReportConfiguration",
     "020015000101012a0001019600014b01010101000700"),
    ("150.1.1", "42.1.1", "ReportServices", "020011000101012a0001019600034b000800"),
)

CORE = "urn:jaus:jss:core:"
MOBILITY = "urn:jaus:jss:mobility:"

Reply = tuple[JausAddress, str, dict[str, Any]]

JAUSPP = JausAddress(150, 1, 1)
JTS = JausAddress(126, 1, 199)


class Robot(Protocol):
    """A sans-I/O test robot."""

    address: JausAddress

    def handle(self, source: JausAddress, name: str, fields: Mapping[str, Any],
               now: float) -> list[Reply]: ...

    def tick(self, now: float) -> list[Reply]: ...


def _node_list(node: int, component: int, uris: Iterable[str]) -> list[dict[str, Any]]:
    return [{"node_rec": {"node_id": node}, "component_list": [{
        "component_rec": {"component_id": component, "instance_id": 0},
        "service_list": [{"uri": u, "major_version_number": 1, "minor_version_number": 0}
                         for u in uris]}]}]


@dataclass
class _Event:
    client: JausAddress
    event_id: int
    query: str
    query_fields: dict[str, Any]
    periodic: bool
    rate: float
    due: float
    sequence: int = 0


#: ReportX for QueryX (the query/report pairs the robots answer)
_REPORT_OF = {"QueryGlobalPose": "ReportGlobalPose", "QueryLocalPose": "ReportLocalPose",
              "QueryVelocityState": "ReportVelocityState"}


class JausppRobot:
    """The JAUS++ robot of ``captures-jauspp.md`` (one node, one component)."""

    SERVICES = tuple(CORE + s for s in ("AccessControl", "Discovery", "Events", "Liveness",
                                        "Management", "Time", "Transport")) + tuple(
        MOBILITY + s for s in ("GlobalPoseSensor", "LocalPoseSensor", "PrimitiveDriver",
                               "VelocityStateSensor"))
    CONTROL_TIMEOUT = 5  # seconds, the library default
    POSE = {"latitude": 28.538426, "longitude": -81.3792, "altitude": 30.0, "yaw": 0.5}

    def __init__(self, catalogue: Catalogue, address: JausAddress = JAUSPP,
                 *, name: str = "JausppRobot", update_rate: float = 25.0) -> None:
        self.catalogue = catalogue
        self.address = address
        self.name = name
        self.update_rate = update_rate
        self.controller: JausAddress | None = None
        self.control_until = 0.0
        #: times a controller lost control by not renewing it in time
        self.control_timeouts = 0
        self.status = 2  # STANDBY after start-up
        self.events: list[_Event] = []
        self.known: set[int] = set()
        self.received: list[tuple[float, JausAddress, str, dict[str, Any]]] = []
        self.commands: list[tuple[str, dict[str, Any]]] = []

    # -- discovery -------------------------------------------------------------------------
    def services_report(self, query: Mapping[str, Any]) -> dict[str, Any]:
        """ReportServices for ``query`` as JAUS++ builds it: IDs looked up literally."""
        nodes = query.get("node_list") or []
        if not nodes:  # an empty list: every node and component
            return {"node_list": _node_list(self.address.node, self.address.component,
                                            self.SERVICES)}
        for node in nodes:
            if node["node_rec"]["node_id"] != self.address.node:
                continue  # 255 is just another node ID that does not exist
            for comp in node["component_list"]:
                if comp["component_id"] == self.address.component:
                    return {"node_list": _node_list(self.address.node,
                                                    self.address.component, self.SERVICES)}
        return {"node_list": []}

    def _identification(self, query_type: int) -> dict[str, Any]:
        if query_type == 3:
            return {"query_type": 3, "type": 40001, "identification": "SimNode"}
        if query_type == 4:
            return {"query_type": 4, "type": 60001, "identification": "SimRobot"}
        return {"query_type": query_type, "type": 10001, "identification": self.name}

    # -- the robot ---------------------------------------------------------------------------
    def handle(self, source: JausAddress, name: str, fields: Mapping[str, Any],
               now: float) -> list[Reply]:
        self.received.append((now, source, name, dict(fields)))
        out: list[Reply] = []

        def reply(n: str, f: dict[str, Any] | None = None) -> None:
            out.append((source, n, f or {}))

        if source.subsystem not in self.known:  # its Discovery probes every newcomer
            self.known.add(source.subsystem)
            reply("QueryIdentification", {"query_type": 2})
            reply("QueryConfiguration", {"query_type": 2})
        if name == "QueryIdentification":
            reply("ReportIdentification", self._identification(int(fields["query_type"])))
        elif name == "QueryConfiguration":
            reply("ReportConfiguration", {"node_list": [{
                "node_rec": {"node_id": self.address.node},
                "component_list": [{"component_id": self.address.component,
                                    "instance_id": 0}]}]})
        elif name == "QueryServices":
            reply("ReportServices", self.services_report(fields))
        elif name == "QueryStatus":
            reply("ReportStatus", {"status": self.status, "reserved": 0})
        elif name == "QueryHeartbeatPulse":
            reply("ReportHeartbeatPulse")
        elif name == "QueryTimeout":
            reply("ReportTimeout", {"timeout": self.CONTROL_TIMEOUT})
        elif name == "QueryAuthority":
            reply("ReportAuthority", {"authority_code": 0})
        elif name == "RequestControl":
            if self.controller in (None, source):
                self.controller = source
                self.control_until = now + self.CONTROL_TIMEOUT * 1.1
                reply("ConfirmControl", {"response_code": 0})
            else:
                reply("ConfirmControl", {"response_code": 2})
        elif name == "ReleaseControl" and source == self.controller:
            self.controller, self.status = None, 2
            reply("RejectControl", {"response_code": 0})
        elif name == "QueryControl":
            c = self.controller or JausAddress(0, 0, 0)
            reply("ReportControl", {"subsystem_id": c.subsystem, "node_id": c.node,
                                    "component_id": c.component, "authority_code": 0})
        elif name == "Resume" and source == self.controller:
            self.status = 1
        elif name in ("SetWrenchEffort",) and source == self.controller:
            self.commands.append((name, dict(fields)))
        elif name in _REPORT_OF:
            reply(_REPORT_OF[name], self._report(_REPORT_OF[name], now))
        elif name == "CreateEvent":
            out += self._create_event(source, fields, now)
        elif name == "CancelEvent":
            for event in self.events:
                if event.client == source and event.event_id == fields["event_id"]:
                    self.events.remove(event)
                    break
            reply("ConfirmEventRequest", {"request_id": fields["request_id"],
                                          "event_id": fields["event_id"],
                                          "confirmed_periodic_rate": 0})
        # QueryServiceList, QueryEventTimeout (core v1.1): unknown to JAUS++, no answer
        return out

    def _create_event(self, source: JausAddress, fields: Mapping[str, Any],
                      now: float) -> list[Reply]:
        query = self.catalogue.decode(bytes(fields["query_message"]))
        if query.name not in _REPORT_OF:
            return [(source, "RejectEventRequest", {"request_id": fields["request_id"],
                                                    "response_code": 1})]
        periodic = int(fields["event_type"]) == 0
        rate = float(fields["requested_periodic_rate"]) if periodic else 0.0
        same = [e for e in self.events if e.query == query.name]
        for event in same:  # a subscription to the same query is shared and updated
            if event.client == source and event.periodic == periodic:
                event.rate = max(event.rate, rate)
                break
        else:  # event IDs are numbered per report type
            event = _Event(source, len(same), query.name or "", dict(query.fields or {}),
                           periodic, rate, now)
            self.events.append(event)
        return [(source, "ConfirmEventRequest", {"request_id": fields["request_id"],
                                                 "event_id": event.event_id,
                                                 "confirmed_periodic_rate": rate})]

    def _report(self, report: str, now: float) -> dict[str, Any]:
        if report == "ReportGlobalPose":
            return dict(self.POSE)
        if report == "ReportLocalPose":
            return {"x": 1.5, "y": -2.0, "yaw": 0.5}
        return {"velocity_x": 0.5, "yaw_rate": 0.0}

    def tick(self, now: float) -> list[Reply]:
        out: list[Reply] = []
        if self.controller is not None and now > self.control_until:
            out.append((self.controller, "RejectControl", {"response_code": 0}))
            self.controller, self.status = None, 2
            self.control_timeouts += 1
        for event in self.events:
            if now < event.due:
                continue
            rate = event.rate if event.periodic else self.update_rate
            event.due = now + 1.0 / max(rate, 0.1)
            inner = self.catalogue.encode(_REPORT_OF[event.query],
                                          self._report(_REPORT_OF[event.query], now))
            out.append((event.client, "Event", {"event_id": event.event_id,
                                                "sequence_number": event.sequence,
                                                "report_message": inner}))
            event.sequence = (event.sequence + 1) % 256
        return out


class JtsExample:
    """The JAUS Toolset example component ``WaypointDriver_199`` (126.1.199)."""

    SERVICES = (MOBILITY + "LocalPoseSensor", MOBILITY + "LocalWaypointListDriver")

    def __init__(self, address: JausAddress = JTS) -> None:
        self.address = address
        self.controller: JausAddress | None = None
        self.received: list[tuple[float, JausAddress, str, dict[str, Any]]] = []

    def handle(self, source: JausAddress, name: str, fields: Mapping[str, Any],
               now: float) -> list[Reply]:
        self.received.append((now, source, name, dict(fields)))
        if name == "QueryIdentification":  # whatever the type asked
            answer = {"query_type": 2, "type": 10001, "identification": "SimulatedVehicle"}
            return [(source, "ReportIdentification", answer)]
        if name == "QueryServices":  # node 1 once per service, core services not listed
            nodes = [node for uri in self.SERVICES
                     for node in _node_list(self.address.node, self.address.component, [uri])]
            return [(source, "ReportServices", {"node_list": nodes})]
        if name == "QueryStatus":
            return [(source, "ReportStatus", {"status": 0, "reserved": 0})]  # INITIALIZE
        if name == "RequestControl":
            self.controller = source
            return [(source, "ConfirmControl", {"response_code": 0})]
        if name == "ReleaseControl":
            self.controller = None
            return [(source, "RejectControl", {"response_code": 0})]
        if name == "QueryLocalPose":
            return [(source, "ReportLocalPose", {"x": 0.0, "y": 0.0, "yaw": 0.0})]
        return []  # QueryConfiguration, CreateEvent, QueryControl, QueryTimeout, ...

    def tick(self, now: float) -> list[Reply]:
        return []


def names(robot: JausppRobot | JtsExample, name: str) -> list[dict[str, Any]]:
    """The fields of every ``name`` the robot received."""
    return [fields for _at, _src, n, fields in robot.received if n == name]


class EnginePeers:
    """Plays robots against an engine test harness: every message crosses the codec."""

    def __init__(self, harness: Any, *robots: Robot) -> None:
        self.h = harness
        self.robots = robots
        self.relay = harness.engine.profile.jaus_id

    def run(self, seconds: float, step: float = 0.05) -> list[Any]:
        """Advance the clock in ``step``s; robots answer and send on their own."""
        out: list[Any] = []
        for _ in range(round(seconds / step)):
            out += self.route(self.h.advance(step))
            for robot in self.robots:
                for _dest, name, fields in robot.tick(self.h.now):
                    out += self.route(self.h.deliver(robot.address, name, fields))
        return out

    def route(self, actions: list[Any]) -> list[Any]:
        """Hand the engine's messages to the robots they address; deliver the answers."""
        from edge_vis.kit.actions import SendMessage

        out = list(actions)
        pending = list(actions)
        while pending:
            action = pending.pop(0)
            if not isinstance(action, SendMessage):
                continue
            code: str | int = action.name
            if action.service_set is not None:
                code = self.h.catalogue.by_name(action.name, action.service_set).code
            message = self.h.catalogue.decode(self.h.catalogue.encode(code,
                                                                      dict(action.fields)))
            for robot in self.robots:
                if not action.destination.matches(robot.address):
                    continue
                for _dest, name, fields in robot.handle(self.relay, message.name or "",
                                                        message.fields or {}, self.h.now):
                    replies = self.h.deliver(robot.address, name, fields)
                    out += replies
                    pending += replies
        return out


class UdpPeer(asyncio.DatagramProtocol):
    """One robot on a real UDP socket, answering whoever sent to it."""

    def __init__(self, robot: Robot, catalogue: Catalogue | None = None) -> None:
        self.robot = robot
        self.catalogue = catalogue or default_catalogue()
        self.transport: asyncio.DatagramTransport | None = None
        self.remote: tuple[str, int] | None = None
        self._seq = 1
        self._task: asyncio.Task[None] | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]
        self._task = asyncio.get_running_loop().create_task(self._ticks())

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.remote = addr
        for packet in unpack_datagram(data):
            if packet.message_code is None or not packet.destination.matches(
                    self.robot.address):
                continue
            message = self.catalogue.decode(packet.payload)
            self._send(self.robot.handle(packet.source, message.name or "",
                                         message.fields or {}, time.monotonic()))

    def _send(self, replies: list[Reply]) -> None:
        if self.transport is None or self.remote is None:
            return
        for dest, name, fields in replies:
            payload = self.catalogue.encode(name, fields)
            packet = Packet(dest, self.robot.address, payload, sequence=self._seq)
            self._seq = (self._seq + 1) % 0x10000
            self.transport.sendto(pack_datagram([packet]), self.remote)

    async def _ticks(self) -> None:
        while True:
            await asyncio.sleep(0.02)
            self._send(self.robot.tick(time.monotonic()))

    def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
        if self.transport is not None:
            self.transport.close()
