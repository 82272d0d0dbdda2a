"""Commands from operators to a vehicle: admission, throttling, sending. No I/O.

A translator turns an operator's DDS sample into a :class:`~edge_vis.kit.actions.Command`;
it is admitted only from the operator holding the vehicle, never while the vehicle is in
EMERGENCY (for motion and management), and only if some component offers its service.
Admitted commands wait in a :class:`~edge_vis.engine.command_slots.CommandSlot` per kind
(throttle and dead-man) and go out once the providing component is controlled and ready
(controlled is enough for management commands, ``needs_ready=False``). A rejection is
recorded on the vehicle's arbitration so translators can report it; so is a management
command that expires because the relay could not get control of its component.
"""

from __future__ import annotations

from dataclasses import replace

from edge_vis.engine.command_slots import CommandSlot
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
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
        if not state.serves(vehicle):  # the relay serving it sends it (edge_vis.engine.duty)
            state.counters["commands_other_relay"] += 1
            vehicle.not_sent_at.append(now)  # told if this relay takes over (duty)
            del vehicle.not_sent_at[:-64]
            return
        state.touch(vehicle)
        arb = vehicle.arbitration
        reason = ""
        if not arb.allows(command.operator_id):
            holder = arb.holder.operator_id if arb.holder else "nobody"
            reason = (f"{command.name} from {command.operator_id} refused: control held by "
                      f"{holder}")
        elif (command.stop is not None or not command.needs_ready) and vehicle.in_emergency():
            mode = "EMERGENCY (emergency stop)" if vehicle.estop else vehicle.state_name()
            reason = f"{command.name} refused: vehicle in {mode}"
        elif not vehicle.providers(command.service):
            reason = f"{command.name} refused: no component offers {command.service}"
        elif command.component is not None and not vehicle.offers(command.component,
                                                                   command.service):
            reason = (f"{command.name} refused: component {command.component} does not "
                      f"offer {command.service}")
        elif command.needs_ready and (held := [
                a for a in self.destinations(vehicle, command)
                if (c := vehicle.controls.get(a)) is not None and c.hold_standby]):
            reason = (f"{command.name} refused: {held[0]} in STANDBY at the operator's "
                      f"request (send Resume)")
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

    def destinations(self, vehicle: Vehicle, command: Command) -> list[JausAddress]:
        """The components ``command`` goes to."""
        if command.component is not None:
            return [command.component] if vehicle.offers(command.component,
                                                          command.service) else []
        providers = vehicle.providers(command.service)
        return providers if command.every_provider else providers[:1]

    def can_send(self, vehicle: Vehicle, kind: str) -> bool:
        """True when the command waiting in slot ``kind`` may go out now."""
        slot = vehicle.commands[kind]
        command = slot.pending.command if slot.pending else slot.last_command
        if command is None or not vehicle.online:
            return False
        destinations = self.destinations(vehicle, command)
        if not destinations:
            return False
        for address in destinations:
            ctl = vehicle.controls.get(address)
            if ctl is None or not (ctl.ready if command.needs_ready else ctl.controlled):
                return False
        return (command.stop is None and command.needs_ready) or not vehicle.in_emergency()

    def pump(self, vehicle: Vehicle, now: float) -> None:
        """Send what the slots release; expire what cannot be sent."""
        state = self._state
        counters = state.counters
        for kind, slot in vehicle.commands.items():
            if vehicle.online and not state.shutting_down:
                slot.arm_deadman(now)
            if not self.can_send(vehicle, kind):
                before = slot.expired
                waiting = slot.pending.command if slot.pending is not None else None
                slot.expire(now)
                counters["commands_expired"] += slot.expired - before
                if waiting is not None and slot.expired > before and not waiting.needs_ready:
                    self._expired_without_control(vehicle, waiting, now)
                continue
            before = slot.expired
            command = slot.take(now)
            counters["commands_expired"] += slot.expired - before
            if command is None:
                continue
            for destination in self.destinations(vehicle, command):
                state.actions.append(SendMessage(destination, command.name,
                                                 dict(command.fields), command.priority,
                                                 command.service_set, "command"))
                counters["commands_sent"] += 1
                if not command.needs_ready:
                    vehicle.controls[destination].on_command(command.name, now)
                    # let the operator see the effect: ask for the new state at once
                    state.send(destination, "QueryStatus", {})

    def _expired_without_control(self, vehicle: Vehicle, command: Command,
                                 now: float) -> None:
        """A management command waited its lifespan without control: say why."""
        why = []
        for address in self.destinations(vehicle, command):
            ctl = vehicle.controls.get(address)
            if ctl is not None and ctl.controlled:
                continue
            holder = vehicle.holders.get(address)
            held = (f"held by {holder.controller} (authority {holder.authority})"
                    if holder is not None and holder.controller is not None
                    and not holder.is_relay else
                    f"relay control {ctl.state.value if ctl else 'none'}")
            why.append(f"{address} {held}")
        reason = (f"{command.name} from {command.operator_id} not sent: no JAUS control of "
                  + ("; ".join(why) or "its component"))
        vehicle.arbitration.reject(reason)
        self._state.counters["commands_rejected"] += 1
        self._changed(vehicle, "control", now)
