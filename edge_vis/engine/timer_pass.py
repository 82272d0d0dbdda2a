"""The timer pass: what is due, when the next thing is due, and the shutdown sequence.

After every input and timer wake-up the engine runs one pass that sends whatever is due:
the discovery broadcast, and per vehicle the silence check, service queries, liveness
probes, control renewals, subscription refreshes and polls, and queued commands. Visiting
every vehicle on every report would make a report's cost grow with the fleet, so a pass
visits every vehicle only when one of their deadlines has come (or the table changed, or
the relay is stopping), and otherwise only the vehicles the input touched; the cached
earliest deadline is kept exact or early, never late. Shutdown cancels events and
releases control, then reports ShutdownComplete once all are answered or timed out.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from edge_vis.engine.access import Access
from edge_vis.engine.commands import Commands
from edge_vis.engine.control import ControlState
from edge_vis.engine.estop import EmergencyStops
from edge_vis.engine.finder import Finder
from edge_vis.engine.liveness import Liveness
from edge_vis.engine.rates import Rates
from edge_vis.engine.reports import Reports
from edge_vis.engine.state import EngineState
from edge_vis.engine.subscriptions import SubscriptionState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.kit.actions import ShutdownComplete

if TYPE_CHECKING:
    from edge_vis.engine.duty import Duty


class TimerPass:
    """Runs the timer pass over the engine's parts and tracks the next deadline."""

    def __init__(self, state: EngineState, finder: Finder, liveness: Liveness,
                 access: Access, reports: Reports, commands: Commands, rates: Rates,
                 estop: EmergencyStops,
                 polls: Sequence[Callable[[Vehicle, float], None]] = (),
                 duty: Duty | None = None) -> None:
        self._state = state
        self._finder = finder
        self._liveness = liveness
        self._access = access
        self._reports = reports
        self._commands = commands
        self._rates = rates
        #: further per-vehicle duties (holder queries, clocks), each due by its own fields
        self._polls = tuple(polls)
        self._estop = estop
        #: serving or standing by, when several relays share the domain
        self._duty = duty
        self._vehicle_due: float | None = None
        self._due_valid = False
        self._vehicle_count = 0
        self._shutdown_deadline: float | None = None

    def next_deadline(self) -> float | None:
        """When the next pass must run; None when nothing is scheduled."""
        state = self._state
        times: list[float | None] = [self._shutdown_deadline]
        if not state.shutting_down:
            times.append(self._finder.next_discovery)
            if self._duty is not None:
                times.append(self._duty.next_due)
        if not self._due_valid:
            self._vehicle_due = self._earliest(state.vehicles.values())
            self._due_valid = True
        times.append(self._vehicle_due)
        real = [t for t in times if t is not None]
        return min(real) if real else None

    def run(self, now: float) -> None:
        """The pass that sends whatever is due (see the module docstring)."""
        state = self._state
        if state.done:
            return
        if not state.shutting_down:
            self._finder.broadcast(now)
        full = (
            state.shutting_down
            or not self._due_valid
            or len(state.vehicles) != self._vehicle_count
            or (self._vehicle_due is not None and now >= self._vehicle_due)
        )
        visit = list(state.vehicles.values()) if full else list(state.touched.values())
        state.touched = {}
        for vehicle in visit:
            self._visit(vehicle, now)
        if full:
            self._vehicle_count = len(state.vehicles)
            self._vehicle_due = self._earliest(state.vehicles.values())
            self._due_valid = True
        elif visit:
            due = self._earliest(visit)
            if due is not None and (self._vehicle_due is None or due < self._vehicle_due):
                self._vehicle_due = due
        if self._duty is not None and not state.shutting_down:
            self._duty.start(now)
            self._duty.on_timer(now)
            for vehicle in state.touched.values():  # started or stopped serving
                self._visit(vehicle, now)
        if state.touched:  # a visit touched another vehicle: settle it at the next pass
            self._due_valid = False
        if state.plan_dirty and state.planner is not None and not state.shutting_down:
            self._rates.replan(now)
        if state.shutting_down:
            self._check_shutdown(now)

    def shutdown(self, now: float) -> None:
        """Cancel every event, release every component, drop queued commands."""
        state = self._state
        if state.shutting_down:
            return
        state.shutting_down = True
        for vehicle in state.vehicles.values():
            self._reports.cancel(vehicle, now)
            self._access.release(vehicle, now)
            for slot in vehicle.commands.values():
                slot.clear()
        self._shutdown_deadline = now + max(state.profile.control.response_timeout,
                                            state.profile.events.response_timeout)
        self.run(now)

    def _visit(self, vehicle: Vehicle, now: float) -> None:
        state = self._state
        stopping = state.shutting_down
        if not stopping:
            if (vehicle.online and vehicle.last_seen is not None
                    and now > vehicle.last_seen + vehicle.silence_timeout(
                        state.profile.discovery.silence_timeout)):
                self._liveness.lose(vehicle, now)
            if vehicle.next_services_query is not None and now >= vehicle.next_services_query:
                self._finder.query_services(vehicle, now)
            if vehicle.next_liveness is not None and now >= vehicle.next_liveness:
                self._liveness.probe(vehicle, now)
        if vehicle.estop is not None:
            self._estop.pump(vehicle, now)
        self._access.poll(vehicle, now)
        if state.serves(vehicle):  # a relay standing by keeps to liveness
            for poll in self._polls:
                poll(vehicle, now)
        self._reports.poll(vehicle, now)
        if not stopping:
            self._commands.pump(vehicle, now)

    def _earliest(self, vehicles: Iterable[Vehicle]) -> float | None:
        """The earliest deadline of any of ``vehicles``."""
        state = self._state
        can_send = self._commands.can_send
        times: list[float | None] = []
        silence = state.profile.discovery.silence_timeout
        for v in vehicles:
            if not state.shutting_down:
                times.append(v.next_liveness)
                times.append(v.next_services_query)
                if v.online:
                    times.append(v.next_holder_query)
                    times.append(v.next_time_query)
                    times.append(v.handoffs.next_deadline())
                if v.online and v.last_seen is not None:
                    times.append(v.last_seen + v.silence_timeout(silence) + 1e-6)
                for key, slot in v.commands.items():
                    times.append(slot.next_deadline(can_send(v, key)))
            if v.estop is not None and v.online:
                times.append(v.estop.next_deadline())
            times.extend(c.next_deadline() for c in v.controls.values())
            times.extend(s.next_deadline() for s in v.subscriptions.values())
        real = [t for t in times if t is not None]
        return min(real) if real else None

    def _check_shutdown(self, now: float) -> None:
        state = self._state
        pending = sum(
            1 for v in state.vehicles.values() for s in v.subscriptions.values()
            if s.state is SubscriptionState.CANCELLING
        ) + sum(
            1 for v in state.vehicles.values() for c in v.controls.values()
            if c.state is ControlState.RELEASING
        )
        expired = self._shutdown_deadline is not None and now >= self._shutdown_deadline
        if pending == 0 or expired:
            timed_out = sum(
                1 for v in state.vehicles.values() for s in v.subscriptions.values()
                if s.unanswered
            ) + sum(
                1 for v in state.vehicles.values() for c in v.controls.values() if c.unanswered
            )
            state.done = True
            self._shutdown_deadline = None
            state.actions.append(ShutdownComplete(pending + timed_out))
