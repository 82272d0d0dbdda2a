"""Commands from operators to a vehicle: admission, throttling, sending. No I/O.

A translator turns an operator's DDS sample into a :class:`~edge_vis.kit.actions.Command`;
it is admitted only from the operator holding the vehicle, never while the vehicle is in
EMERGENCY (for motion), and only if some component offers its service. Admitted commands
wait in a :class:`~edge_vis.engine.command_slots.CommandSlot` per kind (throttle and
dead-man) and go out once the providing component is controlled and ready. A rejection is
recorded on the vehicle's arbitration so translators can report it.
"""

from __future__ import annotations

from dataclasses import replace

from edge_vis.engine.command_slots import CommandSlot
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.kit.actions import Command, SendMessage


class Commands:
    """Admits operators' commands and sends them when their component is ready."""

    def __init__(self, state: EngineState, changed: Changed) -> None:
        self._state = state
        self._changed = changed

    def offer(self, command: Command, now: float) -> None:
        """A translator produced ``command``: admit it into its slot or reject it."""
        state = self._state
        vehicle = state.by_id.get(command.vehicle_id)
        if vehicle is None:
            state.counters["commands_unknown_vehicle"] += 1
            return
        state.touch(vehicle)
        arb = vehicle.arbitration
        reason = ""
        if not arb.allows(command.operator_id):
            holder = arb.holder.operator_id if arb.holder else "nobody"
            reason = (f"{command.name} from {command.operator_id} refused: control held by "
                      f"{holder}")
        elif command.stop is not None and vehicle.in_emergency():
            mode = "EMERGENCY (emergency stop)" if vehicle.estop else vehicle.state_name()
            reason = f"{command.name} refused: vehicle in {mode}"
        elif not vehicle.providers(command.service):
            reason = f"{command.name} refused: no component offers {command.service}"
        if reason:
            arb.reject(reason)
            state.counters["commands_rejected"] += 1
            self._changed(vehicle, "control", now)
            return
        slot = vehicle.commands.get(command.kind)
        if slot is None:
            profile = state.profile.commands
            if command.rate is not None or command.lifespan is not None:
                # a command mapping's own throttle replaces the profile's for its kind
                profile = replace(profile, rate=command.rate or profile.rate,
                                  lifespan=command.lifespan or profile.lifespan)
            slot = vehicle.commands[command.kind] = CommandSlot(profile)
        slot.offer(command, now)

    def can_send(self, vehicle: Vehicle, kind: str) -> bool:
        """True when the command waiting in slot ``kind`` may go out now."""
        slot = vehicle.commands[kind]
        command = slot.pending.command if slot.pending else slot.last_command
        if command is None or not vehicle.online:
            return False
        providers = vehicle.providers(command.service)
        if not providers:
            return False
        ctl = vehicle.controls.get(providers[0])
        if ctl is None or not ctl.ready:
            return False
        return command.stop is None or not vehicle.in_emergency()

    def pump(self, vehicle: Vehicle, now: float) -> None:
        """Send what the slots release; expire what cannot be sent."""
        state = self._state
        counters = state.counters
        for kind, slot in vehicle.commands.items():
            if vehicle.online and not state.shutting_down:
                slot.arm_deadman(now)
            if not self.can_send(vehicle, kind):
                before = slot.expired
                slot.expire(now)
                counters["commands_expired"] += slot.expired - before
                continue
            before = slot.expired
            command = slot.take(now)
            counters["commands_expired"] += slot.expired - before
            if command is None:
                continue
            destination = vehicle.providers(command.service)[0]
            state.actions.append(SendMessage(destination, command.name, dict(command.fields),
                                             command.priority, command.service_set, "command"))
            counters["commands_sent"] += 1
