"""The state every part of the engine shares, and the outbox its actions go to. No I/O.

The engine's concerns (finding vehicles, liveness, access control, reports, commands,
operators, rates, the timer pass) are separate objects; this is what they have in common
and are handed explicitly: the profile, the vehicle table, the counters, the outbox of
actions for the runtime, the set of vehicles the current input touched and a few
engine-wide flags. Keeping it in one plain object makes the sharing visible and keeps the
concerns free of references to each other's internals.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

from edge_vis.bandwidth.demands import FleetPlanner
from edge_vis.config import RelayProfile
from edge_vis.engine.control import Outgoing
from edge_vis.engine.subscriptions import Request
from edge_vis.engine.vehicle import Vehicle
from edge_vis.errors import EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Action, SendMessage

#: tells translators that ``vehicle`` changed (``change`` names what) at ``now``
Changed = Callable[[Vehicle, str, float], None]
#: handles one (possibly unwrapped) JAUS message ``name`` of a known vehicle
#: (vehicle, sender, message name, fields, now, the message's set) -> None
Handle = Callable[[Vehicle, JausAddress, str, Mapping[str, Any], float, str], None]
#: handles one JAUS message of a known vehicle whose name is implied (a handler table entry)
Handler = Callable[[Vehicle, JausAddress, Mapping[str, Any], float], None]


class InnerCodec(Protocol):
    """What the engine needs from the catalogue: the payloads nested in events."""

    def encode(self, name_or_code: str | int, fields: Mapping[str, Any],
               dialects: Sequence[str] = ()) -> bytes: ...

    def decode(self, payload: bytes, dialects: Sequence[str] = ()) -> Any: ...

    def by_name(self, name: str, service_set: str | None = None) -> Any: ...


def dialects_of(catalogue: Any, vehicle: Vehicle) -> tuple[str, ...]:
    """The message dialects ``vehicle`` speaks: its profile's ``dialects`` when given,
    else those its services are recognised by (none: the base definitions), keeping the
    base definition of a code it carries in a service of that definition's version
    (:meth:`~edge_vis.catalogue.Catalogue.speaks`: a vehicle reporting 1.x and 2.x
    manipulator services reads each such message as the service carrying it defines it)."""
    for profile in (vehicle.profile, vehicle.announced_by):
        if profile is not None and profile.dialects is not None:
            return profile.dialects
    speaks = getattr(catalogue, "speaks", None) or getattr(catalogue, "recognise", None)
    if speaks is None or not vehicle.components:
        return ()
    # every (uri, version) of every component: two versions of one service both count
    services = tuple(sorted({s for found in vehicle.components.values() for s in found}))
    cached = vehicle.dialect_cache
    if cached is not None and cached[0] == services:
        return cached[1]
    found: tuple[str, ...] = speaks(services)
    if not isinstance(found, tuple):
        found = tuple(found)
    vehicle.dialect_cache = (services, found)
    return found


class EngineState:
    """Profile, vehicle table, counters, outbox and flags shared by the engine's parts."""

    def __init__(self, profile: RelayProfile, catalogue: InnerCodec | None,
                 wall_offset: float, planner: FleetPlanner | None) -> None:
        self.profile = profile
        #: plans report rates to fit the links' budgets (None: the profiles' rates as is)
        self.planner = planner
        self.wall_offset = wall_offset
        self.counters: Counter[str] = Counter()
        #: subsystem -> vehicle, and the same vehicles by id
        self.vehicles: dict[int, Vehicle] = {}
        self.by_id: dict[str, Vehicle] = {}
        #: what the runtime is to carry out, in order (drained by the engine's caller)
        self.actions: list[Action] = []
        #: vehicles whose state the current input changed: the next pass visits them
        self.touched: dict[int, Vehicle] = {}
        #: the name of the link a JAUS address is reached over (the runtime asks its
        #: router); vehicle profiles that name their link take precedence
        self.link_of: Callable[[JausAddress], str] = lambda _address: ""
        #: (vehicle id, report) the bandwidth plan could not fit at all
        self.dropped: set[tuple[str, str]] = set()
        #: a subscription started or stopped polling: the rates must be planned again
        self.plan_dirty = False
        self.shutting_down = False
        #: several relays may reach a vehicle: only the vehicles whose ``serving`` is set
        #: are served (:mod:`edge_vis.engine.duty`); False: every vehicle is
        self.arbitrated = False
        #: (topic, instance key) -> the latest merged sample (Publish with ``merge``)
        self.merged: dict[tuple[str, tuple[Any, ...]], dict[str, Any]] = {}
        #: ShutdownComplete was emitted: the engine takes no more input
        self.done = False
        self._catalogue = catalogue

    @property
    def catalogue(self) -> InnerCodec:
        """The catalogue used for payloads nested in CreateEvent and Event."""
        if self._catalogue is None:
            from edge_vis.catalogue import default_catalogue

            self._catalogue = default_catalogue()
        return self._catalogue

    def encode_query(self, name: str, fields: Mapping[str, Any],
                     dialects: Sequence[str] = (), service_set: str | None = None) -> bytes:
        """The complete query message a CreateEvent carries (as ``dialects`` read it; the
        message of ``service_set`` when two sets use ``name``)."""
        code: str | int = name
        if service_set is not None:
            try:
                code = self.catalogue.by_name(name, service_set).code
            except KeyError:
                raise EncodeError(f"no message named {name!r} in service set "
                                  f"{service_set!r}") from None
        if dialects:
            return self.catalogue.encode(code, fields, dialects)
        return self.catalogue.encode(code, fields)

    def serves(self, vehicle: Vehicle) -> bool:
        """This relay serves ``vehicle``: creates its events, holds its control, sends its
        commands and publishes its samples."""
        return vehicle.serving or not self.arbitrated

    def dialects(self, vehicle: Vehicle) -> tuple[str, ...]:
        """The message dialects ``vehicle`` speaks (see :func:`dialects_of`)."""
        return dialects_of(self.catalogue, vehicle)

    def touch(self, vehicle: Vehicle) -> None:
        """``vehicle``'s state changed: the next pass must visit it."""
        self.touched[id(vehicle)] = vehicle

    def send(self, destination: JausAddress, name: str, fields: Mapping[str, Any],
             traffic_class: str = "liveness", service_set: str | None = None) -> None:
        """Queue a JAUS message for ``destination``."""
        self.actions.append(SendMessage(destination, name, dict(fields),
                                        traffic_class=traffic_class, service_set=service_set))

    def send_outgoing(self, destination: JausAddress, items: Sequence[Outgoing]) -> None:
        """Queue what an access-control machine wants sent."""
        for item in items:
            self.send(destination, item.name, item.fields, "control")

    def send_requests(self, destination: JausAddress, items: Sequence[Request]) -> None:
        """Queue what a subscription machine wants sent."""
        for item in items:
            self.send(destination, item.name, item.fields, "telemetry", item.service_set)
