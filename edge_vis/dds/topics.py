"""Which DDS topics exist, which type each carries and which QoS kind applies. No I/O.

A :class:`TopicSpec` names a topic, its IdlStruct type and its :class:`TopicKind`; the kind
decides the QoS (:mod:`edge_vis.dds.qos`) and the direction: the relay *subscribes* to
COMMAND topics and *publishes* all others.

:class:`TopicRegistry` starts with the standard model (:func:`standard_topics`). Translator
plugins with their own data types register extra topics at start-up; registering a name
again with the same type and kind is a no-op, with anything else a
:class:`~edge_vis.errors.PluginConflictError` naming both owners.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from cyclonedds.idl import IdlStruct

from edge_vis.dds import model
from edge_vis.dds.runtime_types import struct_type
from edge_vis.errors import PluginConflictError


class TopicKind(enum.Enum):
    """How a topic's data behaves; each kind has one QoS profile."""

    TELEMETRY = "telemetry"
    """Periodic measurements: only the newest per vehicle matters, a lost one is replaced."""
    STATE = "state"
    """Slowly changing state: every reader, including late joiners, must see the latest."""
    COMMAND = "command"
    """Operator to vehicle: must arrive, must not act late."""
    EMERGENCY = "emergency"
    """An emergency stop: must arrive, however late; never dropped for its age."""
    PRODUCT = "product"
    """Data products (image metadata): every one must reach every reader, even late ones."""
    BULK = "bulk"
    """Chunks of large files: reliable, in order, not kept for late joiners."""


@dataclass(frozen=True, slots=True)
class TopicSpec:
    """One DDS topic: ``name``, the IdlStruct ``type`` it carries, and its ``kind``.

    ``owner`` names who registered it (``"edge_vis"`` or a translator plugin) for conflict
    messages.
    """

    name: str
    type: type[IdlStruct]
    kind: TopicKind
    owner: str = "edge_vis"

    def __post_init__(self) -> None:
        if not self.name or not self.name.replace("_", "").replace("/", "").isalnum():
            raise ValueError(f"topic name {self.name!r} must be letters, digits, '_' or '/'")
        if not (isinstance(self.type, type) and issubclass(self.type, IdlStruct)):
            raise TypeError(f"topic {self.name}: type {self.type!r} is not an IdlStruct")
        if not isinstance(self.kind, TopicKind):
            raise TypeError(f"topic {self.name}: kind {self.kind!r} is not a TopicKind")

    @property
    def inbound(self) -> bool:
        """True for topics the relay reads (commands from operators)."""
        return self.kind is TopicKind.COMMAND or self.kind is TopicKind.EMERGENCY

    @property
    def typename(self) -> str:
        """The IDL type name (``edge_vis::GlobalPose``)."""
        return str(self.type.__idl_typename__)


_STANDARD_KINDS: dict[type[IdlStruct], TopicKind] = {
    model.VehicleIdentification: TopicKind.STATE,
    model.VehicleStatus: TopicKind.STATE,
    model.GlobalPose: TopicKind.TELEMETRY,
    model.LocalPose: TopicKind.TELEMETRY,
    model.Velocity: TopicKind.TELEMETRY,
    model.ControlRequest: TopicKind.COMMAND,
    model.ControlStatus: TopicKind.STATE,
    model.EmergencyCommand: TopicKind.EMERGENCY,
    model.WrenchEffortCommand: TopicKind.COMMAND,
    model.VelocityCommand: TopicKind.COMMAND,
    model.WaypointPlan: TopicKind.COMMAND,
    model.MissionStatus: TopicKind.STATE,
    model.VehiclePlan: TopicKind.STATE,
    model.PlanQuery: TopicKind.COMMAND,
    model.PathSegmentPlan: TopicKind.COMMAND,
    model.MissionSpoolCommand: TopicKind.COMMAND,
    model.SpoolerStatus: TopicKind.STATE,
    model.SpoolerMissions: TopicKind.STATE,
    model.LinkStatus: TopicKind.STATE,
    model.RelayStatus: TopicKind.STATE,
    model.HealthStatus: TopicKind.STATE,
    model.RangeScan: TopicKind.TELEMETRY,
    model.SensorInfo: TopicKind.STATE,
    model.SensorState: TopicKind.STATE,
    model.SensorCommand: TopicKind.COMMAND,
    model.HmiInput: TopicKind.STATE,
    model.ImageProduct: TopicKind.PRODUCT,
    model.ImageData: TopicKind.BULK,
    model.TransferStatus: TopicKind.STATE,
    model.EnvironmentalData: TopicKind.TELEMETRY,
    model.AccelerationState: TopicKind.TELEMETRY,
    model.JointState: TopicKind.TELEMETRY,
    model.JointSpecification: TopicKind.STATE,
    model.EndEffectorPose: TopicKind.TELEMETRY,
    model.EndEffectorVelocity: TopicKind.TELEMETRY,
    model.Odometry: TopicKind.TELEMETRY,
    model.PlatformSpecifications: TopicKind.STATE,
    model.PowerPlantStatus: TopicKind.STATE,
    model.DeviceStatus: TopicKind.STATE,
    model.PlatformStatus: TopicKind.STATE,
    model.DigitalResource: TopicKind.STATE,
    model.PathReport: TopicKind.TELEMETRY,
    model.MeasurementReport: TopicKind.TELEMETRY,
    model.GenericReport: TopicKind.TELEMETRY,
    model.JointCommand: TopicKind.COMMAND,
    model.EndEffectorCommand: TopicKind.COMMAND,
    model.ManipulatorPlan: TopicKind.COMMAND,
    model.ManipulatorPlanStatus: TopicKind.STATE,
    model.ManipulatorList: TopicKind.STATE,
    model.DeviceCommand: TopicKind.COMMAND,
    model.PlatformCommand: TopicKind.COMMAND,
    model.HandoffRequest: TopicKind.COMMAND,
    model.HandoffResponse: TopicKind.COMMAND,
    model.HandoffStatus: TopicKind.STATE,
    model.CostMap: TopicKind.TELEMETRY,
    model.CostMapRequest: TopicKind.COMMAND,
    model.NoGoZones: TopicKind.STATE,
    model.NoGoZoneCommand: TopicKind.COMMAND,
    model.RequestResult: TopicKind.STATE,
    model.DigitalResourceCommand: TopicKind.COMMAND,
    model.CbrnStatus: TopicKind.STATE,
    model.CbrnDetection: TopicKind.STATE,
    model.CbrnCommand: TopicKind.COMMAND,
    model.SkidSteerCommand: TopicKind.COMMAND,
    model.AckermannCommand: TopicKind.COMMAND,
    model.DeviceCapabilities: TopicKind.STATE,
    model.WrenchEffortState: TopicKind.TELEMETRY,
    model.VelocityCommandState: TopicKind.STATE,
    model.VectorState: TopicKind.STATE,
    model.VectorCommand: TopicKind.COMMAND,
    model.AccelerationLimit: TopicKind.STATE,
    model.AccelerationLimitCommand: TopicKind.COMMAND,
    model.GeomagneticProperty: TopicKind.STATE,
    model.PoseCommand: TopicKind.COMMAND,
    model.ManagementCommand: TopicKind.COMMAND,
    model.VehicleClock: TopicKind.STATE,
}


def standard_topics() -> tuple[TopicSpec, ...]:
    """The topics of the shipped model; each is named after its type (``GlobalPose``)."""
    return tuple(
        TopicSpec(struct.__name__, struct, _STANDARD_KINDS[struct]) for struct in model.STRUCTS
    )


class TopicRegistry:
    """Topic name -> :class:`TopicSpec`; built at start-up, read-only while running."""

    def __init__(self, specs: Iterable[TopicSpec] = ()) -> None:
        self._specs: dict[str, TopicSpec] = {}
        self._typenames: dict[str, TopicSpec] = {}
        for spec in specs:
            self.register(spec)

    @classmethod
    def standard(cls) -> TopicRegistry:
        """A registry holding the shipped model's topics."""
        return cls(standard_topics())

    def register(self, spec: TopicSpec) -> TopicSpec:
        """Add ``spec``; return the registered spec.

        Raises :class:`PluginConflictError` if the name is taken by another type or kind,
        or if another type already uses the same IDL type name (DDS would see two
        incompatible types under one name).
        """
        known = self._specs.get(spec.name)
        if known is not None:
            if known.type is spec.type and known.kind is spec.kind:
                return known
            raise PluginConflictError(
                f"topic {spec.name!r} registered by {spec.owner!r} as "
                f"{spec.typename} ({spec.kind.value}) is already registered by "
                f"{known.owner!r} as {known.typename} ({known.kind.value})"
            )
        same_typename = self._typenames.get(spec.typename)
        if same_typename is not None and same_typename.type is not spec.type:
            raise PluginConflictError(
                f"topic {spec.name!r} registered by {spec.owner!r} uses IDL type "
                f"{spec.typename}, which {same_typename.owner!r} already defines differently "
                f"for topic {same_typename.name!r}"
            )
        self._specs[spec.name] = spec
        self._typenames.setdefault(spec.typename, spec)
        return spec

    def register_all(self, specs: Iterable[Any], owner: str | None = None) -> None:
        """Register every topic of one plugin, stamped with ``owner`` if given: a
        :class:`TopicSpec`, or a translator's :class:`~edge_vis.kit.TopicDecl` naming a
        type of the data model."""
        for spec in specs:
            if not isinstance(spec, TopicSpec):
                spec = from_declaration(spec)
            self.register(spec if owner is None else dataclasses.replace(spec, owner=owner))

    def get(self, name: str) -> TopicSpec:
        """The spec of topic ``name``; ``KeyError`` listing the known topics otherwise."""
        try:
            return self._specs[name]
        except KeyError:
            raise KeyError(
                f"unknown DDS topic {name!r}; known: {', '.join(sorted(self._specs))}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self._specs

    def __iter__(self) -> Iterator[TopicSpec]:
        return iter(self._specs.values())

    def __len__(self) -> int:
        return len(self._specs)

    def names(self, kind: TopicKind | None = None) -> list[str]:
        """Topic names, optionally only those of one kind, in registration order."""
        return [s.name for s in self._specs.values() if kind is None or s.kind is kind]

    def inbound(self) -> list[str]:
        """Names of the topics the relay subscribes to (commands)."""
        return [s.name for s in self._specs.values() if s.inbound]


def from_declaration(decl: Any) -> TopicSpec:
    """The :class:`TopicSpec` of a translator's topic declaration (``name``,
    ``type_name`` of :mod:`edge_vis.dds.model`, ``kind``), or of a type built at run time
    from its ``shape`` (:mod:`edge_vis.dds.runtime_types`); ValueError names what is wrong."""
    shape = getattr(decl, "shape", None)
    cls = struct_type(shape) if shape is not None else \
        getattr(model, str(getattr(decl, "type_name", "")), None)
    if not (isinstance(cls, type) and issubclass(cls, IdlStruct)):
        raise ValueError(f"topic {getattr(decl, 'name', decl)!r}: "
                         f"{getattr(decl, 'type_name', None)!r} is not a type of the data model")
    try:
        kind = TopicKind(decl.kind)
    except ValueError:
        raise ValueError(f"topic {decl.name!r}: kind {decl.kind!r} is not one of "
                         f"{', '.join(k.value for k in TopicKind)}") from None
    return TopicSpec(decl.name, cls, kind)
