"""The operator's live view of the fleet, built from DDS samples only. No I/O.

:class:`FleetView` takes ``(topic, sample dict, now)`` as a DDS subscriber receives them
and keeps one :class:`VehicleRow` per vehicle: identity, state, position, speed, who holds
control, how fast its telemetry arrives, its last image - plus the relay's links and a
count of samples per topic. :meth:`FleetView.render` lays that out for an 80x24 terminal
(curses or plain text); :meth:`FleetView.summary` gives the figures a demo run reports.

:class:`Operator` turns key presses into command samples (control requests, wrench
efforts, a short waypoint plan) for the monitor to publish; it holds no socket either.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

#: topics the monitor reads (all published by the relay)
READ_TOPICS: tuple[str, ...] = (
    "VehicleIdentification", "VehicleStatus", "GlobalPose", "LocalPose", "Velocity",
    "ControlStatus", "MissionStatus", "LinkStatus", "RangeScan", "ImageProduct",
    "EnvironmentalData", "TransferStatus", "VehicleClock",
    "VehiclePlan", "SpoolerStatus",
    "SensorState",
    "HandoffStatus",
)
#: manipulators and pan-tilts: joint positions, labelled with the names their
#: specifications give (joint i when a vehicle names none, as manipulator v1.0 does)
READ_TOPICS += ("JointState", "JointSpecification")
#: command topics the monitor writes
WRITE_TOPICS: tuple[str, ...] = ("ControlRequest", "WrenchEffortCommand", "WaypointPlan",
                                 "EmergencyCommand", "HandoffRequest", "HandoffResponse")
#: topics counted as telemetry in a vehicle's rate column
TELEMETRY = frozenset({"GlobalPose", "LocalPose", "Velocity", "RangeScan",
                       "EnvironmentalData"})

EARTH_RADIUS = 6_371_000.0


class RateMeter:
    """Samples per second over a sliding window."""

    def __init__(self, window: float = 5.0) -> None:
        self.window = window
        self._times: deque[float] = deque()

    def add(self, now: float) -> None:
        self._times.append(now)
        self._trim(now)

    def _trim(self, now: float) -> None:
        while self._times and now - self._times[0] > self.window:
            self._times.popleft()

    def rate(self, now: float) -> float:
        """Samples per second over the last window (0 when none)."""
        self._trim(now)
        if not self._times:
            return 0.0
        span = max(now - self._times[0], self.window / 2)
        return len(self._times) / span


@dataclass
class VehicleRow:
    """What the operator sees of one vehicle."""

    vehicle_id: str
    name: str = ""
    vehicle_type: str = ""
    jaus_address: str = ""
    link: str = ""
    state: str = "UNKNOWN"
    online: bool = False
    latitude: float | None = None
    longitude: float | None = None
    yaw: float | None = None
    speed: float | None = None
    depth: float | None = None
    control: str = "NOT_CONTROLLED"
    controller: str = ""
    authority: int = 0
    #: per component: (component, controller or "", its authority, is this relay)
    holders: list[tuple[str, str, int, bool]] = field(default_factory=list)
    #: the vehicle's clock minus the relay's, seconds (None: not read)
    clock_offset: float | None = None
    mission: str = ""
    active_waypoint: int = -1
    #: the plan the vehicle holds (elements read back / listed) and its spooler's mission
    plan: str = ""
    spooler: str = ""
    last_image: str = ""
    last_image_size: int = 0
    images: int = 0
    went_offline: int = 0
    recovered: int = 0
    emergency: bool = False
    emergency_operator: str = ""
    emergency_reason: str = ""
    last_rejection: str = ""
    #: the relay serving it (VehicleStatus.relay), and how often that changed
    relay: str = ""
    relay_changes: int = 0
    #: camera (sensor id) -> its video stream state as last asked for (PLAY, PAUSE, STOP)
    streams: dict[int, str] = field(default_factory=dict)
    #: hand-off requests: (request id, requester, authority, state, explanation)
    handoffs: list[tuple[int, str, int, str, str]] = field(default_factory=list)
    samples: Counter[str] = field(default_factory=Counter)
    rates: dict[str, RateMeter] = field(default_factory=dict)
    last_seen: float = 0.0
    #: per device (manipulator, pan_tilt): joint names, and (value, unit) per joint
    joint_names: dict[str, list[str]] = field(default_factory=dict)
    joints: dict[str, list[tuple[float, str]]] = field(default_factory=dict)

    def rate(self, now: float, topics: Iterable[str] = TELEMETRY) -> float:
        """Telemetry samples per second for this vehicle."""
        return sum(m.rate(now) for t, m in self.rates.items() if t in topics)


class FleetView:
    """Everything the monitor knows, from DDS samples; see the module docstring."""

    def __init__(self, window: float = 5.0) -> None:
        self.window = window
        self.vehicles: dict[str, VehicleRow] = {}
        self.links: dict[str, dict[str, Any]] = {}
        self.samples: Counter[str] = Counter()
        self.started: float | None = None

    def row(self, vehicle_id: str) -> VehicleRow:
        """The row of ``vehicle_id`` (created on first mention)."""
        row = self.vehicles.get(vehicle_id)
        if row is None:
            row = self.vehicles[vehicle_id] = VehicleRow(vehicle_id)
        return row

    def ingest(self, topic: str, sample: Mapping[str, Any], now: float) -> None:
        """Take one sample of ``topic``."""
        if self.started is None:
            self.started = now
        self.samples[topic] += 1
        if topic == "LinkStatus":  # one row per relay and link
            relay = str(sample.get("relay", "") or "")
            link = str(sample.get("link", ""))
            self.links[f"{link}@{relay}" if relay else link] = dict(sample)
            return
        vehicle_id = str(sample.get("vehicle_id", ""))
        if not vehicle_id:
            return
        row = self.row(vehicle_id)
        row.samples[topic] += 1
        row.rates.setdefault(topic, RateMeter(self.window)).add(now)
        row.last_seen = now
        handler = getattr(self, f"_on_{topic}", None)
        if handler is not None:
            handler(row, sample)

    # -- per-topic updates ----------------------------------------------------------------

    def _on_VehicleIdentification(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.name = s.get("name", "") or row.name
        row.vehicle_type = s.get("vehicle_type", "") or row.vehicle_type
        row.jaus_address = s.get("jaus_address", "") or row.jaus_address

    def _on_VehicleStatus(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        online = bool(s.get("online", False)) and s.get("state") != "OFFLINE"
        if row.online and not online:
            row.went_offline += 1
        elif online and not row.online and row.went_offline > row.recovered:
            row.recovered += 1
        row.online = online
        row.state = str(s.get("state", row.state))
        row.link = s.get("link", "") or row.link
        row.emergency = bool(s.get("emergency", False))
        row.emergency_operator = s.get("emergency_operator", "") or ""
        row.emergency_reason = s.get("emergency_reason", "") or ""
        relay = s.get("relay", "") or ""
        if relay and row.relay and relay != row.relay:
            row.relay_changes += 1
        row.relay = relay or row.relay

    def _on_GlobalPose(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.latitude, row.longitude = s.get("latitude"), s.get("longitude")
        row.yaw = s.get("yaw", row.yaw)
        altitude = s.get("altitude")
        if altitude is not None and altitude < -0.5:
            row.depth = -altitude

    def _on_Velocity(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.speed = math.hypot(s.get("vx", 0.0) or 0.0, s.get("vy", 0.0) or 0.0)

    def _on_ControlStatus(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.control = str(s.get("state", row.control))
        row.controller = s.get("operator_id", "") or ""
        row.authority = int(s.get("authority", 0) or 0)
        row.emergency = bool(s.get("emergency", row.emergency))
        row.last_rejection = s.get("last_rejection", "") or ""
        row.holders = [(str(h.get("component", "")), str(h.get("controller", "") or ""),
                        int(h.get("authority", 0) or 0), bool(h.get("is_relay", False)))
                       for h in s.get("holders", None) or []]

    def _on_HandoffStatus(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.handoffs = [(int(r.get("request_id", 0)), str(r.get("requester", "")),
                         int(r.get("authority", 0) or 0), str(r.get("state", "")),
                         str(r.get("explanation", "") or ""))
                        for r in s.get("requests", None) or []]

    def _on_VehicleClock(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        offset = s.get("offset_ms")
        row.clock_offset = offset / 1000.0 if isinstance(offset, int | float) and not (
            math.isnan(offset)) else None

    def _on_MissionStatus(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.mission = str(s.get("state", "")).removeprefix("MISSION_")
        row.active_waypoint = int(s.get("active_waypoint", -1))

    def _on_VehiclePlan(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        elements = s.get("elements") or []
        kinds = {"waypoints" if "Waypoint" in m else "segments" if "PathSegment" in m
                 else "elements" for e in elements if (m := str(e.get("message", "")))}
        what = kinds.pop() if len(kinds) == 1 else "elements"
        count = int(s.get("element_count", -1))
        held = f"{len(elements)}/{count}" if count >= 0 and not s.get("complete") \
            else str(len(elements))
        row.plan = f"{held} {what}" if elements or count > 0 else "empty"

    def _on_SpoolerStatus(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        if s.get("scope") == "MISSION":
            row.spooler = f"{s.get('id', 0)} {str(s.get('status', '')).lower()}"

    def _on_ImageProduct(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.images += 1
        row.last_image = s.get("file_name", "") or str(s.get("image_id", ""))
        row.last_image_size = int(s.get("size_bytes", 0) or 0)

    def _on_SensorState(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        if s.get("stream"):
            row.streams[int(s.get("sensor_id", 0) or 0)] = str(s["stream"])

    def _on_EnvironmentalData(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        if s.get("depth") is not None:
            row.depth = s["depth"]

    def _on_JointSpecification(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        row.joint_names[str(s.get("device", ""))] = [str(n) for n in s.get("names") or ()]

    def _on_JointState(self, row: VehicleRow, s: Mapping[str, Any]) -> None:
        if s.get("quantity") == "position":
            units = list(s.get("units") or ())
            row.joints[str(s.get("device", ""))] = [
                (float(v), units[i] if i < len(units) else "")
                for i, v in enumerate(s.get("values") or ())]

    # -- output ---------------------------------------------------------------------------

    def ordered(self) -> list[VehicleRow]:
        """Rows sorted by vehicle id."""
        return [self.vehicles[k] for k in sorted(self.vehicles)]

    def render(self, now: float, width: int = 80, selected: str | None = None) -> list[str]:
        """Lines of text for a terminal ``width`` columns wide (at least 80).

        Vehicle rows fit 79 columns, so curses can draw them whole on an 80-column screen:
        ``HDG`` is the heading in degrees from north, ``M/S`` the speed, ``HZ`` telemetry
        samples per second. Link rows give the measured use and the budget in kbit/s.
        """
        width = max(width, 80)
        head = (f" {'VEHICLE':<14}{'TYPE':<8}{'STATE':<10}{'POSITION':<20}{'HDG':>4}{'M/S':>5} "
                f"{'CONTROL':<12}{'HZ':>4}")
        lines = [head[:width]]
        for row in self.ordered():
            mark = ">" if row.vehicle_id == selected else " "
            state = row.state if row.online else "OFFLINE"
            if row.emergency:
                state = "!E-STOP!"
            if row.latitude is not None and row.longitude is not None:
                pos = f"{row.latitude:9.5f},{row.longitude:10.5f}"
            else:
                pos = "-"
            heading = f"{math.degrees(row.yaw) % 360:4.0f}" if row.yaw is not None else "   -"
            speed = f"{row.speed:5.1f}" if row.speed is not None else "    -"
            control = {"CONTROLLED": row.controller or "relay", "NOT_CONTROLLED": "-"}.get(
                row.control, row.control.lower())
            line = (f"{mark}{row.vehicle_id[:13]:<14}{row.vehicle_type[:7]:<8}"
                    f"{state[:9]:<10}{pos:<20}{heading}{speed} {control[:11]:<12}"
                    f"{row.rate(now):4.1f}")
            lines.append(line[:width])
            if row.emergency:
                who = f" set by {row.emergency_operator}" if row.emergency_operator else ""
                why = f": {row.emergency_reason}" if row.emergency_reason else ""
                lines.append(f"   *** EMERGENCY STOP{who}{why} ***"[:width])
            extra = []
            if row.jaus_address:
                extra.append(f"jaus {row.jaus_address}")
            if row.relay:
                moved = f" (taken over {row.relay_changes}x)" if row.relay_changes else ""
                extra.append(f"relay {row.relay}{moved}")
            if row.link:
                extra.append(f"link {row.link}")
            if row.depth is not None:
                extra.append(f"depth {row.depth:.1f} m")
            if row.mission and row.mission != "IDLE":
                waypoint = f" wp {row.active_waypoint}" if row.active_waypoint >= 0 else ""
                extra.append(f"mission {row.mission.lower()}{waypoint}")
            if row.plan:
                extra.append(f"holds {row.plan}")
            if row.spooler:
                extra.append(f"spooled mission {row.spooler}")
            if row.last_image:
                size = f" ({row.last_image_size // 1024} KiB)" if row.last_image_size else ""
                extra.append(f"image {row.last_image}{size}")
            if row.streams:
                extra.append("camera " + " ".join(f"{sensor}:{state.lower()}" for sensor, state
                                                  in sorted(row.streams.items())))
            if row.went_offline:
                extra.append(f"dropouts {row.went_offline} recovered {row.recovered}")
            held = [f"{c} by {'relay' if relay else who}({authority})"
                    for c, who, authority, relay in row.holders if who]
            if held:
                extra.append("held " + " ".join(held))
            if row.clock_offset is not None:
                extra.append(f"clock {row.clock_offset:+.2f} s")
            if extra:
                lines.append(("   " + ", ".join(extra))[:width])
            lines += [line[:width] for line in _joint_lines(row)]
            for request_id, requester, authority, state, why in row.handoffs:
                if state in ("PENDING", "DEFERRED"):
                    reason = f" '{why}'" if why else ""
                    lines.append((f"   HAND-OFF #{request_id} to {requester} ({authority})"
                                  f"{reason} {state.lower()}: a = grant, n = refuse")[:width])
        if not self.vehicles:
            lines.append(" (no vehicle seen yet)")
        if self.links:
            lines.append("")
            lines.append((f"{'LINK':<10}{'UP':<4}{'USE kb/s':>9}{'BUDGET kb/s':>12}{'LOAD':>6} "
                          f"{'IN/OUT msgs':>14}{'QUEUE':>7}{'DROPS':>7} RELAY")[:width])
            for key in sorted(self.links):
                link = self.links[key]
                name = str(link.get("link", key))
                budget = float(link.get("budget_bps", 0.0) or 0.0)
                measured = float(link.get("measured_bps", 0.0) or 0.0)
                load = f"{100 * measured / budget:5.1f}%" if budget > 0 else "-"
                budget_text = f"{budget / 1000:.1f}" if budget > 0 else "unlimited"
                drops = sum(int(d.get("count", 0)) for d in link.get("drops", []) or [])
                msgs = f"{link.get('messages_in', 0)}/{link.get('messages_out', 0)}"
                queue = int(link.get("queue_depth", 0) or 0)
                lines.append((f"{name[:9]:<10}{'yes' if link.get('up') else 'NO':<4}"
                              f"{measured / 1000:9.1f}{budget_text:>12}{load:>6} {msgs:>14}"
                              f"{queue:>7}{drops:>7} {link.get('relay', '') or ''}")[:width])
        return lines

    def summary(self) -> dict[str, Any]:
        """Figures for a demo run: vehicles seen, samples per topic, faults recovered."""
        return {
            "vehicles": {row.vehicle_id: {
                "name": row.name, "type": row.vehicle_type, "state": row.state,
                "online": row.online, "emergency": row.emergency,
                "samples": sum(row.samples.values()),
                "images": row.images, "dropouts": row.went_offline,
                "recovered": row.recovered} for row in self.ordered()},
            "samples_per_topic": dict(sorted(self.samples.items())),
            "faults_recovered": sum(row.recovered for row in self.vehicles.values()),
        }


def _joint_lines(row: VehicleRow) -> list[str]:
    """One line per device with joints: each joint's name (or number) and position."""
    out = []
    for device, joints in sorted(row.joints.items()):
        names = row.joint_names.get(device, [])
        shown = [f"{names[i] if i < len(names) and names[i] else f'j{i + 1}'} "
                 f"{value:.2f}{' ' + unit if unit else ''}"
                 for i, (value, unit) in enumerate(joints)]
        out.append(f"   {device.replace('_', '-')}: " + ", ".join(shown))
    return out


# -- operator commands --------------------------------------------------------------------


def control_request(vehicle_id: str, operator_id: str, authority: int,
                    release: bool = False) -> dict[str, Any]:
    """A ControlRequest sample."""
    return {"vehicle_id": vehicle_id, "operator_id": operator_id,
            "action": "RELEASE" if release else "REQUEST", "authority": authority}


def emergency_command(vehicle_id: str, operator_id: str, authority: int, *,
                      clear: bool = False, reason: str = "") -> dict[str, Any]:
    """An EmergencyCommand sample: SET, or CLEAR."""
    return {"vehicle_id": vehicle_id, "operator_id": operator_id,
            "action": "CLEAR" if clear else "SET", "authority": authority, "reason": reason}


def wrench_command(vehicle_id: str, operator_id: str, linear: float,
                   rotational: float) -> dict[str, Any]:
    """A WrenchEffortCommand sample: forward effort and turn effort in percent."""
    return {"vehicle_id": vehicle_id, "operator_id": operator_id,
            "propulsive_linear_x": max(-100.0, min(100.0, linear)),
            "propulsive_rotational_z": max(-100.0, min(100.0, rotational))}


def waypoint_plan(vehicle_id: str, operator_id: str, latitude: float, longitude: float,
                  yaw: float, *, plan_id: str = "", side: float = 15.0,
                  speed: float = 1.5) -> dict[str, Any]:
    """A WaypointPlan sample: a short triangle starting ``side`` metres ahead."""
    points = []
    for ahead, right in ((side, 0.0), (side, side), (0.0, side)):
        north = ahead * math.cos(yaw) - right * math.sin(yaw)
        east = ahead * math.sin(yaw) + right * math.cos(yaw)
        lat = latitude + math.degrees(north / EARTH_RADIUS)
        lon = longitude + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(latitude))))
        points.append({"latitude": lat, "longitude": lon, "altitude": 0.0, "x": 0.0, "y": 0.0,
                       "z": 0.0, "tolerance": 1.0})
    return {"vehicle_id": vehicle_id, "operator_id": operator_id,
            "plan_id": plan_id or f"{operator_id}-triangle", "waypoints": points,
            "frame": "GLOBAL", "speed": speed}


class Operator:
    """Key presses to command samples; holds the selection and the drive efforts.

    Keys: Up/Down select a vehicle (or, in drive mode, change forward effort), Left/Right
    turn in drive mode, ``c`` take control, ``r`` release, ``d`` drive mode on/off,
    space stop, ``w`` send a waypoint triangle, ``h`` ask the holder for a hand-off, ``a`` /
    ``n`` grant / refuse the oldest hand-off request, ``e`` emergency stop (at once; on a
    vehicle already in emergency, ``e`` then ``y`` clears it, any other key keeps it),
    ``q`` quit.
    """

    STEP = 10.0

    def __init__(self, operator_id: str, authority: int) -> None:
        self.operator_id = operator_id
        self.authority = authority
        self.selected: str | None = None
        self.driving = False
        self.linear = 0.0
        self.rotational = 0.0
        self.message = ""
        self.quit = False
        #: the vehicle whose emergency ``y`` would clear (asked by ``e``)
        self.confirm_clear: str | None = None

    def select(self, view: FleetView, step: int) -> None:
        ids = [row.vehicle_id for row in view.ordered()]
        if not ids:
            self.selected = None
            return
        index = ids.index(self.selected) if self.selected in ids else -1
        self.selected = ids[(index + step) % len(ids)] if index >= 0 else ids[0]

    def key(self, key: str, view: FleetView) -> list[tuple[str, dict[str, Any]]]:
        """Handle one key (names: ``UP``, ``DOWN``, ``LEFT``, ``RIGHT`` or a character)."""
        if self.selected not in view.vehicles:
            self.select(view, 0)
        vid = self.selected
        pending, self.confirm_clear = self.confirm_clear, None
        if pending is not None:
            if key == "y":
                self.message = f"clearing the emergency stop of {pending}"
                return [("EmergencyCommand", emergency_command(
                    pending, self.operator_id, self.authority, clear=True))]
            self.message = f"{pending}: emergency stop kept"
            if key in ("e", "n"):
                return []
        if key == "e" and vid is not None:
            if view.vehicles[vid].emergency:
                self.confirm_clear = vid
                self.message = f"CLEAR the emergency stop of {vid}? y = clear, any key = keep"
                return []
            self.driving = False
            self.linear = self.rotational = 0.0
            self.message = f"EMERGENCY STOP sent to {vid}"
            return [("EmergencyCommand", emergency_command(
                vid, self.operator_id, self.authority, reason=f"monitor of {self.operator_id}"))]
        if key == "q":
            self.quit = True
            return self.stop() if self.driving else []
        if vid is None:
            self.message = "no vehicle to command yet"
            return []
        if not self.driving and key in ("UP", "DOWN"):
            self.select(view, -1 if key == "UP" else 1)
            return []
        if key == "c":
            self.message = f"requesting control of {vid} (authority {self.authority})"
            return [("ControlRequest", control_request(vid, self.operator_id, self.authority))]
        if key == "r":
            self.driving = False
            self.message = f"releasing {vid}"
            return [("ControlRequest", control_request(vid, self.operator_id, self.authority,
                                                       release=True))]
        if key == "h":
            self.message = f"asking the holder of {vid} to hand it over"
            return [("HandoffRequest", {"vehicle_id": vid, "operator_id": self.operator_id,
                                        "authority": self.authority,
                                        "explanation": f"monitor of {self.operator_id}"})]
        if key in ("a", "n"):
            open_ = [h for h in view.vehicles[vid].handoffs if h[3] in ("PENDING", "DEFERRED")]
            if not open_:
                self.message = f"{vid}: no hand-off request to answer"
                return []
            response = "GRANTED" if key == "a" else "DENIED"
            self.message = f"{vid}: hand-off #{open_[0][0]} to {open_[0][1]} {response.lower()}"
            return [("HandoffResponse", {"vehicle_id": vid, "operator_id": self.operator_id,
                                         "request_id": open_[0][0], "response": response})]
        if key == "d":
            self.driving = not self.driving
            self.linear = self.rotational = 0.0
            self.message = f"drive mode {'on' if self.driving else 'off'} for {vid}"
            return self.stop()
        if key == " ":
            return self.stop()
        if key == "w":
            row = view.vehicles[vid]
            if row.latitude is None or row.longitude is None:
                self.message = f"{vid}: no position yet"
                return []
            self.message = f"waypoint triangle sent to {vid}"
            return [("WaypointPlan", waypoint_plan(vid, self.operator_id, row.latitude,
                                                   row.longitude, row.yaw or 0.0))]
        if self.driving and key in ("UP", "DOWN", "LEFT", "RIGHT"):
            if key in ("UP", "DOWN"):
                self.linear += self.STEP if key == "UP" else -self.STEP
            else:
                self.rotational += self.STEP if key == "RIGHT" else -self.STEP
            self.linear = max(-100.0, min(100.0, self.linear))
            self.rotational = max(-100.0, min(100.0, self.rotational))
            return self.drive()
        return []

    def drive(self) -> list[tuple[str, dict[str, Any]]]:
        """The current effort command (resent periodically while driving: dead-man)."""
        if not self.driving or self.selected is None:
            return []
        self.message = f"{self.selected}: effort {self.linear:+.0f}% turn {self.rotational:+.0f}%"
        return [("WrenchEffortCommand", wrench_command(self.selected, self.operator_id,
                                                       self.linear, self.rotational))]

    def stop(self) -> list[tuple[str, dict[str, Any]]]:
        """Zero effort for the selected vehicle."""
        self.linear = self.rotational = 0.0
        if self.selected is None:
            return []
        return [("WrenchEffortCommand", wrench_command(self.selected, self.operator_id,
                                                       0.0, 0.0))]
