"""A JAUS robot that another client controls, written from the AS5710 JSIDL for the tests.

:class:`ContestedRobot` is one component (node 1, component 1) offering AccessControl,
Management and Time, played by its own rules (not the product's code):

* AccessControl: ``QueryControl`` -> ReportControl with the controlling client's address
  and the current authority (zeros when nobody controls it); ``QueryAuthority`` ->
  ReportAuthority; ``RequestControl`` above the current authority preempts (the old
  controller gets RejectControl), from the controller itself it sets the authority
  (if not below the default), else ConfirmControl INSUFFICIENT_AUTHORITY; ``SetAuthority``
  from the controller only, within [default, current]; ``ReleaseControl`` from the
  controller -> RejectControl CONTROL_RELEASED.
* Management: Standby/Resume between STANDBY and READY from the controller; Shutdown and
  Reset from the controller end its control (RejectControl) -> SHUTDOWN / STANDBY.
* Time: ReportTime of a clock ``clock_offset`` seconds off UTC; SetTime from the
  controller only.

It starts controlled by ``FOREIGN`` (another operator control unit) with authority
``foreign_authority``; :meth:`ContestedRobot.foreign_release` lets that client go.
"""

from __future__ import annotations

import datetime as dt
import time
from collections.abc import Mapping
from typing import Any

from edge_vis.jaus.address import JausAddress

CORE = "urn:jaus:jss:core:"
FOREIGN = JausAddress(9, 1, 5)
Reply = tuple[JausAddress, str, dict[str, Any]]
STANDBY, READY, SHUTDOWN = 2, 1, 3


class ContestedRobot:
    """See the module docstring."""

    SERVICES = tuple(CORE + s for s in ("Transport", "Events", "AccessControl", "Management",
                                        "Liveness", "Discovery", "Time"))

    def __init__(self, address: JausAddress, *, foreign_authority: int = 120,
                 default_authority: int = 10, clock_offset: float = 0.0) -> None:
        self.address = address
        self.default_authority = default_authority
        self.controller: JausAddress | None = FOREIGN
        self.authority = foreign_authority
        self.status = STANDBY
        self.clock_offset = clock_offset
        self.received: list[tuple[float, JausAddress, str, dict[str, Any]]] = []
        self.outbox: list[Reply] = []

    def names(self, name: str) -> list[dict[str, Any]]:
        return [f for _t, _s, n, f in self.received if n == name]

    def foreign_release(self) -> None:
        """The other client releases control (nothing to send: it is not on this link)."""
        self.controller, self.authority, self.status = None, self.default_authority, STANDBY

    def clock(self) -> dt.datetime:
        return dt.datetime.fromtimestamp(time.time() + self.clock_offset, tz=dt.UTC)

    def _lose_control(self) -> list[Reply]:
        old, self.controller = self.controller, None
        self.authority = self.default_authority
        if self.status == READY:
            self.status = STANDBY
        return [(old, "RejectControl", {"response_code": 0})] if old not in (None,
                                                                             FOREIGN) else []

    def handle(self, source: JausAddress, name: str, fields: Mapping[str, Any],
               now: float) -> list[Reply]:
        self.received.append((now, source, name, dict(fields)))
        out: list[Reply] = []

        def reply(n: str, f: dict[str, Any] | None = None) -> None:
            out.append((source, n, f or {}))

        controller = source == self.controller
        if name == "QueryIdentification":
            reply("ReportIdentification", {"query_type": int(fields["query_type"]),
                                           "type": 10001, "identification": "Contested"})
        elif name == "QueryConfiguration":
            reply("ReportConfiguration", {"node_list": [{
                "node_rec": {"node_id": self.address.node},
                "component_list": [{"component_id": self.address.component,
                                    "instance_id": 0}]}]})
        elif name == "QueryServices":
            reply("ReportServices", {"node_list": [{
                "node_rec": {"node_id": self.address.node}, "component_list": [{
                    "component_rec": {"component_id": self.address.component,
                                      "instance_id": 0},
                    "service_list": [{"uri": u, "major_version_number": 1,
                                      "minor_version_number": 1} for u in self.SERVICES]}]}]})
        elif name == "QueryHeartbeatPulse":
            reply("ReportHeartbeatPulse")
        elif name == "QueryStatus":
            reply("ReportStatus", {"status": self.status, "reserved": 0})
        elif name == "QueryTimeout":
            reply("ReportTimeout", {"timeout": 0})
        elif name == "QueryControl":
            c = self.controller
            reply("ReportControl", {"subsystem_id": c.subsystem if c else 0,
                                    "node_id": c.node if c else 0,
                                    "component_id": c.component if c else 0,
                                    "authority_code": self.authority if c else 0})
        elif name == "QueryAuthority":
            reply("ReportAuthority", {"authority_code": self.authority})
        elif name == "RequestControl":
            code = int(fields["authority_code"])
            if controller:
                if code < self.default_authority:
                    out += self._lose_control()
                else:
                    self.authority = code
                    reply("ConfirmControl", {"response_code": 0})
            elif self.status == SHUTDOWN:
                reply("ConfirmControl", {"response_code": 1})
            elif (self.controller is None and code >= self.default_authority) or (
                    self.controller is not None and code > self.authority):
                out += self._lose_control()
                self.controller, self.authority = source, code
                reply("ConfirmControl", {"response_code": 0})
            else:
                reply("ConfirmControl", {"response_code": 2})
        elif name == "ReleaseControl" and controller:
            out += self._lose_control()
        elif name == "SetAuthority" and controller:
            code = int(fields["authority_code"])
            if self.default_authority <= code <= self.authority:
                self.authority = code
        elif name == "Resume" and controller and self.status == STANDBY:
            self.status = READY
        elif name == "Standby" and controller and self.status == READY:
            self.status = STANDBY
        elif name in ("Shutdown", "Reset") and controller:
            out += self._lose_control()
            self.status = SHUTDOWN if name == "Shutdown" else STANDBY
        elif name == "QueryTime":
            t = self.clock()
            reply("ReportTime", {
                "time_stamp": {"milliseconds": t.microsecond // 1000, "seconds": t.second,
                               "minutes": t.minute, "hour": t.hour, "day": t.day},
                "date_stamp": {"day": t.day, "month": t.month, "year": t.year - 2000}})
        elif name == "SetTime" and controller:
            s, d = fields["time_stamp"], fields["date_stamp"]
            new = dt.datetime(2000 + d["year"], d["month"], s["day"], s["hour"], s["minutes"],
                              s["seconds"], s["milliseconds"] * 1000, tzinfo=dt.UTC)
            self.clock_offset += (new - self.clock()).total_seconds()
        return out

    def tick(self, now: float) -> list[Reply]:
        out, self.outbox = self.outbox, []
        return out
