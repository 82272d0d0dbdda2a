"""The translator contract: pure mappings between JAUS messages and DDS samples. No I/O.

A translator is a plugin (entry-point group ``edge_vis.translators``) that declares, as
class attributes, what it deals with, so conflicts are found at start-up:

* ``messages`` - names of the JAUS messages it consumes (reports, usually);
* ``reports`` - :class:`ReportSpec` entries: the reports it wants delivered, how to query
  them, from which service and at which rate. The engine creates JAUS events for them (or
  polls when the vehicle ignores events);
* ``publishes`` / ``subscribes`` - the DDS topics it writes and reads;
* ``controlled_services`` - service URIs it sends commands to; the engine takes control of
  the components offering them while an operator holds the vehicle;
* ``bindings`` - for a listed message whose name is not enough, which of them it takes
  (:class:`Binding`): the one of a message set (``ReportActiveElement`` is 0x441E in
  mobility and 0x461E in manipulator) and/or those sent by a component offering one of
  some services (the core List Manager's reports, which every list driver inherits). Two
  translators may list one name when their bindings do not overlap.

Call order (one translator instance per engine)::

    __init__()  ->  configure(table)?  ->  verify(catalogue)
                ->  ( on_message | on_sample | on_vehicle )*

A translator with options declares them as a dataclass, :attr:`Translator.options_type`;
``configure`` reads the profile's ``[translators.NAME]`` table against it with the
validation kit (:mod:`edge_vis.schema`: unknown keys, types, ranges, all named with their
key path) and hands the result to ``apply_options``. A translator without an options type
refuses any table. ``verify`` checks what the options name against the live catalogue
(messages, field paths) before the relay starts; ``edge-vis check`` calls it too.
``describe`` gives the rows of the mapping table (``edge-vis mappings``; the default lists
``messages``).

Every hook receives a read-only :class:`TranslatorContext` and returns a list of actions
(:class:`~edge_vis.kit.actions.Publish`, :class:`~edge_vis.kit.actions.Command`,
:class:`~edge_vis.kit.actions.DeclareVehicle`). A translator never touches sockets,
DDS or the clock; the context carries the time and the live message catalogue (with the
profile's own JSIDL), so a translator needs nothing from the engine's internals.
"""

from __future__ import annotations

import re
from abc import ABC
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Action
from edge_vis.schema import read_table

#: Management states (ReportStatus.status), AS5710 Management service.
STATUS_NAMES: Mapping[int, str] = {
    0: "INITIALIZE", 1: "READY", 2: "STANDBY", 3: "SHUTDOWN", 4: "FAILURE", 5: "EMERGENCY",
}


@dataclass(frozen=True, slots=True)
class ReportSpec:
    """A report a translator wants: ``query`` (with ``query_fields``) asks ``service`` for
    ``report``. ``rate`` is the default rate in Hz (profiles override it per report);
    ``on_change`` asks for an every-change event instead of a periodic one."""

    report: str
    query: str
    service: str
    query_fields: Mapping[str, Any] = field(default_factory=dict)
    rate: float = 1.0
    on_change: bool = False
    #: the message set of ``query`` and ``report`` when two sets use the names
    service_set: str | None = None


@dataclass(frozen=True, slots=True)
class Binding:
    """Which messages of a listed name reach a translator: those of ``service_set`` ("" =
    any set) sent by a component offering one of ``services`` (empty = any component)."""

    service_set: str = ""
    services: tuple[str, ...] = ()

    def overlaps(self, other: Binding) -> bool:
        """Whether a message could match both (then two translators cannot both claim it)."""
        sets = not self.service_set or not other.service_set \
            or self.service_set == other.service_set
        services = not self.services or not other.services \
            or bool(set(self.services) & set(other.services))
        return sets and services

    def matches(self, service_set: str, services: tuple[str, ...]) -> bool:
        """Whether a message of ``service_set`` ("" when not known: any) from a component
        offering ``services`` matches."""
        return (not self.service_set or not service_set or self.service_set == service_set) \
            and \
            (not self.services or any(uri in services for uri in self.services))

    @property
    def specificity(self) -> int:
        """The more a binding names, the more it is preferred among matches."""
        return 2 * bool(self.service_set) + bool(self.services)


@dataclass(frozen=True, slots=True)
class TopicDecl:
    """A DDS topic a translator adds: ``name`` carries the data-model type ``type_name``
    (``"GenericReport"``) with the QoS of ``kind`` (``telemetry``, ``state``, ``command``,
    ``product`` or ``bulk``). A declaration, so the kit needs no DDS to describe it; the
    DDS side resolves the type when the relay opens its topics.

    With ``shape`` (a :class:`~edge_vis.kit.shapes.StructShape`) the type is not one of the
    model's: the DDS side builds it at run time from the shape, and ``type_name`` is its
    scoped IDL name (a profile mapping's typed topic, ``edge_vis::profile::CameraStatus``)."""

    name: str
    type_name: str
    kind: str = "telemetry"
    shape: Any = None


@dataclass(frozen=True, slots=True)
class HolderView:
    """Who holds JAUS control of one component, as the component last reported it.

    ``controller`` is the controlling client's address (None when nobody controls it),
    ``authority`` the authority it controls with (ReportControl), ``current_authority``
    the component's current authority (ReportAuthority; its default when uncontrolled),
    ``is_relay`` whether the controller is this relay.
    """

    component: JausAddress
    controller: JausAddress | None = None
    authority: int = 0
    current_authority: int = 0
    is_relay: bool = False


@dataclass(frozen=True, slots=True)
class HandoffView:
    """One request to hand a vehicle over (IOP EnhancedAccessControl): ``requester`` is an
    operator id, or ``jaus:S.N.C`` for another JAUS client asking through the vehicle
    component ``via``; ``state`` PENDING or DEFERRED while the holder decides, then
    GRANTED, DENIED, TIMEOUT, CANCELLED, NOT_AVAILABLE or INSUFFICIENT_AUTHORITY."""

    request_id: int
    requester: str
    authority: int
    explanation: str = ""
    state: str = "PENDING"
    reason: str = ""
    via: str = ""


@dataclass(frozen=True, slots=True)
class ClockView:
    """A vehicle's clock against the relay's: ``offset`` seconds (vehicle minus relay, the
    message's flight time taken as half the round trip ``round_trip``), read from
    ``component``'s ReportTime; ``set_time_sent`` counts SetTime the relay sent it."""

    component: JausAddress
    offset: float
    round_trip: float
    set_time_sent: int = 0
    note: str = ""


@dataclass(frozen=True, slots=True)
class VehicleView:
    """What translators may know about a vehicle (a snapshot; changing it changes nothing).

    ``state`` is the most severe management status of its components (``"READY"``,
    ``"EMERGENCY"``...), ``"UNKNOWN"`` before any ReportStatus, ``"OFFLINE"`` when lost.
    ``services`` are ``(uri, version)`` pairs over all components. ``holders`` says who
    holds each component with AccessControl, ``clock`` how far its clock is off,
    ``handoffs`` who asked the holder to hand it over.
    """

    vehicle_id: str
    subsystem: int
    name: str = ""
    vehicle_type: str = ""
    address: JausAddress | None = None
    services: tuple[tuple[str, str], ...] = ()
    components: Mapping[JausAddress, tuple[tuple[str, str], ...]] = field(default_factory=dict)
    online: bool = False
    state: str = "UNKNOWN"
    link: str = ""
    last_seen: float | None = None
    last_seen_ms: int = 0
    controller: str = ""
    controller_authority: int = 0
    jaus_control: str = "none"
    rejected_commands: int = 0
    last_rejection: str = ""
    notes: tuple[str, ...] = ()
    #: an emergency stop is in force: set through the relay and not yet cleared, or a
    #: component reports EMERGENCY; who set it through the relay and why
    emergency: bool = False
    emergency_operator: str = ""
    emergency_reason: str = ""
    holders: tuple[HolderView, ...] = ()
    clock: ClockView | None = None
    #: the relay serving it (this one's name while it does; see ``[serving]``)
    relay: str = ""
    #: hand-off requests to the holder (open ones and the latest outcomes), the relay's
    #: hand-off and re-assert timeouts (s, 0 = none) and the vehicle's own (NaN: unknown)
    handoffs: tuple[HandoffView, ...] = ()
    handoff_timeout: float = 0.0
    handoff_reassert_timeout: float = 0.0
    vehicle_handoff_timeout: float = float("nan")
    #: the message dialects it speaks (``manipulator-1.0``, ``iop``): its messages are
    #: decoded and encoded with those definitions
    dialects: tuple[str, ...] = ()
    #: codes it reads in the base definition although one of ``dialects`` defines them
    #: (it carries them in a service of the base definition's version)
    base_codes: frozenset[int] = frozenset()

    def speaks(self, dialect: str, code: int) -> bool:
        """Whether message ``code`` to or from it is read in ``dialect``'s definition."""
        return dialect in self.dialects and code not in self.base_codes


@dataclass(frozen=True, slots=True)
class TranslatorContext:
    """Read-only context of one call: the time, the relay and the vehicle concerned.

    ``now`` is the engine's clock (seconds); ``timestamp_ms`` is wall-clock milliseconds
    since the Unix epoch, for sample timestamps. ``source`` is the JAUS sender of the
    message being translated, if any.
    """

    now: float
    timestamp_ms: int
    relay_id: JausAddress
    vehicle: VehicleView | None = None
    vehicles: Mapping[str, VehicleView] = field(default_factory=dict)
    source: JausAddress | None = None
    #: the relay's message catalogue (``edge_vis.catalogue.Catalogue``: shipped sets,
    #: message-set plugins and the profile's JSIDL), for encoding or looking up messages
    catalogue: Any = None
    #: the message set of the message being translated ("" when not known)
    service_set: str = ""


class Translator(ABC):  # noqa: B024 - every hook has a harmless default
    """Base class of translator plugins; override the hooks you need.

    Subclasses are named ``<ServiceSet>Translator`` and registered under the entry-point
    name they expose as :attr:`name`.
    """

    name: ClassVar[str] = ""
    messages: ClassVar[tuple[str, ...]] = ()
    reports: ClassVar[tuple[ReportSpec, ...]] = ()
    publishes: ClassVar[tuple[str, ...]] = ()
    subscribes: ClassVar[tuple[str, ...]] = ()
    controlled_services: ClassVar[tuple[str, ...]] = ()
    #: listed message name -> which of them it takes (unbound names: all of them)
    bindings: ClassVar[Mapping[str, Binding]] = {}
    #: DDS topics of this translator's own: :class:`TopicDecl` (a topic name for a type of
    #: the shipped data model), or ``edge_vis.dds.topics.TopicSpec`` for a custom
    #: translator that brings its own IDL type
    topic_types: ClassVar[tuple[Any, ...]] = ()
    #: the dataclass its ``[translators.NAME]`` table is read into; None: takes no options
    options_type: ClassVar[type | None] = None

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        """A JAUS message listed in :attr:`messages` arrived from ``ctx.vehicle``.

        Reports carried inside Event messages arrive here already unwrapped.
        """
        return []

    def on_sample(
        self, topic: str, sample: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        """A sample of a topic listed in :attr:`subscribes` arrived (``ctx.vehicle`` is the
        vehicle named by the sample's ``vehicle_id``, or None if unknown)."""
        return []

    def configure(self, options: Mapping[str, Any], source: str = "") -> None:
        """Take the profile's ``[translators.NAME]`` table (from file ``source``).

        The table is read against :attr:`options_type` and the result given to
        :meth:`apply_options`; raises ConfigError naming every bad key. A translator
        without an options type takes no table.
        """
        where = f"translators.{self.name or type(self).__name__}"
        if self.options_type is None:
            raise ConfigError([(source, where, "this translator takes no options")])
        self.apply_options(read_table(self.options_type, options, file=source, path=where))

    def apply_options(self, options: Any) -> None:  # noqa: B027 - an optional hook
        """Use validated options (an instance of :attr:`options_type`)."""

    def verify(self, catalogue: Any, source: str = "") -> None:  # noqa: B027 - optional
        """Check the configured options against ``catalogue`` (the relay's live one, with
        the profile's JSIDL) before anything runs; raise ConfigError naming each message,
        service or field path that does not exist. The default has nothing to check."""

    def describe(self) -> list[dict[str, Any]]:
        """Rows of the mapping table, one per JAUS message (see ``edge-vis mappings``)."""
        queries = {spec.report: spec.query for spec in self.reports}
        return [{"translator": self.name, "direction": "jaus->dds", "message": message,
                 "topic": ", ".join(self.publishes), "query": queries.get(message, ""),
                 "service": "", "rate": None, "fields": [],
                 "doc": "declared message and topics only"}
                for message in self.messages]

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        """The engine's view of ``ctx.vehicle`` changed.

        ``change`` is one of ``"identified"`` (identity or services learnt),
        ``"online"``, ``"offline"``, ``"status"`` (management state), ``"control"``
        (operator arbitration, JAUS access control, who holds each component),
        ``"emergency"`` (an emergency stop set, confirmed or cleared through the relay),
        ``"clock"`` (a new reading of the vehicle's clock) and ``"handoff"`` (a hand-off
        request made, answered or timed out).
        """
        return []


_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def derive_vehicle_id(name: str, subsystem: int) -> str:
    """A stable vehicle ID from the reported name and subsystem: ``SimulatedVehicle-126``."""
    clean = _UNSAFE.sub("_", name.strip()).strip("_")
    return f"{clean or 'jaus'}-{subsystem}"
