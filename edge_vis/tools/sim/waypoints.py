"""The List Manager and Global Waypoint List Driver of a simulated vehicle. No I/O.

Elements are a doubly linked list keyed by UID (AS5710A List Manager): each SetElement
record names its previous and next UIDs, 0 meaning none. A request is applied whole or
refused whole with the JSIDL response code. Element data must be a SetGlobalWaypoint or
a SetGlobalPathSegment message (the Global Path Segment Driver's list, driven straight to
each segment's end point); the driver steers the kinematic model to each waypoint in turn
at the travel speed given by ExecuteList and reports the active element (0 when none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from edge_vis.tools.sim.kinematics import Motion, Origin, clamp, wrap_angle

INVALID_ID = 1
INVALID_PREVIOUS = 2
INVALID_NEXT = 3
UNSUPPORTED_TYPE = 4
NOT_FOUND = 5
OUT_OF_MEMORY = 6
UNSPECIFIED = 7

MAX_ELEMENTS = 1000
ALL_ELEMENTS = 0xFFFF
DEFAULT_TOLERANCE = 1.0
SET_GLOBAL_WAYPOINT = 0x040C
SET_GLOBAL_PATH_SEGMENT = 0x040F


def target_of(code: int, fields: dict[str, Any]) -> dict[str, Any] | None:
    """The waypoint an element drives to: a SetGlobalWaypoint's, or a SetGlobalPathSegment's
    end point P2 (the sim drives straight to it; the segment is kept under ``segment``);
    None for any other message."""
    if code == SET_GLOBAL_WAYPOINT:
        return dict(fields)
    if code == SET_GLOBAL_PATH_SEGMENT:
        target = {"latitude": fields["p2_latitude"], "longitude": fields["p2_longitude"],
                  "segment": dict(fields)}
        if "path_tolerance" in fields:
            target["waypoint_tolerance"] = min(100.0, fields["path_tolerance"])
        return target
    return None


@dataclass(slots=True)
class Element:
    """One list element and the waypoint it carries."""

    uid: int
    previous: int
    next: int
    data: dict[str, Any]
    waypoint: dict[str, Any]


class WaypointList:
    """Elements plus execution state."""

    def __init__(self) -> None:
        self.elements: dict[int, Element] = {}
        self.active = 0
        self.travel_speed = 0.0
        self.executing = False
        self.reached: list[int] = []

    # -- list manager ---------------------------------------------------------------------

    def set_elements(self, records: list[dict[str, Any]],
                     waypoints: list[dict[str, Any] | None]) -> int:
        """Insert or replace elements; 0 on success, else a RejectElementRequest code.

        ``waypoints[i]`` is the decoded SetGlobalWaypoint of ``records[i]`` or None when
        the element data is not one.
        """
        staged = dict(self.elements)
        for rec, waypoint in zip(records, waypoints, strict=True):
            uid = rec["element_uid"]
            if uid in (0, ALL_ELEMENTS):
                return INVALID_ID
            if waypoint is None:
                return UNSUPPORTED_TYPE
            staged[uid] = Element(uid, rec["previous_uid"], rec["next_uid"],
                                  dict(rec["element_data"]), waypoint)
        if len(staged) > MAX_ELEMENTS:
            return OUT_OF_MEMORY
        for rec in records:
            elem = staged[rec["element_uid"]]
            if elem.previous and (elem.previous not in staged or elem.previous == elem.uid):
                return INVALID_PREVIOUS
            if elem.next and (elem.next not in staged or elem.next == elem.uid):
                return INVALID_NEXT
        for rec in records:  # link the neighbours to the new elements
            elem = staged[rec["element_uid"]]
            if elem.previous:
                staged[elem.previous].next = elem.uid
            if elem.next:
                staged[elem.next].previous = elem.uid
        self.elements = staged
        return 0

    def delete(self, uids: list[int]) -> int:
        """Delete elements (65535 = all); 0 on success, else a response code."""
        if ALL_ELEMENTS in uids:
            if self.executing:
                return UNSPECIFIED
            self.elements.clear()
            return 0
        for uid in uids:
            if uid not in self.elements:
                return NOT_FOUND
            if self.executing and uid == self.active:
                return UNSPECIFIED
        for uid in uids:
            elem = self.elements.pop(uid)
            if elem.previous in self.elements:
                self.elements[elem.previous].next = elem.next
            if elem.next in self.elements:
                self.elements[elem.next].previous = elem.previous
        return 0

    def order(self) -> list[int]:
        """UIDs from the head of the list (previous 0) following the next links."""
        heads = [e.uid for e in self.elements.values() if e.previous == 0]
        out: list[int] = []
        seen: set[int] = set()
        for head in sorted(heads):
            uid = head
            while uid and uid in self.elements and uid not in seen:
                seen.add(uid)
                out.append(uid)
                uid = self.elements[uid].next
        out += sorted(uid for uid in self.elements if uid not in seen)
        return out

    # -- driver ---------------------------------------------------------------------------

    def execute(self, speed: float, start: int | None) -> bool:
        """Start driving the list at ``start`` (or its head); False if there is nothing."""
        order = self.order()
        if not order or (start is not None and start not in self.elements):
            return False
        self.active = start if start is not None else order[0]
        self.travel_speed = speed
        self.executing = speed > 0
        self.reached = []
        return True

    def stop(self) -> None:
        """Stop executing (manual override, control lost, emergency)."""
        self.executing = False
        self.active = 0

    def clear(self) -> None:
        """Forget everything (a reboot)."""
        self.__init__()  # type: ignore[misc]

    def steer(self, motion: Motion, origin: Origin) -> None:
        """Command ``motion`` towards the active waypoint; advance when it is reached."""
        if not self.executing:
            return
        while True:
            elem = self.elements.get(self.active)
            if elem is None:
                self.stop()
                motion.stop()
                return
            wp = elem.waypoint
            tx, ty = origin.to_local(wp["latitude"], wp["longitude"])
            dx, dy = tx - motion.x, ty - motion.y
            tolerance = max(0.5, wp.get("waypoint_tolerance", DEFAULT_TOLERANCE) or 0.5)
            if math.hypot(dx, dy) > tolerance:
                break
            self.reached.append(elem.uid)
            if not elem.next or elem.next not in self.elements:
                self.executing = False
                self.active = 0
                motion.stop()
                return
            self.active = elem.next
        error = wrap_angle(math.atan2(dy, dx) - motion.yaw)
        yaw_rate = clamp(2.0 * error, -motion.max_yaw_rate, motion.max_yaw_rate)
        distance = math.hypot(dx, dy)
        speed = min(self.travel_speed, motion.max_speed, 0.8 * distance + 0.2)
        motion.command(speed * max(0.0, math.cos(error)), yaw_rate)
