"""Which components a simulated vehicle has and which services each one offers. No I/O.

A UGV is laid out the way many real robots are: a node manager component holding
Discovery and Liveness, a platform component with Management, Time, the pose/velocity sensors
and both drivers, and a sensor component with the range sensor and the camera. The UUV
has one component and no Discovery at all - it announces itself with a vendor message.
"""

from __future__ import annotations

from dataclasses import dataclass

from edge_vis.jaus.address import JausAddress

CORE = "urn:jaus:jss:core:"
MOBILITY = "urn:jaus:jss:mobility:"
ENV = "urn:jaus:jss:environmentSensing:"
UUV = "urn:edge-vis:uuv:"

TRANSPORT = CORE + "Transport"
EVENTS = CORE + "Events"
ACCESS_CONTROL = CORE + "AccessControl"
MANAGEMENT = CORE + "Management"
LIVENESS = CORE + "Liveness"
DISCOVERY = CORE + "Discovery"
LIST_MANAGER = CORE + "ListManager"
TIME = CORE + "Time"
GLOBAL_POSE = MOBILITY + "GlobalPoseSensor"
LOCAL_POSE = MOBILITY + "LocalPoseSensor"
VELOCITY_STATE = MOBILITY + "VelocityStateSensor"
PRIMITIVE_DRIVER = MOBILITY + "PrimitiveDriver"
WAYPOINT_LIST_DRIVER = MOBILITY + "GlobalWaypointListDriver"
PATH_SEGMENT_DRIVER = MOBILITY + "GlobalPathSegmentDriver"
LOCAL_PATH_SEGMENT_DRIVER = MOBILITY + "LocalPathSegmentDriver"
MISSION_SPOOLER = "urn:jaus:jss:missionSpooler:MissionSpooler"
RANGE_SENSOR = ENV + "RangeSensor"
VISUAL_SENSOR = ENV + "VisualSensor"
STILL_IMAGE = ENV + "StillImage"
DIGITAL_VIDEO = ENV + "DigitalVideo"
VENDOR_DISCOVERY = UUV + "VendorDiscovery"
OCEAN_ENVIRONMENT = UUV + "OceanEnvironmentSensor"
ATR_NOTIFIER = UUV + "AtrImageNotifier"


def version_of(uri: str, version: tuple[int, int] | None = None) -> tuple[int, int]:
    """(major, minor) version of a service URI as the vehicle reports it (``version``: its
    component's, for any but core services)."""
    return (1, 1) if uri.startswith(CORE) else version or (1, 0)


@dataclass(frozen=True, slots=True)
class ComponentSpec:
    """One JAUS component of a vehicle."""

    component: int
    name: str
    services: tuple[str, ...]
    #: the version of its services other than core ones (default 1.0)
    version: tuple[int, int] | None = None
    #: services it does not report but whose messages its services answer (an older
    #: version's services answering what a newer version gave services of their own)
    answers: tuple[str, ...] = ()


UGV_LAYOUT: tuple[ComponentSpec, ...] = (
    ComponentSpec(1, "NodeManager", (TRANSPORT, EVENTS, DISCOVERY, LIVENESS)),
    ComponentSpec(2, "Platform", (
        TRANSPORT, EVENTS, ACCESS_CONTROL, MANAGEMENT, LIVENESS, TIME, GLOBAL_POSE,
        LOCAL_POSE, VELOCITY_STATE, PRIMITIVE_DRIVER, LIST_MANAGER, WAYPOINT_LIST_DRIVER,
        PATH_SEGMENT_DRIVER, LOCAL_PATH_SEGMENT_DRIVER, MISSION_SPOOLER,
    )),
    ComponentSpec(3, "Sensors", (
        TRANSPORT, EVENTS, ACCESS_CONTROL, RANGE_SENSOR, VISUAL_SENSOR, STILL_IMAGE,
        DIGITAL_VIDEO,
    )),
)

UUV_LAYOUT: tuple[ComponentSpec, ...] = (
    ComponentSpec(1, "Vehicle", (
        TRANSPORT, EVENTS, ACCESS_CONTROL, MANAGEMENT, LIVENESS, GLOBAL_POSE, VELOCITY_STATE,
        PRIMITIVE_DRIVER, VENDOR_DISCOVERY, OCEAN_ENVIRONMENT, ATR_NOTIFIER,
    )),
)


def layout(kind: str) -> tuple[ComponentSpec, ...]:
    """The components of a vehicle of ``kind`` (``ugv`` or ``uuv``)."""
    return UUV_LAYOUT if kind == "uuv" else UGV_LAYOUT


def address(subsystem: int, node: int, spec: ComponentSpec) -> JausAddress:
    """The JAUS address of a component."""
    return JausAddress(subsystem, node, spec.component)
