"""Emergency stop of a vehicle, set and cleared through the relay. No I/O.

Theory of operation
-------------------
The Management service (AS5710) accepts SetEmergency from any client, controlling or not,
stores the sender's address, and leaves EMERGENCY only when every client that set one
sent ClearEmergency. So the relay sets the emergency under its own JAUS id on behalf of
an operator, and the profile's ``[emergency]`` rules (:class:`~edge_vis.config.
EmergencyProfile`) decide which operators may ask it to set and to clear.

* **SET** sends SetEmergency to every component offering Management (or IOP
  PlatformState, which takes the same messages) at once, in the ``emergency`` traffic
  class: ahead of every queue on the link, never paced, throttled, expired or dropped
  (:mod:`edge_vis.routing.router`). It is sent again every ``retry_period`` (with a
  QueryStatus) until that component reports EMERGENCY, at most ``max_attempts`` times.
* While set, the vehicle is *in emergency* (:meth:`Vehicle.in_emergency`): motion
  commands are refused and queued ones dropped (:mod:`edge_vis.engine.commands`).
* A vehicle that is offline, or not discovered yet, keeps the request; it goes out as
  soon as the vehicle is found (again). A vehicle found again after a loss may have
  rebooted out of EMERGENCY, so every component is asked again.
* **CLEAR** sends ClearEmergency the same way until each component reports a state other
  than EMERGENCY; only then is the relay's latch released. Controlled components are
  brought back to READY with Resume (:mod:`edge_vis.engine.control`) and motion flows
  again only once they are READY.
* Refusals (an operator not allowed to set or clear) are counted and reported as the
  vehicle's ``last_rejection`` in ``ControlStatus``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from edge_vis.engine.control import EMERGENCY
from edge_vis.engine.discovery import MANAGEMENT
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import EMERGENCY_CLASS, PRIORITY_SAFETY, EmergencyRequest, SendMessage

if TYPE_CHECKING:  # the vehicle holds an Estop: these import this module
    from edge_vis.engine.state import Changed, EngineState
    from edge_vis.engine.vehicle import Vehicle

log = logging.getLogger(__name__)

PLATFORM_STATE = "urn:jaus:jss:iop:PlatformState"
#: SetEmergency/ClearEmergency emergency_code: the only one defined
STOP = 1
#: requests kept for vehicles not discovered yet
MAX_PENDING = 64


@dataclass(slots=True)
class Target:
    """One component the emergency is delivered to."""

    attempts: int = 0
    next_at: float | None = 0.0
    confirmed: bool = False


@dataclass(slots=True)
class Estop:
    """An emergency stop set through the relay, until every component confirmed CLEAR."""

    #: the operator who set it (for the ``setter`` clearing rule), its authority and why
    operator_id: str
    authority: int
    reason: str
    since: float
    clearing: bool = False
    targets: dict[JausAddress, Target] = field(default_factory=dict)

    def next_deadline(self) -> float | None:
        """When a (re)transmission is due."""
        times = [t.next_at for t in self.targets.values()
                 if not t.confirmed and t.next_at is not None]
        return min(times) if times else None


def targets_of(vehicle: Vehicle) -> list[JausAddress]:
    """Components of ``vehicle`` that take SetEmergency/ClearEmergency."""
    return sorted({*vehicle.providers(MANAGEMENT), *vehicle.providers(PLATFORM_STATE)})


class EmergencyStops:
    """Sets, delivers and clears emergency stops (see the module docstring)."""

    def __init__(self, state: EngineState, changed: Changed) -> None:
        self._state = state
        self._changed = changed
        #: vehicle id -> a SET for a vehicle not discovered yet
        self.pending: dict[str, EmergencyRequest] = {}

    # -- operators' requests ---------------------------------------------------------------
    def request(self, req: EmergencyRequest, now: float) -> None:
        """An operator's SET or CLEAR (from a translator)."""
        state = self._state
        action = req.action.lower()
        vehicle = state.by_id.get(req.vehicle_id)
        if action not in ("set", "clear"):
            state.counters["emergency_requests_invalid"] += 1
            if vehicle is not None:
                self._refuse(vehicle, f"emergency action {req.action!r} from "
                                      f"{req.operator_id} is neither SET nor CLEAR", now)
            return
        refusal = self._refusal(vehicle, req, action)
        if refusal:
            state.counters["emergency_requests_refused"] += 1
            log.warning("vehicle %s: %s", req.vehicle_id, refusal)
            if vehicle is not None:
                self._refuse(vehicle, refusal, now)
            return
        if vehicle is None:
            if action == "set":
                if len(self.pending) < MAX_PENDING or req.vehicle_id in self.pending:
                    self.pending[req.vehicle_id] = req
                    log.warning("emergency stop for %s kept until it is discovered",
                                req.vehicle_id)
                else:
                    state.counters["emergency_requests_dropped"] += 1
            else:
                self.pending.pop(req.vehicle_id, None)
            return
        if action == "set":
            reason = req.reason or f"set by {req.operator_id}"
            self.set(vehicle, req.operator_id, req.authority, reason, now)
        else:
            self.clear(vehicle, req.operator_id, now)

    def _refusal(self, vehicle: Vehicle | None, req: EmergencyRequest, action: str) -> str:
        """Why the profile's rules refuse ``req``; "" when they allow it."""
        rules = self._state.profile.emergency
        operators = self._state.profile.operators
        what = f"emergency {action.upper()} from {req.operator_id or '(no operator id)'}"
        if action == "set":
            if rules.set_by == "anyone":
                return ""
            refusal = operators.refusal(req.operator_id, req.authority)
            return f"{what} refused: {refusal}" if refusal else ""
        estop = vehicle.estop if vehicle is not None else None
        if vehicle is not None and estop is None:
            if EMERGENCY in vehicle.statuses.values():
                return (f"{what} refused: the vehicle's emergency was not set through this "
                        f"relay; only the client that set it can clear it")
            return f"{what} refused: no emergency stop is set"
        refusal = operators.refusal(req.operator_id, req.authority)
        if refusal:
            return f"{what} refused: {refusal}"
        if estop is None or req.operator_id == estop.operator_id:
            return ""
        if rules.clear_by == "setter":
            return f"{what} refused: only {estop.operator_id}, who set it, may clear it"
        if rules.clear_by == "authority" and req.authority < estop.authority:
            return (f"{what} refused: authority {req.authority} below the setter's "
                    f"({estop.operator_id}, {estop.authority})")
        return ""

    def _refuse(self, vehicle: Vehicle, reason: str, now: float) -> None:
        vehicle.arbitration.reject(reason)
        self._changed(vehicle, "control", now)

    # -- the mechanics ---------------------------------------------------------------------
    def set(self, vehicle: Vehicle, operator_id: str, authority: int, reason: str,
            now: float) -> None:
        """Set (or set again) the emergency of ``vehicle`` and send it at once."""
        state = self._state
        estop = vehicle.estop
        if estop is None or estop.clearing:
            estop = vehicle.estop = Estop(operator_id, authority, reason, now)
            log.warning("vehicle %s: EMERGENCY STOP %s", vehicle.vehicle_id, reason)
        else:  # already set: deliver again to whoever did not confirm; keep the setter
            estop.authority = max(estop.authority, authority)
        state.counters["emergency_set"] += 1
        if dropped := vehicle.drop_motion():
            state.counters["commands_dropped"] += dropped
        self._retarget(vehicle, now, reset=True)
        state.touch(vehicle)
        self.pump(vehicle, now)
        self._changed(vehicle, "emergency", now)

    def clear(self, vehicle: Vehicle, operator_id: str, now: float) -> None:
        """Clear the emergency set through the relay (rules already checked)."""
        estop = vehicle.estop
        if estop is None:
            return
        log.warning("vehicle %s: emergency stop cleared by %s", vehicle.vehicle_id,
                    operator_id)
        self._state.counters["emergency_cleared"] += 1
        estop.clearing = True
        estop.reason = f"clearing (by {operator_id})"
        self._retarget(vehicle, now, reset=True)
        if not estop.targets:
            vehicle.estop = None
        self._state.touch(vehicle)
        self.pump(vehicle, now)
        self._changed(vehicle, "emergency", now)

    def _retarget(self, vehicle: Vehicle, now: float, *, reset: bool) -> None:
        """Deliver to every current target; ``reset`` starts counting attempts anew."""
        estop = vehicle.estop
        if estop is None:
            return
        for address in targets_of(vehicle):
            target = estop.targets.get(address)
            if target is None:
                estop.targets[address] = Target(next_at=now)
            elif reset:
                target.attempts, target.next_at, target.confirmed = 0, now, False

    def pump(self, vehicle: Vehicle, now: float) -> None:
        """Send what is due to the components that have not confirmed."""
        estop = vehicle.estop
        if estop is None or not vehicle.online:
            return
        state = self._state
        name = "ClearEmergency" if estop.clearing else "SetEmergency"
        limit = state.profile.emergency.max_attempts
        for address, target in estop.targets.items():
            if target.confirmed or target.next_at is None or now < target.next_at:
                continue
            if target.attempts >= limit:
                target.next_at = None
                state.counters["emergency_unconfirmed"] += 1
                log.warning("vehicle %s: %s to %s unconfirmed after %d attempts",
                            vehicle.vehicle_id, name, address, target.attempts)
                continue
            target.attempts += 1
            target.next_at = now + state.profile.emergency.retry_period
            state.actions.append(SendMessage(address, name, {"emergency_code": STOP},
                                             PRIORITY_SAFETY, None, EMERGENCY_CLASS))
            state.send(address, "QueryStatus", {}, "control")
            state.counters[f"emergency_{'clear' if estop.clearing else 'set'}_sent"] += 1

    # -- what the vehicle says --------------------------------------------------------------
    def on_status(self, vehicle: Vehicle, source: JausAddress, status: int,
                  now: float) -> None:
        """ReportStatus ``status`` from ``source``: confirms a SET or a CLEAR."""
        estop = vehicle.estop
        if estop is None:
            return
        target = estop.targets.get(source)
        if target is None or target.confirmed:
            return
        if (status == EMERGENCY) != estop.clearing:
            target.confirmed = True
            self._state.touch(vehicle)
            if estop.clearing and all(t.confirmed for t in estop.targets.values()):
                vehicle.estop = None
                log.warning("vehicle %s: emergency stop cleared by every component",
                            vehicle.vehicle_id)
            self._changed(vehicle, "emergency", now)

    def on_found(self, vehicle: Vehicle, now: float) -> None:
        """``vehicle`` is online again (it may have rebooted): deliver to all again."""
        if vehicle.estop is not None:
            self._retarget(vehicle, now, reset=True)
            self._state.touch(vehicle)

    def on_identified(self, vehicle: Vehicle, now: float) -> None:
        """``vehicle`` was identified or its services became known."""
        req = self.pending.pop(vehicle.vehicle_id, None)
        if req is not None and vehicle.estop is None:
            self.set(vehicle, req.operator_id, req.authority,
                     req.reason or f"set by {req.operator_id} before discovery", now)
        elif vehicle.estop is not None:
            self._retarget(vehicle, now, reset=False)
            self._state.touch(vehicle)

    def on_operator_lost(self, operator_id: str, now: float) -> None:
        """``operator_id``'s DDS writers are gone: with ``on_operator_lost``, set the
        emergency of every vehicle it held."""
        state = self._state
        if not state.profile.emergency.on_operator_lost:
            return
        for vehicle in list(state.vehicles.values()):
            holder = vehicle.arbitration.holder
            if holder is None or holder.operator_id != operator_id:
                continue
            state.counters["emergency_operator_lost"] += 1
            self.set(vehicle, operator_id, holder.authority,
                     f"set by the relay: operator {operator_id} vanished while holding "
                     f"the vehicle", now)
