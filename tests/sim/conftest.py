"""Harness for the simulated vehicle's sans-I/O logic: a fake clock and a catalogue wire.

Every message given to the vehicle is encoded and decoded by the catalogue first, and
every message it sends is encoded and decoded too (events unwrapped), so a wrong field
name or an out-of-range value fails the test that caused it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import pytest

from edge_vis.catalogue import Message, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.tools.sim.outputs import Restarted, Send
from edge_vis.tools.sim.profile import FaultSpec, VehicleSpec
from edge_vis.tools.sim.subsystem import SimVehicle

OCU = JausAddress(200, 1, 1)
OTHER = JausAddress(201, 1, 1)
PLATFORM = JausAddress(101, 1, 2)
NODE_MANAGER = JausAddress(101, 1, 1)
SENSORS = JausAddress(101, 1, 3)


@dataclass(frozen=True)
class Out:
    """One message the vehicle sent, decoded."""

    source: JausAddress
    destination: JausAddress
    name: str
    fields: dict[str, Any]
    report: Message | None = None  # the report inside an Event


def spec(**changes: Any) -> VehicleSpec:
    faults = changes.pop("faults", None)
    base = VehicleSpec("ugv-test", 101, "udp://127.0.0.1:0", init_time=0.5)
    if faults is not None:
        changes["faults"] = faults if isinstance(faults, FaultSpec) else FaultSpec(**faults)
    return replace(base, **changes)


class Wire:
    """A vehicle driven with a fake clock through the real catalogue."""

    def __init__(self, vehicle_spec: VehicleSpec | None = None, start: float = 0.0) -> None:
        self.catalogue = default_catalogue()
        self.now = start
        self.vehicle = SimVehicle(vehicle_spec or spec(), self.catalogue, start=start)
        self.restarts = 0

    def _decode(self, actions: list[Any]) -> list[Out]:
        outs = []
        for action in actions:
            if isinstance(action, Restarted):
                self.restarts += 1
                continue
            assert isinstance(action, Send)
            payload = self.catalogue.encode(action.name, action.fields)
            msg = self.catalogue.decode(payload)
            report = self.catalogue.unwrap_event(msg) if msg.name == "Event" else None
            outs.append(Out(action.source, action.destination, msg.name or "?",
                            msg.fields or {}, report))
        return outs

    def send(self, name: str, fields: Mapping[str, Any] | None = None, *,
             to: JausAddress = PLATFORM, source: JausAddress = OCU) -> list[Out]:
        msg = self.catalogue.decode(self.catalogue.encode(name, fields or {}))
        return self._decode(self.vehicle.receive(source, to, msg, self.now))

    def query(self, name: str, fields: Mapping[str, Any] | None = None, **kw: Any) -> Out:
        outs = self.send(name, fields, **kw)
        assert len(outs) == 1, outs
        return outs[0]

    def advance(self, seconds: float, step: float = 0.02) -> list[Out]:
        outs: list[Out] = []
        end = self.now + seconds
        while self.now < end - 1e-9:
            self.now = min(end, self.now + step)
            outs += self._decode(self.vehicle.on_timer(self.now))
        return outs

    def payload(self, name: str, fields: Mapping[str, Any] | None = None) -> bytes:
        return self.catalogue.encode(name, fields or {})

    def take_control(self, authority: int = 100, source: JausAddress = OCU,
                     to: JausAddress = PLATFORM) -> None:
        out = self.query("RequestControl", {"authority_code": authority}, to=to, source=source)
        assert (out.name, out.fields["response_code"]) == ("ConfirmControl", 0)

    def ready(self, authority: int = 100) -> None:
        """Initialise, take control of the platform and Resume it."""
        self.advance(1.0)
        self.take_control(authority)
        self.send("Resume")
        assert self.query("QueryStatus").fields["status"] == 1


@pytest.fixture
def wire() -> Wire:
    return Wire()


def named(outs: list[Out], name: str) -> list[Out]:
    return [o for o in outs if o.name == name]
