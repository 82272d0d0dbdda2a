"""What the engine shows of itself: vehicle views, translator contexts, snapshots. No I/O.

Translators never see a :class:`~edge_vis.engine.vehicle.Vehicle`; they get a read-only
:class:`~edge_vis.kit.contract.VehicleView` inside a
:class:`~edge_vis.kit.contract.TranslatorContext`, built here on demand (views of the
other vehicles only when a translator looks them up, so a context stays cheap on the
report path). Status displays get an :class:`EngineSnapshot`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

from edge_vis.engine.access import jaus_control
from edge_vis.engine.control import EMERGENCY
from edge_vis.engine.handoff_requests import handoff_view
from edge_vis.engine.state import EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import TranslatorContext, VehicleView

NAN = math.nan


@dataclass(frozen=True, slots=True)
class SubscriptionView:
    """Status of one report subscription, for status displays."""

    provider: JausAddress
    report: str
    state: str
    rate: float
    event_id: int | None
    events_received: int
    reason: str
    events_missed: int = 0


@dataclass(frozen=True, slots=True)
class VehicleSnapshot:
    """A vehicle with its subscriptions and per-component control states."""

    view: VehicleView
    subscriptions: tuple[SubscriptionView, ...]
    controls: Mapping[JausAddress, str]


@dataclass(frozen=True, slots=True)
class EngineSnapshot:
    """Read-only status of the whole engine."""

    vehicles: tuple[VehicleSnapshot, ...]
    counters: Mapping[str, int] = field(default_factory=dict)
    shutting_down: bool = False


class Views:
    """Builds views, contexts and snapshots from the shared state."""

    def __init__(self, state: EngineState) -> None:
        self._state = state
        self._lazy = _LazyViews(self)

    def view(self, vehicle: Vehicle) -> VehicleView:
        """The read-only view of ``vehicle`` translators get."""
        state = self._state
        holder = vehicle.arbitration.holder
        notes = tuple(f"{a}: {c.note}" for a, c in sorted(vehicle.controls.items()) if c.note)
        last_ms = (int((vehicle.last_seen + state.wall_offset) * 1000)
                   if vehicle.last_seen is not None else 0)
        dialects = state.dialects(vehicle)
        return VehicleView(
            vehicle_id=vehicle.vehicle_id,
            subsystem=vehicle.subsystem,
            name=vehicle.name,
            vehicle_type=vehicle.vehicle_type,
            address=vehicle.address,
            services=vehicle.all_services(),
            components=dict(vehicle.components),
            online=vehicle.online,
            state=vehicle.state_name(),
            link=(vehicle.profile.link if vehicle.profile and vehicle.profile.link
                  else state.link_of(vehicle.address) if vehicle.address is not None else ""),
            last_seen=vehicle.last_seen,
            last_seen_ms=last_ms,
            controller=holder.operator_id if holder else "",
            controller_authority=holder.authority if holder else 0,
            jaus_control=jaus_control(vehicle),
            rejected_commands=vehicle.arbitration.rejected_commands,
            last_rejection=vehicle.arbitration.last_rejection,
            notes=notes,
            holders=tuple(h for _a, h in sorted(vehicle.holders.items())),
            clock=vehicle.clock,
            emergency=vehicle.estop is not None or EMERGENCY in vehicle.statuses.values(),
            emergency_operator=vehicle.estop.operator_id if vehicle.estop else "",
            emergency_reason=vehicle.estop.reason if vehicle.estop else "",
            relay=state.profile.relay_name if state.serves(vehicle) else "",
            handoffs=tuple(handoff_view(e) for e in vehicle.handoffs.entries),
            handoff_timeout=state.profile.control.handoff_timeout,
            handoff_reassert_timeout=state.profile.control.handoff_reassert_timeout,
            vehicle_handoff_timeout=(vehicle.handoff_timeouts[0]
                                     if vehicle.handoff_timeouts[0] is not None else NAN),
            dialects=tuple(dialects),
            base_codes=getattr(dialects, "base", frozenset()),
        )

    def context(self, vehicle: Vehicle | None, now: float,
                source: JausAddress | None = None, service_set: str = "") -> TranslatorContext:
        """What a translator is handed with an input at ``now``."""
        state = self._state
        return TranslatorContext(
            now=now,
            timestamp_ms=int((now + state.wall_offset) * 1000),
            relay_id=state.profile.jaus_id,
            vehicle=self.view(vehicle) if vehicle is not None else None,
            vehicles=self._lazy,
            source=source,
            catalogue=state.catalogue,
            service_set=service_set,
        )

    def snapshot(self) -> EngineSnapshot:
        """Read-only status of every vehicle, subscription and counter."""
        state = self._state
        vehicles = []
        for v in state.vehicles.values():
            subs = tuple(
                SubscriptionView(s.provider, s.report, s.state.value, s.rate, s.event_id,
                                 s.events_received, s.reason, s.events_missed)
                for s in v.subscriptions.values()
            )
            controls = {a: c.state.value for a, c in v.controls.items()}
            vehicles.append(VehicleSnapshot(self.view(v), subs, controls))
        return EngineSnapshot(tuple(vehicles), dict(state.counters), state.shutting_down)

    def by_id(self) -> Mapping[str, Vehicle]:
        """The vehicle table by id (for the lazy mapping of views)."""
        return self._state.by_id


class _LazyViews(Mapping[str, VehicleView]):
    """``vehicle_id -> VehicleView`` built on access, so contexts stay cheap."""

    def __init__(self, views: Views) -> None:
        self._views = views

    def __getitem__(self, key: str) -> VehicleView:
        return self._views.view(self._views.by_id()[key])

    def __iter__(self) -> Iterator[str]:
        return iter(self._views.by_id())

    def __len__(self) -> int:
        return len(self._views.by_id())
