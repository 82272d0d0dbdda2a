"""A simulated JAUS vehicle: the component side of the JSS services, sans-I/O.

:class:`SimVehicle` is one JAUS subsystem. The adapter feeds it every decoded message
with :meth:`SimVehicle.receive` and wakes it at :meth:`SimVehicle.next_deadline` with
:meth:`SimVehicle.on_timer`; both take ``now`` (seconds, any monotonic origin) and return
:class:`~edge_vis.tools.sim.outputs.Send` actions. Nothing here reads a clock, touches a socket
or draws from an unseeded random source, so a run is reproducible from its profile.

Theory of operation
-------------------
* Messages are dispatched per destination component (wildcards reach every component)
  and per service: a component ignores messages of services it does not offer, as a real
  one does. Queries are answered by the same report builders the Events service uses.
* Access control follows AS5710A: higher authority pre-empts (the old controller gets
  RejectControl CONTROL_RELEASED), a lower one gets ConfirmControl INSUFFICIENT_AUTHORITY,
  control not renewed within the timeout is released with RejectControl.
* Management: INITIALIZE -> STANDBY after ``init_time``; Resume/Standby only from the
  controller; emergencies from anyone, cleared by the clients that set them (all of
  them), back to the state before. In EMERGENCY, as the JSIDL says: RequestControl is
  answered NOT_AVAILABLE (even to the controller, who keeps control), ReleaseControl with
  RejectControl NOT_AVAILABLE (control kept), control does not time out, SetAuthority,
  Reset, Shutdown, Standby and Resume are ignored, and no command moves the vehicle.
* Management (AS5710A): Shutdown and Reset only from the controller and not in EMERGENCY:
  control ends with RejectControl, then SHUTDOWN for good, or INITIALIZE again.
* Time: ReportTime (time and date, per the query's presence vector) from a clock that is
  ``clock_offset`` seconds off UTC; SetTime only from the controller.
* Commands (SetWrenchEffort, list manager, ExecuteList) are obeyed only from the
  controller and only in READY; otherwise silently ignored and counted.
* The kinematic model advances in fixed steps of :data:`DT` seconds.
* A vehicle with a manipulator gets its arm and pan-tilt components, their messages and
  their dialect from :mod:`edge_vis.tools.sim.arm`.
* Faults from the profile: scheduled drop-outs (silence, optionally a reboot that loses
  control, events, the waypoint list and sequence numbers), refused control, rejected
  events, the JAUS Toolset example's stubs (no events, no QueryTimeout, INITIALIZE
  forever) and malformed frames at a given rate.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import logging
import math
import random
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from edge_vis.catalogue import Catalogue, Message, default_catalogue
from edge_vis.errors import DecodeError, EncodeError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.tools.sim import (
    arm,
    iop_sim,
    local_segments,
    scripted,
    self_report,
    sensing_control,
    spooling,
)
from edge_vis.tools.sim import components as svc
from edge_vis.tools.sim.components import ComponentSpec
from edge_vis.tools.sim.events import EVERY_CHANGE, PERIODIC, EventTable, Subscription
from edge_vis.tools.sim.kinematics import Motion, clamp
from edge_vis.tools.sim.outputs import Action, Restarted, Send
from edge_vis.tools.sim.profile import VehicleSpec
from edge_vis.tools.sim.sensors import Sensors
from edge_vis.tools.sim.waypoints import WaypointList, target_of

log = logging.getLogger(__name__)

#: kinematic model step (s)
DT = 0.1

# Management states (ReportStatus)
INITIALIZE, READY, STANDBY, SHUTDOWN, FAILURE, EMERGENCY = range(6)
STATE_NAMES = ("INITIALIZE", "READY", "STANDBY", "SHUTDOWN", "FAILURE", "EMERGENCY")
NOT_AVAILABLE_STATES = (INITIALIZE, SHUTDOWN, FAILURE, EMERGENCY)

# ConfirmControl / RejectControl codes
CONTROL_ACCEPTED, NOT_AVAILABLE, INSUFFICIENT_AUTHORITY = 0, 1, 2
CONTROL_RELEASED = 0

# RejectEventRequest codes
PERIODIC_UNSUPPORTED, CONNECTION_REFUSED, INVALID_SETUP, MESSAGE_UNSUPPORTED, INVALID_ID = (
    1, 3, 4, 5, 6)

#: malformed-frame defects the adapter knows how to make
CORRUPTIONS = ("truncated", "bad_size", "bad_body", "bad_version")


class Component:
    """Per-component state: services, access control, management, events."""

    def __init__(self, spec: ComponentSpec, address: JausAddress, vehicle: VehicleSpec) -> None:
        self.spec = spec
        self.address = address
        self.services = frozenset(spec.services + spec.answers)
        self.default_authority = vehicle.default_authority
        self.events = EventTable(vehicle.event_timeout) if svc.EVENTS in self.services else None
        self.controller: JausAddress | None = None
        self.authority = vehicle.default_authority
        self.control_renewed = 0.0
        self.state: int | None = INITIALIZE if svc.MANAGEMENT in self.services else None
        self.saved_state = STANDBY
        self.emergency_ids: set[JausAddress] = set()

    def offers(self, service: str) -> bool:
        """Whether the component offers ``service``."""
        return service in self.services

    def reset(self) -> None:
        """Back to power-on state (a reboot)."""
        self.controller = None
        self.authority = self.default_authority
        if self.state is not None:
            self.state = INITIALIZE
        self.emergency_ids.clear()
        if self.events is not None:
            self.events.clear()


class SimVehicle:
    """One simulated JAUS subsystem; see the module docstring."""

    def __init__(self, spec: VehicleSpec, catalogue: Catalogue | None = None, *,
                 start: float = 0.0, wall_offset: float = 0.0) -> None:
        self.spec = spec
        self.catalogue = catalogue if catalogue is not None else default_catalogue()
        self.wall_offset = wall_offset
        self.rng = random.Random(spec.seed)
        self.components: dict[JausAddress, Component] = {}
        self.layout = svc.layout(spec.kind)
        if spec.iop and spec.kind == "ugv":
            self.layout = (*self.layout, iop_sim.COMPONENT)
        if spec.kind == "custom":
            services = spec.services or scripted.services_of(self.catalogue, [
                *([spec.hello.message] if spec.hello else []),
                *(r.message for r in spec.reports)])
            self.layout = (ComponentSpec(spec.component, spec.name, services),)
        #: the manipulator and pan-tilt (:mod:`edge_vis.tools.sim.arm`), if it has them
        self.arm = arm.Arm(spec.manipulator) if spec.manipulator is not None else None
        if spec.manipulator is not None:
            self.layout = (*self.layout, *arm.layout(spec.manipulator))
        #: the message dialects it speaks on the wire
        self.dialects = self.arm.dialects if self.arm is not None else ()
        for cspec in self.layout:
            addr = svc.address(spec.subsystem, spec.node, cspec)
            self.components[addr] = Component(cspec, addr, spec)
        self.motion = Motion(yaw=spec.heading, max_speed=spec.max_speed,
                             max_yaw_rate=spec.max_yaw_rate)
        self.effort: dict[str, float] = {}
        self.waypoints = WaypointList()
        self.spooler = spooling.Spooler()
        self.sensing = sensing_control.SensingState()
        self.counters: Counter[str] = Counter()
        self.reboots = 0
        self._physics_time = start
        self._now = start
        self._init_done_at = start + spec.init_time
        faults = spec.faults
        first = faults.dropout_first if faults.dropout_first is not None else faults.dropout_every
        self._dropout_start = start + first if faults.dropout_every else math.inf
        self._dropout_end = math.inf
        self.down = False
        self._next_malformed = (start + self.rng.expovariate(faults.malformed_rate)
                                if faults.malformed_rate > 0 else math.inf)
        uuv = spec.kind == "uuv"
        self.hello = spec.hello
        if uuv and self.hello is None:
            self.hello = replace(scripted.UUV_HELLO, fields={
                **scripted.UUV_HELLO.fields, "bulk_image_port": spec.bulk_image_port})
        self._next_hello = start if self.hello is not None else math.inf
        self._start = start
        #: report index -> when it is next sent unasked
        self._next_report = {i: start + r.period for i, r in enumerate(spec.reports)
                             if r.period > 0}
        self._answers = {r.query: r for r in spec.reports if r.query}
        self._next_environment = (start + spec.environment_period
                                  if uuv and spec.environment_period > 0 else math.inf)
        self._next_atr = start + spec.atr_period if uuv and spec.atr_period > 0 else math.inf
        self.atr_images: dict[int, bytes] = {}
        self.sensors = Sensors(spec, self.motion, wall_offset)
        self.sensors.t = start
        self.last_client: JausAddress | None = None
        #: the vehicle's clock minus UTC, seconds (SetTime changes it)
        self.clock_offset = spec.clock_offset
        self._unsupported_seen: set[tuple[str, JausAddress]] = set()

    # -- the sans-I/O interface -----------------------------------------------------------

    @property
    def name(self) -> str:
        """The vehicle's name (its ReportIdentification string)."""
        return self.spec.name

    def receive(self, source: JausAddress, destination: JausAddress, message: Message,
                now: float) -> list[Action]:
        """Handle one message addressed to this subsystem; return what to send."""
        out = self._advance(now)
        self._now = now
        if self.down:
            self.counters["ignored_while_down"] += 1
            return out
        self.counters["received"] += 1
        if message.name is None or message.fields is None:
            self.counters["unsupported"] += 1
            log.debug("%s: ignoring unknown message 0x%04X from %s", self.name, message.code,
                      source)
            return out
        self.last_client = source
        handled = False
        for comp in self.components.values():
            if not destination.matches(comp.address):
                continue
            answer = self._answers.get(message.name)
            if answer is not None:
                handled = True
                self.counters["queries_answered"] += 1
                out.append(self._scripted_report(comp, source, answer, now))
                continue
            entry = _HANDLERS.get(message.name)
            if entry is not None and comp.offers(entry[0]):
                handled = True
                out += entry[1](self, comp, source, message.fields, now)
            elif message.name in _QUERIES and comp.offers(_QUERIES[message.name][0]):
                handled = True
                out += self._answer(comp, source, message.name, message.fields)
        if not handled:
            self.counters["unsupported"] += 1
            if (message.name, destination) not in self._unsupported_seen:
                self._unsupported_seen.add((message.name, destination))
                log.info("%s: ignoring %s to %s: no such component or service (reported once)",
                         self.name, message.name, destination)
        out += self._every_change()
        return out

    def on_timer(self, now: float) -> list[Action]:
        """Do whatever is due at ``now``; return what to send."""
        out = self._advance(now)
        if self.down:
            return out
        for comp in self.components.values():
            out += self._control_timeout(comp, now)
            if comp.offers(iop_sim.ENHANCED_ACCESS_CONTROL):
                out += iop_sim.expire(self, comp, now)
            if comp.events is not None:
                for sub in comp.events.expire(now):
                    log.info("%s: event %d (%s) of %s expired", self.name, sub.event_id,
                             sub.query_name, sub.subscriber)
                for sub in comp.events.due(now):
                    out += self._event(comp, sub, force=True)
        if now >= self._next_malformed:
            self._next_malformed = now + self.rng.expovariate(self.spec.faults.malformed_rate)
            out.append(self._malformed())
        if now >= self._next_hello:
            self._next_hello = now + self.spec.hello_period
            out.append(self._hello())
        for i, due in self._next_report.items():
            if now >= due:
                report = self.spec.reports[i]
                self._next_report[i] = now + report.period
                out.append(self._scripted_report(self._first_component(), BROADCAST, report,
                                                 now))
        if now >= self._next_environment:
            self._next_environment = now + self.spec.environment_period
            comp = self._first(svc.OCEAN_ENVIRONMENT)
            if comp is not None:
                fields = self.sensors.ocean_environment({})
                out.append(Send(comp.address, BROADCAST, "ReportOceanEnvironment", fields))
        if now >= self._next_atr:
            self._next_atr = now + self.spec.atr_period
            out += self._atr_notice(now)
        out += self._every_change()
        return out

    def next_deadline(self) -> float | None:
        """When :meth:`on_timer` next has something to do."""
        if self.down:  # silent: only the model and the end of the drop-out matter
            return min(self._physics_time + DT, self._dropout_end)
        times = [self._physics_time + DT, self._dropout_start, self._dropout_end,
                 self._next_malformed, self._next_hello, self._next_environment, self._next_atr,
                 *self._next_report.values()]
        for comp in self.components.values():
            if (comp.controller is not None and self.spec.control_timeout > 0
                    and comp.state != EMERGENCY):
                times.append(comp.control_renewed + self.spec.control_timeout)
            if comp.events is not None:
                deadline = comp.events.next_deadline()
                if deadline is not None:
                    times.append(deadline)
        finite = [t for t in times if t != math.inf]
        return min(finite) if finite else None

    def component(self, component_id: int) -> Component:
        """The component with id ``component_id`` (KeyError if none)."""
        for comp in self.components.values():
            if comp.address.component == component_id:
                return comp
        raise KeyError(component_id)

    # -- time, faults ---------------------------------------------------------------------

    def _advance(self, now: float) -> list[Action]:
        out: list[Action] = []
        while self._physics_time + DT <= now:
            self._physics_time += DT
            self.waypoints.steer(self.motion, self.spec.origin)
            self.spooler.step(self._physics_time)
            self.motion.step(DT)
            if self.arm is not None:
                self.arm.step(DT, *(self._ready(c) for c in (arm.ARM_COMPONENT,
                                                             arm.PAN_TILT_COMPONENT)))
            self.sensors.t = self._physics_time
        if self._init_done_at <= now:
            self._init_done_at = math.inf
            if not self.spec.faults.jts_example:
                for comp in self.components.values():
                    if comp.state == INITIALIZE:
                        comp.state = STANDBY
                        log.info("%s: %s initialised -> STANDBY", self.name, comp.address)
        if not self.down and now >= self._dropout_start:
            self.down = True
            self._dropout_end = self._dropout_start + self.spec.faults.dropout_duration
            self._dropout_start = math.inf
            self.counters["dropouts"] += 1
            log.warning("%s: dropping out for %.1f s", self.name,
                        self.spec.faults.dropout_duration)
        if self.down and now >= self._dropout_end:
            self.down = False
            self._dropout_start = self._dropout_end + (
                self.spec.faults.dropout_every - self.spec.faults.dropout_duration)
            self._dropout_end = math.inf
            if self.spec.faults.dropout_reboot:
                out += self._reboot(now)
            log.warning("%s: back after drop-out%s", self.name,
                        " (rebooted)" if self.spec.faults.dropout_reboot else "")
        return out

    def _ready(self, component_id: int) -> bool:
        comp = self.component(component_id)
        return comp.controller is not None and comp.state == READY

    def _reboot(self, now: float) -> list[Action]:
        self.reboots += 1
        for comp in self.components.values():
            comp.reset()
        self.waypoints.clear()
        self.spooler = spooling.Spooler()
        self.motion.stop()
        self.effort = {}
        self._init_done_at = now + self.spec.init_time
        return [Restarted(self.name)]

    def _malformed(self) -> Send:
        comp = next(iter(self.components.values()))
        kind = self.rng.choice(CORRUPTIONS)
        self.counters["malformed_sent"] += 1
        return Send(comp.address, self.last_client or BROADCAST, "ReportHeartbeatPulse", {},
                    corrupt=kind)

    def _first(self, service: str) -> Component | None:
        return next((c for c in self.components.values() if c.offers(service)), None)

    # -- access control -------------------------------------------------------------------

    def _send(self, comp: Component, dest: JausAddress, name: str,
              fields: dict[str, Any] | None = None) -> list[Action]:
        return [Send(comp.address, dest, name, fields or {})]

    def _lose_control(self, comp: Component, why: str) -> list[Action]:
        """Drop the controller of ``comp`` and tell it with RejectControl."""
        old = comp.controller
        comp.controller = None
        comp.authority = comp.default_authority
        self._leave_ready(comp)
        log.info("%s: %s released control of %s (%s)", self.name, old, comp.address, why)
        if old is None:
            return []
        return self._send(comp, old, "RejectControl", {"response_code": CONTROL_RELEASED})

    def _leave_ready(self, comp: Component) -> None:
        if comp.state == READY:
            comp.state = STANDBY
        if any(comp.offers(s) for s in (svc.PRIMITIVE_DRIVER, svc.WAYPOINT_LIST_DRIVER,
                                        iop_sim.SKID_STEER, iop_sim.ACKERMANN)):
            self._halt()
        if comp.offers(svc.MISSION_SPOOLER):
            self.spooler.lost_control()

    def _halt(self) -> None:
        self.motion.stop()
        self.effort = {}
        self.waypoints.stop()

    def _control_timeout(self, comp: Component, now: float) -> list[Action]:
        timeout = self.spec.control_timeout
        if comp.state == EMERGENCY:  # no time-out in EMERGENCY: a full one after it
            comp.control_renewed = now
            return []
        if comp.controller is None or timeout <= 0 or now - comp.control_renewed < timeout:
            return []
        self.counters["control_timeouts"] += 1
        return self._lose_control(comp, f"not renewed within {timeout} s")

    def _request_control(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                         now: float) -> list[Action]:
        authority = fields["authority_code"]

        def confirm(code: int) -> list[Action]:
            return self._send(comp, source, "ConfirmControl", {"response_code": code})

        if self.spec.faults.refuse_control:
            self.counters["control_refused"] += 1
            return confirm(NOT_AVAILABLE)
        unavailable = comp.state in NOT_AVAILABLE_STATES and not (
            self.spec.faults.jts_example and comp.state == INITIALIZE)
        if comp.state == EMERGENCY:  # the controller, if any, keeps control
            return confirm(NOT_AVAILABLE)
        if comp.controller == source:
            if authority < comp.default_authority:
                return self._lose_control(comp, "authority below the default")
            comp.authority = authority
            comp.control_renewed = now
            return confirm(CONTROL_ACCEPTED)
        if unavailable:
            return confirm(NOT_AVAILABLE)
        if comp.controller is None:
            if authority < comp.default_authority:
                return confirm(INSUFFICIENT_AUTHORITY)
            comp.controller, comp.authority, comp.control_renewed = source, authority, now
            log.info("%s: %s took control of %s (authority %d)", self.name, source,
                     comp.address, authority)
            return confirm(CONTROL_ACCEPTED)
        if authority > comp.authority:
            out = self._lose_control(comp, f"pre-empted by {source} (authority {authority})")
            comp.controller, comp.authority, comp.control_renewed = source, authority, now
            self.counters["preemptions"] += 1
            return out + confirm(CONTROL_ACCEPTED)
        return confirm(INSUFFICIENT_AUTHORITY)

    def _release_control(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                         now: float) -> list[Action]:
        if comp.controller != source:
            return []
        if comp.state == EMERGENCY:
            return self._send(comp, source, "RejectControl", {"response_code": NOT_AVAILABLE})
        return self._lose_control(comp, "ReleaseControl")

    def _set_authority(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                       now: float) -> list[Action]:
        code = fields["authority_code"]
        if (comp.state != EMERGENCY and comp.controller == source
                and comp.default_authority <= code <= comp.authority):
            comp.authority = code
        return []

    def _set_time(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                  now: float) -> list[Action]:
        if comp.controller != source:  # the Time service's Controlled state only
            self.counters["commands_ignored"] += 1
            log.info("%s: ignoring SetTime from %s (controller %s)", self.name, source,
                     comp.controller)
            return []
        current = self.clock(now)
        stamp, date = fields.get("time_stamp"), fields.get("date_stamp")
        if stamp is None:
            return []
        year, month = (2000 + date["year"], date["month"]) if date else (current.year,
                                                                         current.month)
        try:
            new = dt.datetime(year, month, stamp["day"], stamp["hour"], stamp["minutes"],
                              stamp["seconds"], stamp["milliseconds"] * 1000,
                              tzinfo=dt.UTC)
        except ValueError:
            self.counters["bad_set_time"] += 1
            return []
        self.clock_offset += (new - current).total_seconds()
        self.counters["set_time"] += 1
        log.info("%s: clock set by %s to %s", self.name, source, new.isoformat())
        return []

    def clock(self, now: float) -> dt.datetime:
        """The vehicle's clock (UTC, but ``clock_offset`` off) at ``now``."""
        return dt.datetime.fromtimestamp(now + self.wall_offset + self.clock_offset,
                                         tz=dt.UTC)

    def _report_time(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        t = self.clock(self._now)
        return {"time_stamp": {"milliseconds": t.microsecond // 1000, "seconds": t.second,
                               "minutes": t.minute, "hour": t.hour, "day": t.day},
                "date_stamp": {"day": t.day, "month": t.month,
                               "year": min(max(t.year - 2000, 0), 127)}}

    def _query_timeout(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                       now: float) -> list[Action]:
        if self.spec.faults.jts_example:
            return []
        return self._send(comp, source, "ReportTimeout", {"timeout": self.spec.control_timeout})

    def _commanding(self, comp: Component, source: JausAddress, what: str) -> bool:
        """Whether ``source`` may command ``comp`` now (controller, READY)."""
        ok = comp.controller == source and (
            comp.state in (READY, None)
            or (self.spec.faults.jts_example and comp.state == INITIALIZE))
        if not ok:
            self.counters["commands_ignored"] += 1
            state = STATE_NAMES[comp.state] if comp.state is not None else "-"
            log.info("%s: ignoring %s from %s (controller %s, state %s)", self.name, what,
                     source, comp.controller, state)
        return ok

    # -- management -----------------------------------------------------------------------

    def _management(self, comp: Component, source: JausAddress, name: str) -> list[Action]:
        if comp.controller != source:
            self.counters["commands_ignored"] += 1
            return []
        if name == "Resume" and comp.state == STANDBY:
            comp.state = READY
            self.counters["obeyed_resume"] += 1
        elif name == "Standby" and comp.state == READY:
            comp.state = STANDBY
            self.counters["obeyed_standby"] += 1
            self._halt()
        elif name in ("Reset", "Shutdown") and comp.state in (READY, STANDBY):
            self.counters[f"obeyed_{name.lower()}"] += 1
            out = self._lose_control(comp, name)
            comp.state = INITIALIZE if name == "Reset" else SHUTDOWN
            if name == "Reset":
                self._init_done_at = self._physics_time + self.spec.init_time
            return out
        return []

    def _set_emergency(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                       now: float) -> list[Action]:
        comp.emergency_ids.add(source)
        if comp.state != EMERGENCY:
            comp.saved_state = comp.state if comp.state is not None else STANDBY
            comp.state = EMERGENCY
            self._halt()
            log.warning("%s: EMERGENCY set by %s", self.name, source)
        return []

    def _clear_emergency(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                         now: float) -> list[Action]:
        if source not in comp.emergency_ids:  # only a client that set one may clear
            self.counters["emergency_clears_ignored"] += 1
            return []
        comp.emergency_ids.discard(source)
        if comp.state == EMERGENCY and not comp.emergency_ids:
            comp.state = comp.saved_state
            comp.control_renewed = now
            log.warning("%s: emergency cleared by %s", self.name, source)
        return []

    # -- events ---------------------------------------------------------------------------

    def _reject_event(self, comp: Component, source: JausAddress, request_id: int,
                      code: int, what: str = "") -> list[Action]:
        self.counters["events_rejected"] += 1
        log.info("%s: rejecting event request %d of %s on %s%s (code %d)", self.name,
                 request_id, source, comp.address, f" for {what}" if what else "", code)
        return self._send(comp, source, "RejectEventRequest",
                          {"request_id": request_id, "response_code": code})

    def _decode_query(self, payload: bytes) -> Message | None:
        try:
            query = self.catalogue.decode(payload, self.dialects)
        except DecodeError:
            return None
        return query if query.name is not None else None

    def _create_event(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Action]:
        if self.spec.faults.jts_example:
            return []  # the JAUS Toolset example's stub handler: no answer at all
        assert comp.events is not None
        request_id = fields["request_id"]
        query = self._decode_query(fields["query_message"])
        if query is None:
            return self._reject_event(comp, source, request_id, INVALID_SETUP)
        entry = _QUERIES.get(query.name or "")
        if entry is None or not comp.offers(entry[0]):
            return self._reject_event(comp, source, request_id, MESSAGE_UNSUPPORTED, query.name)
        if self.spec.faults.rejects_event(query.name or ""):
            return self._reject_event(comp, source, request_id, CONNECTION_REFUSED, query.name)
        event_type = fields["event_type"]
        rate = fields["requested_periodic_rate"]
        if event_type == PERIODIC:
            if rate <= 0:
                return self._reject_event(comp, source, request_id, INVALID_SETUP)
            rate = min(rate, self.spec.max_event_rate)
        elif event_type == EVERY_CHANGE:
            rate = 0.0
        else:
            return self._reject_event(comp, source, request_id, INVALID_SETUP)
        sub = comp.events.create(source, event_type, rate, query.name or "",
                                 query.fields or {}, fields["query_message"], now)
        if sub is None:
            return self._reject_event(comp, source, request_id, CONNECTION_REFUSED)
        log.info("%s: event %d on %s for %s: %s at %s", self.name, sub.event_id, comp.address,
                 source, query.name, f"{rate:g} Hz" if event_type == PERIODIC else "change")
        self.counters["events_created"] += 1
        return self._send(comp, source, "ConfirmEventRequest", {
            "request_id": request_id, "event_id": sub.event_id,
            "confirmed_periodic_rate": rate})

    def _update_event(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Action]:
        if self.spec.faults.jts_example:
            return []
        assert comp.events is not None
        request_id = fields["request_id"]
        sub = comp.events.get(fields["event_id"])
        if sub is None or sub.subscriber != source:
            return self._reject_event(comp, source, request_id, INVALID_ID)
        query = self._decode_query(fields["query_message"])
        if query is None or query.code != self.catalogue.by_name(sub.query_name).code:
            return self._reject_event(comp, source, request_id, INVALID_SETUP)
        rate = fields["requested_periodic_rate"]
        if sub.event_type == PERIODIC:
            if rate <= 0:
                return self._reject_event(comp, source, request_id, INVALID_SETUP)
            rate = min(rate, self.spec.max_event_rate)
        else:
            rate = 0.0
        comp.events.update(sub, rate, query.fields or {}, fields["query_message"], now)
        return self._send(comp, source, "ConfirmEventRequest", {
            "request_id": request_id, "event_id": sub.event_id,
            "confirmed_periodic_rate": rate})

    def _cancel_event(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Action]:
        if self.spec.faults.jts_example:
            return []
        assert comp.events is not None
        request_id, event_id = fields["request_id"], fields["event_id"]
        sub = comp.events.get(event_id)
        if sub is None or sub.subscriber != source:
            return self._reject_event(comp, source, request_id, INVALID_ID)
        comp.events.cancel(event_id)
        log.info("%s: event %d (%s) cancelled by %s", self.name, event_id, sub.query_name,
                 source)
        return self._send(comp, source, "ConfirmEventRequest", {
            "request_id": request_id, "event_id": event_id, "confirmed_periodic_rate": 0.0})

    def _query_events(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Action]:
        assert comp.events is not None
        (kind, value), = fields["query_events_var"].items()
        subs = list(comp.events)
        if kind == "message_id_rec":
            subs = [s for s in subs
                    if int.from_bytes(s.query_payload[:2], "little") == value["message_code"]]
        elif kind == "event_type_rec":
            subs = [s for s in subs if s.event_type == value["event_type"]]
        elif kind == "event_id_rec":
            subs = [s for s in subs if s.event_id == value["event_id"]]
        return self._send(comp, source, "ReportEvents", {"event_list": [
            {"event_type": s.event_type, "event_id": s.event_id,
             "query_message": s.query_payload} for s in subs]})

    def _query_event_timeout(self, comp: Component, source: JausAddress,
                             fields: dict[str, Any], now: float) -> list[Action]:
        if self.spec.faults.jts_example:
            return []
        return self._send(comp, source, "ReportEventTimeout",
                          {"timeout": self.spec.event_timeout})

    def _event(self, comp: Component, sub: Subscription, *, force: bool) -> list[Action]:
        """An Event for ``sub`` (only when the report changed, unless ``force``)."""
        report = self._report(comp, sub.query_name, sub.query_fields)
        if report is None:
            return []
        name, fields = report
        if not force:
            key = {k: v for k, v in fields.items() if k != "time_stamp"}
            if key == sub.last_report:
                return []
            sub.last_report = key
        try:
            payload = self.catalogue.encode(self._code(name), fields, self.dialects)
        except EncodeError as exc:
            log.error("%s: cannot encode %s for event %d: %s", self.name, name, sub.event_id, exc)
            return []
        self.counters["events_sent"] += 1
        return [Send(comp.address, sub.subscriber, "Event", {
            "event_id": sub.event_id, "sequence_number": sub.next_sequence(),
            "report_message": payload})]

    def _every_change(self) -> list[Action]:
        out: list[Action] = []
        for comp in self.components.values():
            if comp.events is not None:
                for sub in comp.events.changes():
                    out += self._event(comp, sub, force=False)
        return out

    # -- queries and reports --------------------------------------------------------------

    def _code(self, report_name: str) -> int:
        return self.catalogue.by_name(report_name).code

    def _answer(self, comp: Component, source: JausAddress, query_name: str,
                fields: dict[str, Any]) -> list[Action]:
        if query_name in ("QueryTimeout", "QueryEventTimeout") and self.spec.faults.jts_example:
            return []
        report = self._report(comp, query_name, fields)
        if report is None:
            return []
        return [Send(comp.address, source, report[0], report[1])]

    def _report(self, comp: Component, query_name: str,
                fields: dict[str, Any]) -> tuple[str, dict[str, Any]] | None:
        entry = _QUERIES.get(query_name)
        if entry is None or not comp.offers(entry[0]):
            return None
        _service, report_name, builder = entry
        body = builder(self, comp, fields)
        if body is None:
            return None
        if "presence_vector" in fields and report_name in _PV_FILTERED:
            body = self._filter(report_name, body, fields["presence_vector"])
        return report_name, body

    def _filter(self, report_name: str, body: dict[str, Any], pv: int) -> dict[str, Any]:
        """Keep the optional fields whose presence-vector bit the query set."""
        defn = self.catalogue.get(self._code(report_name))
        if defn is None:
            return body
        optional = [f.name for f in defn.body.fields if f.optional]
        keep = {name for bit, name in enumerate(optional) if pv >> bit & 1}
        return {k: v for k, v in body.items() if k not in optional or k in keep}

    def _report_control(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        c = comp.controller
        return {"subsystem_id": c.subsystem if c else 0, "node_id": c.node if c else 0,
                "component_id": c.component if c else 0,
                "authority_code": comp.authority if c else 0}

    def _report_status(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {"status": comp.state if comp.state is not None else STANDBY, "reserved": 0}

    def _report_wrench_effort(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return dict(self.effort)

    def _report_element(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any] | None:
        elem = self.waypoints.elements.get(fields["element_uid"])
        if elem is None:
            return None
        return {"element_uid": elem.uid, "previous_uid": elem.previous, "next_uid": elem.next,
                "element_data": elem.data}

    def _report_element_list(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {"element_list": [{"element_uid": uid} for uid in self.waypoints.order()]}

    def _report_element_count(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {"element_count": len(self.waypoints.elements)}

    def _report_active_element(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {"element_uid": self.waypoints.active}

    def _report_path_segment(self, comp: Component,
                             fields: dict[str, Any]) -> dict[str, Any] | None:
        elem = self.waypoints.elements.get(self.waypoints.active)
        segment = elem.waypoint.get("segment") if elem is not None else None
        return dict(segment) if segment is not None else None

    def _report_travel_speed(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {"speed": clamp(self.waypoints.travel_speed, 0, 327.67)}

    def _report_heartbeat(self, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return {}

    # -- commands -------------------------------------------------------------------------

    def _set_wrench_effort(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                           now: float) -> list[Action]:
        if not self._commanding(comp, source, "SetWrenchEffort"):
            return []
        self.effort = dict(fields)
        self.waypoints.stop()
        linear = fields.get("propulsive_linear_effort_x", 0.0)
        rotational = fields.get("propulsive_rotational_effort_z", 0.0)
        self.motion.command(self.spec.max_speed * linear / 100.0,
                            self.spec.max_yaw_rate * rotational / 100.0)
        self.counters["commands_obeyed"] += 1
        return []

    def _set_element(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                     now: float) -> list[Action]:
        if not self._commanding(comp, source, "SetElement"):
            return []
        request_id = fields["request_id_rec"]["request_id"]
        records = fields["element_list"]
        waypoints = []
        for rec in records:
            data = rec["element_data"]
            waypoint = None
            if data.get("format") == 0:
                inner = self._decode_query(data["data"])
                if inner is not None and inner.fields is not None:
                    waypoint = target_of(inner.code, inner.fields) or \
                        local_segments.target_of(inner.code, inner.fields, self.spec.origin)
            waypoints.append(waypoint)
        code = self.waypoints.set_elements(records, waypoints)
        if code:
            return self._send(comp, source, "RejectElementRequest",
                              {"request_id": request_id, "response_code": code})
        self.counters["commands_obeyed"] += 1
        return self._send(comp, source, "ConfirmElementRequest", {"request_id": request_id})

    def _delete_element(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                        now: float) -> list[Action]:
        if not self._commanding(comp, source, "DeleteElement"):
            return []
        request_id = fields["request_id_rec"]["request_id"]
        code = self.waypoints.delete([r["element_uid"] for r in fields["delete_element_list"]])
        if code:
            return self._send(comp, source, "RejectElementRequest",
                              {"request_id": request_id, "response_code": code})
        return self._send(comp, source, "ConfirmElementRequest", {"request_id": request_id})

    def _execute_list(self, comp: Component, source: JausAddress, fields: dict[str, Any],
                      now: float) -> list[Action]:
        if not self._commanding(comp, source, "ExecuteList"):
            return []
        if self.waypoints.execute(fields["speed"], fields.get("element_uid")):
            self.effort = {}
            self.counters["commands_obeyed"] += 1
            log.info("%s: executing waypoint list from %d at %.1f m/s", self.name,
                     self.waypoints.active, fields["speed"])
        return []

    # -- UUV vendor messages --------------------------------------------------------------

    def _first_component(self) -> Component:
        return next(iter(self.components.values()))

    def _hello(self) -> Send:
        """The hello of the profile (custom) or the UUV's VendorHello, from the JSIDL."""
        assert self.hello is not None
        comp = self._first(svc.VENDOR_DISCOVERY) or self._first_component()
        services = [(uri, svc.version_of(uri, comp.spec.version)) for uri in comp.spec.services]
        return Send(comp.address, BROADCAST, self.hello.message, scripted.hello_fields(
            self.catalogue, self.hello, self.name, comp.address, services))

    def _scripted_report(self, comp: Component, to: JausAddress,
                         report: scripted.ReportSpec, now: float) -> Send:
        """A report of the profile, its numbers drifted to now."""
        self.counters["reports_sent"] += 1
        fields = scripted.report_fields(self.catalogue, report, now - self._start)
        return Send(comp.address, to, report.message, fields)

    def atr_image(self, image_id: int) -> bytes:
        """The bytes of ATR image ``image_id`` (the same every time it is asked for)."""
        data = self.atr_images.get(image_id)
        return data if data is not None else self.sensors.atr_image(image_id)

    def still_image(self) -> bytes:
        """The current camera frame."""
        return self.sensors.still_image()

    def _atr_notice(self, now: float) -> list[Action]:
        comp = self._first(svc.ATR_NOTIFIER)
        if comp is None:
            return []
        image_id = len(self.atr_images) + 1 + 1000 * self.reboots
        data = self.atr_image(image_id)
        self.atr_images[image_id] = data
        while len(self.atr_images) > 8:
            del self.atr_images[next(iter(self.atr_images))]
        lat, lon = self.spec.origin.to_geodetic(self.motion.x + self.rng.uniform(-20, 20),
                                                self.motion.y + self.rng.uniform(-20, 20))
        self.counters["atr_notices"] += 1
        return [Send(comp.address, BROADCAST, "ReportAtrImageAvailable", {
            "image_id": image_id, "size_bytes": len(data), "format": 1,
            "sha256": hashlib.sha256(data).digest(),
            "capture_time": int((now + self.wall_offset) * 1000),
            "target_class": self.rng.choice(("mine-like", "tyre", "rock", "unknown")),
            "confidence": round(self.rng.uniform(0.3, 0.99), 3),
            "latitude": lat, "longitude": lon})]


Handler = Callable[[SimVehicle, Component, JausAddress, dict[str, Any], float], list[Action]]
Builder = Callable[[SimVehicle, Component, dict[str, Any]], "dict[str, Any] | None"]


def _sensor(report: Callable[[Sensors, dict[str, Any]], dict[str, Any]]) -> Builder:
    """A report builder that asks the vehicle's sensors."""
    def build(vehicle: SimVehicle, comp: Component, fields: dict[str, Any]) -> dict[str, Any]:
        return report(vehicle.sensors, fields)
    return build


def _management_handler(name: str) -> Handler:
    def handle(vehicle: SimVehicle, comp: Component, source: JausAddress,
               fields: dict[str, Any], now: float) -> list[Action]:
        return vehicle._management(comp, source, name)
    return handle


def _spooler_order(method: str, timed: bool = False) -> Handler:
    """A Mission Spooler order: only from the controller in READY (see ``spooling``)."""
    def handle(vehicle: SimVehicle, comp: Component, source: JausAddress,
               fields: dict[str, Any], now: float) -> list[Action]:
        if vehicle._commanding(comp, source, method):
            order = getattr(vehicle.spooler, method)
            done = order(fields, now) if timed else order(fields)
            vehicle.counters["commands_obeyed" if done else "spooler_orders_ignored"] += 1
        return []
    return handle


_HANDLERS: dict[str, tuple[str, Handler]] = {
    "RequestControl": (svc.ACCESS_CONTROL, SimVehicle._request_control),
    "ReleaseControl": (svc.ACCESS_CONTROL, SimVehicle._release_control),
    "SetAuthority": (svc.ACCESS_CONTROL, SimVehicle._set_authority),
    "QueryTimeout": (svc.ACCESS_CONTROL, SimVehicle._query_timeout),
    "SetTime": (svc.TIME, SimVehicle._set_time),
    "Standby": (svc.MANAGEMENT, _management_handler("Standby")),
    "Resume": (svc.MANAGEMENT, _management_handler("Resume")),
    "Reset": (svc.MANAGEMENT, _management_handler("Reset")),
    "Shutdown": (svc.MANAGEMENT, _management_handler("Shutdown")),
    "SetEmergency": (svc.MANAGEMENT, SimVehicle._set_emergency),
    "ClearEmergency": (svc.MANAGEMENT, SimVehicle._clear_emergency),
    "CreateEvent": (svc.EVENTS, SimVehicle._create_event),
    "UpdateEvent": (svc.EVENTS, SimVehicle._update_event),
    "CancelEvent": (svc.EVENTS, SimVehicle._cancel_event),
    "QueryEvents": (svc.EVENTS, SimVehicle._query_events),
    "QueryEventTimeout": (svc.EVENTS, SimVehicle._query_event_timeout),
    "SetWrenchEffort": (svc.PRIMITIVE_DRIVER, SimVehicle._set_wrench_effort),
    "SetElement": (svc.LIST_MANAGER, SimVehicle._set_element),
    "DeleteElement": (svc.LIST_MANAGER, SimVehicle._delete_element),
    "ExecuteList": (svc.WAYPOINT_LIST_DRIVER, SimVehicle._execute_list),
    "SpoolMission": (svc.MISSION_SPOOLER, _spooler_order("spool")),
    "RunMission": (svc.MISSION_SPOOLER, _spooler_order("run", timed=True)),
    "PauseMission": (svc.MISSION_SPOOLER, _spooler_order("pause")),
    "ResumeMission": (svc.MISSION_SPOOLER, _spooler_order("resume", timed=True)),
    "AbortMission": (svc.MISSION_SPOOLER, _spooler_order("abort")),
    "InsertMessages": (svc.MISSION_SPOOLER, _spooler_order("insert_messages")),
    "RemoveMessages": (svc.MISSION_SPOOLER, _spooler_order("remove_messages")),
    "InsertMissionTask": (svc.MISSION_SPOOLER, _spooler_order("insert_task")),
    "RemoveMissionTask": (svc.MISSION_SPOOLER, _spooler_order("remove_tasks")),
}

#: query name -> (service, report name, report builder)
_QUERIES: dict[str, tuple[str, str, Builder]] = {
    "QueryIdentification": (svc.DISCOVERY, "ReportIdentification",
                            lambda v, c, f: self_report.identification(v.spec, c.spec, f)),
    "QueryConfiguration": (svc.DISCOVERY, "ReportConfiguration",
                           lambda v, c, f: self_report.configuration(v.spec, v.layout)),
    "QueryServices": (svc.DISCOVERY, "ReportServices",
                      lambda v, c, f: self_report.services(v.spec, v.layout, f)),
    "QueryServiceList": (svc.DISCOVERY, "ReportServiceList",
                         lambda v, c, f: self_report.service_list(v.spec, v.layout, f)),
    "QueryControl": (svc.ACCESS_CONTROL, "ReportControl", SimVehicle._report_control),
    "QueryAuthority": (svc.ACCESS_CONTROL, "ReportAuthority",
                       lambda v, c, f: {"authority_code": c.authority}),
    "QueryStatus": (svc.MANAGEMENT, "ReportStatus", SimVehicle._report_status),
    "QueryTime": (svc.TIME, "ReportTime", SimVehicle._report_time),
    "QueryHeartbeatPulse": (svc.LIVENESS, "ReportHeartbeatPulse", SimVehicle._report_heartbeat),
    "QueryGlobalPose": (svc.GLOBAL_POSE, "ReportGlobalPose", _sensor(Sensors.global_pose)),
    "QueryLocalPose": (svc.LOCAL_POSE, "ReportLocalPose", _sensor(Sensors.local_pose)),
    "QueryVelocityState": (svc.VELOCITY_STATE, "ReportVelocityState",
                           _sensor(Sensors.velocity_state)),
    "QueryWrenchEffort": (svc.PRIMITIVE_DRIVER, "ReportWrenchEffort",
                          SimVehicle._report_wrench_effort),
    "QueryElement": (svc.LIST_MANAGER, "ReportElement", SimVehicle._report_element),
    "QueryElementList": (svc.LIST_MANAGER, "ReportElementList",
                         SimVehicle._report_element_list),
    "QueryElementCount": (svc.LIST_MANAGER, "ReportElementCount",
                          SimVehicle._report_element_count),
    "QueryActiveElement": (svc.WAYPOINT_LIST_DRIVER, "ReportActiveElement",
                           SimVehicle._report_active_element),
    "QueryTravelSpeed": (svc.WAYPOINT_LIST_DRIVER, "ReportTravelSpeed",
                         SimVehicle._report_travel_speed),
    "QueryLocalPathSegment": (svc.LOCAL_PATH_SEGMENT_DRIVER, "ReportLocalPathSegment",
                              local_segments.report),
    "QueryGlobalPathSegment": (svc.PATH_SEGMENT_DRIVER, "ReportGlobalPathSegment",
                               SimVehicle._report_path_segment),
    "QueryMissionStatus": (svc.MISSION_SPOOLER, "ReportMissionStatus",
                           lambda v, c, f: v.spooler.report_status()),
    "QueryStoredMissions": (svc.MISSION_SPOOLER, "ReportStoredMissions",
                            lambda v, c, f: v.spooler.report_stored()),
    "QueryMissionPlan": (svc.MISSION_SPOOLER, "ReportMissionPlan",
                         lambda v, c, f: v.spooler.report_plan(f)),
    "QuerySpoolingPreferences": (svc.MISSION_SPOOLER, "ReportSpoolingPreferences",
                                 lambda v, c, f: {"data": {"ushort": 1}}),
    "QueryRangeSensorData": (svc.RANGE_SENSOR, "ReportRangeSensorData",
                             _sensor(Sensors.range_sensor_data)),
    "QueryStillImageData": (svc.STILL_IMAGE, "ReportStillImageData",
                            _sensor(Sensors.still_image_data)),
    "QueryRangeSensorCapabilities": (svc.RANGE_SENSOR, "ReportRangeSensorCapabilities",
                                     _sensor(Sensors.range_sensor_capabilities)),
    "QueryRangeSensorConfiguration": (svc.RANGE_SENSOR, "ReportRangeSensorConfiguration",
                                      _sensor(Sensors.range_sensor_configuration)),
    "QueryVisualSensorCapabilities": (svc.VISUAL_SENSOR, "ReportVisualSensorCapabilities",
                                      _sensor(Sensors.visual_sensor_capabilities)),
    "QueryVisualSensorConfiguration": (svc.VISUAL_SENSOR, "ReportVisualSensorConfiguration",
                                       _sensor(Sensors.visual_sensor_configuration)),
    "QueryStillImageSensorCapabilities": (svc.STILL_IMAGE,
                                          "ReportStillImageSensorCapabilities",
                                          _sensor(Sensors.still_image_capabilities)),
    "QueryStillImageSensorConfiguration": (svc.STILL_IMAGE,
                                           "ReportStillImageSensorConfiguration",
                                           _sensor(Sensors.still_image_configuration)),
    "QueryOceanEnvironment": (svc.OCEAN_ENVIRONMENT, "ReportOceanEnvironment",
                              _sensor(Sensors.ocean_environment)),
}

_HANDLERS.update(sensing_control.HANDLERS)
_QUERIES.update(sensing_control.QUERIES)
# the IOP and UGV services of a vehicle with ``iop = true`` (:mod:`edge_vis.tools.sim.iop_sim`)
_HANDLERS.update(iop_sim.HANDLERS)
_QUERIES.update(iop_sim.QUERIES)

#: reports whose optional fields follow the query's presence vector
_PV_FILTERED = frozenset({"ReportGlobalPose", "ReportLocalPose", "ReportVelocityState",
                          "ReportWrenchEffort", "ReportOceanEnvironment", "ReportTime"})


_HANDLERS.update(arm.HANDLERS)
_QUERIES.update(arm.QUERIES)
