"""What a simulated vehicle's sensors measure, as JAUS report fields. No I/O.

:class:`Sensors` reads the kinematic model and the vehicle's profile and builds the field
dicts of the sensor reports: global and local pose, velocity state, a range scan of a
walled yard with two posts, camera frames (PNG), sensor capabilities and configuration,
ocean environment for a UUV. Values are clamped to the ranges the JSS messages can carry.
The caller sets :attr:`Sensors.t`, the simulation time of the last model step.
"""

from __future__ import annotations

import math
import time
from typing import Any

from edge_vis.tools.sim.images import camera_frame, frame_pixels, png_grey
from edge_vis.tools.sim.kinematics import Motion, clamp, wrap_angle
from edge_vis.tools.sim.profile import VehicleSpec


class Sensors:
    """Report builders over one vehicle's model state."""

    def __init__(self, spec: VehicleSpec, motion: Motion, wall_offset: float = 0.0) -> None:
        self.spec = spec
        self.motion = motion
        self.wall_offset = wall_offset
        self.t = 0.0
        self._image_cache: tuple[int, bytes] | None = None
        self._scan_cache: tuple[float, list[dict[str, Any]]] | None = None

    def time_stamp(self) -> dict[str, int]:
        wall = self.t + self.wall_offset
        t = time.gmtime(wall)
        return {"milliseconds": int((wall % 1.0) * 1000) % 1000, "seconds": min(t.tm_sec, 59),
                "minutes": t.tm_min, "hour": t.tm_hour, "day": t.tm_mday}

    def depth(self) -> float:
        return 20.0 + 5.0 * math.sin(self.t / 60.0) if self.spec.kind == "uuv" else 0.0

    def global_pose(self, fields: dict[str, Any]) -> dict[str, Any]:
        lat, lon = self.spec.origin.to_geodetic(self.motion.x, self.motion.y)
        return {"latitude": clamp(lat, -90, 90), "longitude": clamp(lon, -180, 180),
                "altitude": clamp(self.spec.origin.altitude - self.depth(), -10000, 35000),
                "position_rms": 0.5, "roll": 0.0, "pitch": 0.0, "yaw": wrap_angle(self.motion.yaw),
                "attitude_rms": 0.05, "time_stamp": self.time_stamp()}

    def local_pose(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"x": clamp(self.motion.x, -1e5, 1e5), "y": clamp(self.motion.y, -1e5, 1e5),
                "z": self.depth(), "position_rms": 0.5, "roll": 0.0, "pitch": 0.0,
                "yaw": wrap_angle(self.motion.yaw), "attitude_rms": 0.05,
                "time_stamp": self.time_stamp()}

    def velocity_state(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"velocity_x": clamp(self.motion.speed, -327, 327), "velocity_y": 0.0,
                "velocity_z": 0.0, "velocity_rms": 0.1, "roll_rate": 0.0, "pitch_rate": 0.0,
                "yaw_rate": clamp(self.motion.yaw_rate, -32, 32), "rate_rms": 0.01,
                "time_stamp": self.time_stamp()}

    def scan(self) -> list[dict[str, Any]]:
        """A 181-beam scan of a walled yard (radius 40 m) with two posts in it."""
        if self._scan_cache is not None and self._scan_cache[0] == self.t:
            return self._scan_cache[1]
        m = self.motion
        posts = ((15.0, 5.0, 1.0), (-8.0, 12.0, 1.5))
        points = []
        for i in range(181):
            bearing = math.radians(i - 90)
            heading = m.yaw + bearing
            dx, dy = math.cos(heading), math.sin(heading)
            # distance to the circular wall: solve |p + t d| = R
            b = m.x * dx + m.y * dy
            c = m.x * m.x + m.y * m.y - 40.0 ** 2
            rng = -b + math.sqrt(max(0.0, b * b - c))
            for px, py, pr in posts:
                ox, oy = px - m.x, py - m.y
                t = ox * dx + oy * dy
                miss = (ox - t * dx) ** 2 + (oy - t * dy) ** 2
                if t > 0 and miss < pr * pr:
                    rng = min(rng, t - math.sqrt(pr * pr - miss))
            points.append({"range": clamp(rng, 0.0, 1e6), "bearing": bearing,
                           "inclination": 0.0})
        self._scan_cache = (self.t, points)
        return points

    def range_sensor_data(self, fields: dict[str, Any]) -> dict[str, Any]:
        out = []
        for q in fields.get("query_range_sensor_data_list", []) or [{"sensor_id": 1}]:
            if q["sensor_id"] != 1:
                out.append({"range_sensor_data_error_rec": {
                    "sensor_id": q["sensor_id"], "data_error_code": 255,
                    "error_message": "no such sensor"}})
                continue
            out.append({"range_sensor_data_seq": {
                "range_sensor_data_rec": {"sensor_id": 1, "report_coordinate_system": 0,
                                          "time_stamp": self.time_stamp()},
                "range_sensor_data_point_list": self.scan()}})
        return {"range_sensor_data_list": out}

    def range_sensor_capabilities(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"range_sensor_capabilities_list": [{
            "sensor_id": 1, "sensor_name": "front lidar",
            "supported_states": {"active": 1, "standby": 0, "off": 0},
            "minimum_horizontal_field_of_view_start_angle": -math.pi / 2,
            "maximum_horizontal_field_of_view_stop_angle": math.pi / 2,
            "miniumum_update_rate": 1.0, "maximum_update_rate": 20.0,
            "minimum_range": 0.1, "maximum_range": 80.0}]}

    def range_sensor_configuration(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"range_sensor_configuration_list": [{
            "sensor_id": 1, "horizontal_field_of_view_start_angle": -math.pi / 2,
            "horizontal_field_of_view_stop_angle": math.pi / 2, "update_rate": 10.0,
            "minimum_range": 0.1, "maximum_range": 80.0, "sensor_state": 0}]}

    def visual_sensor_capabilities(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"visual_sensor_capabilities_list": [{
            "sensor_id": 1, "sensor_name": "mast camera",
            "supported_states": {"active": 1, "standby": 1, "off": 0},
            "imaging_modes": {"color": 0, "greyscale": 1}}]}

    def visual_sensor_configuration(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"visual_sensor_configuration_list": [{
            "sensor_id": 1, "sensor_state": 0, "imaging_mode": 1,
            "horizontal_field_of_view": 1.0, "vertical_field_of_view": 0.75}]}

    def still_image_capabilities(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"still_image_sensor_list": [{
            "sensor_id": 1, "supported_frame_sizes": {"qqvga_160x120": 1},
            "supported_image_formats": {"png": 1}}]}

    def still_image_configuration(self, fields: dict[str, Any]) -> dict[str, Any]:
        return {"still_image_sensor_configuration_list": [{
            "sensor_id": 1, "frame_size": 5, "still_image_format": 2}]}

    def still_image(self) -> bytes:
        """The current camera frame (a PNG; a new frame every second)."""
        number = int(self.t)
        if self._image_cache is None or self._image_cache[0] != number:
            self._image_cache = (number, camera_frame(self.spec.image_width,
                                                      self.spec.image_height,
                                                      self.spec.seed, number))
        return self._image_cache[1]

    def still_image_data(self, fields: dict[str, Any]) -> dict[str, Any]:
        out = []
        for q in fields.get("query_still_image_data_list", []) or [{"sensor_id": 1}]:
            if q["sensor_id"] != 1:
                continue
            out.append({"sensor_id": 1, "report_coordinate_system": 0,
                        "time_stamp": self.time_stamp(),
                        "image_frame": {"format": 2, "data": self.still_image()}})
        return {"still_image_data_list": out}

    def ocean_environment(self, fields: dict[str, Any]) -> dict[str, Any]:
        t = self.t
        return {"water_temperature": 12.0 + 0.5 * math.sin(t / 90.0),
                "salinity": 35.0 + 0.2 * math.sin(t / 200.0),
                "depth": self.depth(), "current_speed": 0.4 + 0.1 * math.sin(t / 30.0),
                "current_direction": wrap_angle(0.8 + 0.2 * math.sin(t / 45.0)),
                "time_stamp": self.time_stamp()}

    def atr_image(self, image_id: int) -> bytes:
        """The bytes of ATR image ``image_id`` (deterministic; a 320x240 PNG)."""
        return png_grey(320, 240, frame_pixels(320, 240, self.spec.seed + 7919, image_id))
