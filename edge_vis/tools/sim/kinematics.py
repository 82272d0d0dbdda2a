"""A planar kinematic vehicle model and local-to-geodetic conversion. No I/O.

The frame is north-east-down: ``x`` north, ``y`` east (metres from the origin), ``yaw``
clockwise from north (radians, within [-pi, pi]); positive yaw rate turns right. That is
the JAUS convention for global and local pose. The model is a unicycle whose speed and
yaw rate follow their commanded values with first-order lag, stepped at a fixed ``dt`` so
that runs are reproducible whatever the caller's clock does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from edge_vis.schema import setting

EARTH_RADIUS = 6_371_000.0


def wrap_angle(angle: float) -> float:
    """``angle`` in [-pi, pi]."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def clamp(value: float, low: float, high: float) -> float:
    """``value`` limited to [low, high]."""
    return low if value < low else high if value > high else value


@dataclass(slots=True)
class Motion:
    """State and commands of the unicycle model."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    speed: float = 0.0
    yaw_rate: float = 0.0
    speed_command: float = 0.0
    yaw_rate_command: float = 0.0
    max_speed: float = 3.0
    max_yaw_rate: float = 1.0
    lag: float = 0.3  # seconds to reach ~63 % of a commanded change

    def command(self, speed: float, yaw_rate: float) -> None:
        """Set the commanded speed (m/s) and yaw rate (rad/s), limited to the maxima."""
        self.speed_command = clamp(speed, -self.max_speed, self.max_speed)
        self.yaw_rate_command = clamp(yaw_rate, -self.max_yaw_rate, self.max_yaw_rate)

    def stop(self) -> None:
        """Command zero speed and yaw rate."""
        self.command(0.0, 0.0)

    def step(self, dt: float) -> None:
        """Advance the model by ``dt`` seconds."""
        k = 1.0 - math.exp(-dt / self.lag) if self.lag > 0 else 1.0
        self.speed += (self.speed_command - self.speed) * k
        self.yaw_rate += (self.yaw_rate_command - self.yaw_rate) * k
        if abs(self.speed) < 1e-4 and self.speed_command == 0.0:
            self.speed = 0.0
        if abs(self.yaw_rate) < 1e-5 and self.yaw_rate_command == 0.0:
            self.yaw_rate = 0.0
        self.yaw = wrap_angle(self.yaw + self.yaw_rate * dt)
        self.x += self.speed * math.cos(self.yaw) * dt
        self.y += self.speed * math.sin(self.yaw) * dt

    @property
    def velocity(self) -> tuple[float, float]:
        """Velocity (north, east) in m/s."""
        return self.speed * math.cos(self.yaw), self.speed * math.sin(self.yaw)


@dataclass(frozen=True, slots=True)
class Origin:
    """The geodetic point the local frame is anchored to (degrees; altitude in metres)."""

    latitude: float = setting(ge=-89, le=89)
    longitude: float = setting(ge=-180, le=180)
    altitude: float = 0.0

    def to_geodetic(self, x: float, y: float) -> tuple[float, float]:
        """Latitude and longitude (degrees) of local point (x north, y east)."""
        lat = self.latitude + math.degrees(x / EARTH_RADIUS)
        lon = self.longitude + math.degrees(
            y / (EARTH_RADIUS * math.cos(math.radians(self.latitude)))
        )
        return lat, lon

    def to_local(self, latitude: float, longitude: float) -> tuple[float, float]:
        """Local (x north, y east) metres of a geodetic point."""
        x = math.radians(latitude - self.latitude) * EARTH_RADIUS
        y = math.radians(longitude - self.longitude) * EARTH_RADIUS * math.cos(
            math.radians(self.latitude)
        )
        return x, y
