"""A JAUS vehicle with two Management components, written from the Management JSIDL.

:class:`ManagedRobot` is one subsystem (node 1) whose components 1 (PrimitiveDriver,
Management, AccessControl) and 2 (Management, AccessControl; a payload, say) follow the
protocol behaviour of ``urn:jaus:jss:core:Management`` 1.1 as written, not the relay's
reading of it:

* SetEmergency from anyone (controlling or not) pushes EMERGENCY and stores the sender;
  ClearEmergency is obeyed only from a stored sender, and the component pops back once
  every stored sender has cleared (``pop_to`` overrides where it pops to, for a vehicle
  that comes back in STANDBY);
* in EMERGENCY: RequestControl gets ConfirmControl NOT_AVAILABLE (the controller keeps
  control), ReleaseControl gets RejectControl NOT_AVAILABLE, control does not time out,
  Resume/Standby/Reset/Shutdown/SetAuthority are ignored;
* Resume from the controller takes STANDBY to READY; SetWrenchEffort is obeyed only from
  the controller in READY.

Every message received is logged with the component's state on arrival, so a test can
say what reached the vehicle in which state. ``silent`` makes the whole vehicle drop
everything (out of radio range). :class:`ManagedRobotUdp` puts it on a real UDP socket.
Only the catalogue (the wire codec) is shared with the product.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram

CORE = "urn:jaus:jss:core:"
MOBILITY = "urn:jaus:jss:mobility:"
INITIALIZE, READY, STANDBY, SHUTDOWN, FAILURE, EMERGENCY = range(6)
NOT_AVAILABLE = 1
CONTROL_TIMEOUT = 5


@dataclass
class Arrival:
    """One message as the vehicle got it."""

    at: float
    component: int
    source: JausAddress
    name: str
    fields: dict[str, Any]
    state: int


@dataclass
class Component:
    """One component's Management and AccessControl state."""

    id: int
    services: tuple[str, ...]
    state: int = STANDBY
    controller: JausAddress | None = None
    control_until: float = 0.0
    emergency_ids: set[JausAddress] = field(default_factory=set)
    pushed_from: int = STANDBY
    obeyed: list[tuple[float, dict[str, Any]]] = field(default_factory=list)


class ManagedRobot:
    """See the module docstring."""

    def __init__(self, subsystem: int = 88, *, name: str = "ManagedBot",
                 pop_to: int | None = None) -> None:
        self.subsystem = subsystem
        self.name = name
        self.pop_to = pop_to
        self.silent = False
        base = (CORE + "AccessControl", CORE + "Management")
        self.components = {
            1: Component(1, (*base, MOBILITY + "PrimitiveDriver")),
            2: Component(2, base),
        }
        self.log: list[Arrival] = []

    def address(self, component: int) -> JausAddress:
        return JausAddress(self.subsystem, 1, component)

    def arrivals(self, name: str, component: int | None = None) -> list[Arrival]:
        return [a for a in self.log if a.name == name
                and (component is None or a.component == component)]

    # -- the protocol --------------------------------------------------------------------
    def handle(self, source: JausAddress, dest: JausAddress, name: str,
               fields: Mapping[str, Any], now: float) -> list[tuple[JausAddress, JausAddress,
                                                                    str, dict[str, Any]]]:
        if self.silent:
            return []
        out: list[tuple[JausAddress, JausAddress, str, dict[str, Any]]] = []
        for comp in self.components.values():
            me = self.address(comp.id)
            if not dest.matches(me):
                continue
            self.log.append(Arrival(now, comp.id, source, name, dict(fields), comp.state))
            for reply_name, reply_fields in self._handle(comp, source, name, fields, now):
                out.append((me, source, reply_name, reply_fields))
        return out

    def _handle(self, comp: Component, source: JausAddress, name: str,
                fields: Mapping[str, Any], now: float) -> list[tuple[str, dict[str, Any]]]:
        emergency = comp.state == EMERGENCY
        if name == "QueryIdentification":
            if comp.id != 1:
                return []
            return [("ReportIdentification", {"query_type": int(fields["query_type"]),
                                              "type": 10001, "identification": self.name})]
        if name == "QueryConfiguration":
            return [("ReportConfiguration", {"node_list": [{
                "node_rec": {"node_id": 1},
                "component_list": [{"component_id": c, "instance_id": 0}
                                   for c in self.components]}]})]
        if name == "QueryServices":
            return [("ReportServices", {"node_list": [{
                "node_rec": {"node_id": 1},
                "component_list": [{
                    "component_rec": {"component_id": c.id, "instance_id": 0},
                    "service_list": [{"uri": u, "major_version_number": 1,
                                      "minor_version_number": 1} for u in c.services]}
                    for c in self.components.values()]}]})]
        if name == "QueryStatus":
            return [("ReportStatus", {"status": comp.state, "reserved": 0})]
        if name == "QueryTimeout":
            return [("ReportTimeout", {"timeout": CONTROL_TIMEOUT})]
        if name == "SetEmergency":
            if not emergency:
                comp.pushed_from = comp.state
                comp.state = EMERGENCY
            comp.emergency_ids.add(source)
            return []
        if name == "ClearEmergency":
            if emergency and source in comp.emergency_ids:  # guard isIDStored
                comp.emergency_ids.discard(source)
                if not comp.emergency_ids:
                    comp.state = self.pop_to if self.pop_to is not None else comp.pushed_from
                    comp.control_until = now + CONTROL_TIMEOUT
            return []
        if name == "RequestControl":
            if emergency:  # Receiving.Ready.*.NotAvailable.Emergency
                return [("ConfirmControl", {"response_code": NOT_AVAILABLE})]
            if comp.controller is None or comp.controller == source \
                    or now > comp.control_until:
                comp.controller = source
                comp.control_until = now + CONTROL_TIMEOUT
                return [("ConfirmControl", {"response_code": 0})]
            return [("ConfirmControl", {"response_code": 2})]
        if name == "ReleaseControl" and source == comp.controller:
            if emergency:
                return [("RejectControl", {"response_code": NOT_AVAILABLE})]
            comp.controller = None
            if comp.state == READY:
                comp.state = STANDBY
            return [("RejectControl", {"response_code": 0})]
        if emergency:
            return []  # Resume, Standby, Reset, Shutdown, SetAuthority: internal
        if name == "Resume" and source == comp.controller and comp.state == STANDBY:
            comp.state = READY
        elif name == "SetWrenchEffort" and source == comp.controller and comp.state == READY:
            comp.obeyed.append((now, dict(fields)))
        return []


class ManagedRobotUdp(asyncio.DatagramProtocol):
    """:class:`ManagedRobot` on a real UDP socket, answering whoever sent to it."""

    def __init__(self, robot: ManagedRobot, catalogue: Catalogue | None = None) -> None:
        self.robot = robot
        self.catalogue = catalogue or default_catalogue()
        self.transport: asyncio.DatagramTransport | None = None
        self._seq = 1
        #: (arrival time, message code) of every packet on the wire, silent or not
        self.packets: list[tuple[float, int | None]] = []

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        now = time.monotonic()
        for packet in unpack_datagram(data):
            self.packets.append((now, packet.message_code))
            if packet.message_code is None:
                continue
            message = self.catalogue.decode(packet.payload)
            for src, dest, name, fields in self.robot.handle(
                    packet.source, packet.destination, message.name or "",
                    message.fields or {}, now):
                payload = self.catalogue.encode(name, fields)
                reply = Packet(dest, src, payload, sequence=self._seq)
                self._seq = (self._seq + 1) % 0x10000
                if self.transport is not None:
                    self.transport.sendto(pack_datagram([reply]), addr)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
