"""The Local Path Segment Driver of a simulated vehicle. No I/O.

Its list is the platform's one List Manager list (one component, one List Manager: the
waypoint list and global path segment drivers share it). A SetLocalPathSegment element is
given in the local frame its Local Pose Sensor reports (x north, y east, metres from the
vehicle's origin); the sim drives straight to its end point P2 (placed on the map when the
element is set, so the driver steers to it like any other) and reports the segment back
(QueryLocalPathSegment) while it is the active element.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from edge_vis.tools.sim.kinematics import Origin

if TYPE_CHECKING:
    from edge_vis.tools.sim.subsystem import Component, SimVehicle

SET_LOCAL_PATH_SEGMENT = 0x0410
#: where an element's target keeps the local segment it came from
KEY = "local_segment"


def target_of(code: int, fields: dict[str, Any], origin: Origin) -> dict[str, Any] | None:
    """The point a SetLocalPathSegment element drives to (its P2, on the map), the segment
    kept under :data:`KEY`; None for any other message."""
    if code != SET_LOCAL_PATH_SEGMENT:
        return None
    latitude, longitude = origin.to_geodetic(fields["p2_x"], fields["p2_y"])
    target: dict[str, Any] = {"latitude": latitude, "longitude": longitude,
                              KEY: dict(fields)}
    if "path_tolerance" in fields:
        target["waypoint_tolerance"] = min(100.0, fields["path_tolerance"])
    return target


def report(vehicle: SimVehicle, comp: Component, fields: dict[str, Any]) -> dict[str, Any] | None:
    """ReportLocalPathSegment: the active element's local segment (nothing when the active
    element is not one)."""
    elem = vehicle.waypoints.elements.get(vehicle.waypoints.active)
    segment = elem.waypoint.get(KEY) if elem is not None else None
    return dict(segment) if segment is not None else None
