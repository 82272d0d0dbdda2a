"""Simulation profiles: which vehicles to simulate and how they misbehave. Reads a TOML file.

A profile is a list of ``[[vehicles]]`` tables; every key has a default, so the smallest
vehicle is ``name``, ``subsystem`` and ``link``::

    seed = 7                                  # one seed for every vehicle's RNG

    [[vehicles]]
    name = "ugv-alpha"
    kind = "ugv"                              # ugv: discovery, sensors, drivers; uuv: see below
    subsystem = 101
    link = "udp://127.0.0.11:3794"            # or "pty" for a serial pseudo-terminal
    origin = { latitude = 36.6, longitude = -121.9 }

    [vehicles.faults]
    dropout = { every = 60.0, duration = 5.0, reboot = true }  # optional first = 10.0
    reject_events = ["QueryRangeSensorData"]  # or true for every CreateEvent
    refuse_control = false
    jts_example = false                       # ignore CreateEvent/QueryTimeout, INITIALIZE forever
    malformed_rate = 0.2                      # malformed frames per second

A ``uuv`` does not implement JAUS Discovery: it announces itself with the vendor
``VendorHello`` message and reports ocean environment and ATR image notices unsolicited;
with ``atr_dir`` set, each announced ATR image is also written there as ``atr-<id>.png``
(ready for ``edge-vis send-image``).
Errors are collected and raised together as one :class:`~edge_vis.errors.ConfigError`.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from edge_vis.errors import ConfigError
from edge_vis.tools.sim.kinematics import Origin

KINDS = ("ugv", "uuv")


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """Misbehaviour injected into one vehicle."""

    dropout_every: float = 0.0
    dropout_duration: float = 0.0
    dropout_first: float | None = None  # seconds after start; default: ``dropout_every``
    dropout_reboot: bool = False
    reject_events: frozenset[str] = frozenset()  # query names, or {"*"}
    refuse_control: bool = False
    jts_example: bool = False
    malformed_rate: float = 0.0

    def rejects_event(self, query_name: str) -> bool:
        """Whether a CreateEvent for ``query_name`` must be rejected."""
        return "*" in self.reject_events or query_name in self.reject_events


@dataclass(frozen=True, slots=True)
class VehicleSpec:
    """One simulated vehicle (a JAUS subsystem)."""

    name: str
    subsystem: int
    link: str
    kind: str = "ugv"
    node: int = 1
    pty_link: str = ""
    pty_path_file: str = ""
    baud: int = 57600
    origin: Origin = field(default_factory=lambda: Origin(36.5965, -121.8747))
    heading: float = 0.0
    max_speed: float = 3.0
    max_yaw_rate: float = 1.0
    control_timeout: int = 5
    event_timeout: int = 1
    default_authority: int = 0
    max_event_rate: float = 25.0
    init_time: float = 0.5
    image_width: int = 160
    image_height: int = 120
    hello_period: float = 2.0
    environment_period: float = 1.0
    atr_period: float = 15.0
    bulk_image_port: int = 0
    atr_dir: str = ""
    faults: FaultSpec = field(default_factory=FaultSpec)
    seed: int = 0

    @property
    def is_pty(self) -> bool:
        """Whether the vehicle talks over a serial pseudo-terminal."""
        return self.link == "pty"

    @property
    def udp_address(self) -> tuple[str, int]:
        """The (ip, port) a UDP vehicle binds."""
        parts = urlsplit(self.link)
        return parts.hostname or "127.0.0.1", parts.port if parts.port is not None else 3794


@dataclass(frozen=True, slots=True)
class SimProfile:
    """Every vehicle of one simulation run."""

    vehicles: tuple[VehicleSpec, ...]
    source: str = ""


class _Problems:
    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[tuple[str, str, str]] = []

    def add(self, path: str, message: str) -> None:
        self.items.append((self.source, path, message))


def _number(table: Mapping[str, Any], key: str, default: float, path: str, problems: _Problems,
            *, low: float | None = None, high: float | None = None, integer: bool = False
            ) -> Any:
    value = table.get(key, default)
    ok = isinstance(value, int) if integer else isinstance(value, int | float)
    if isinstance(value, bool) or not ok:
        kind = "an integer" if integer else "a number"
        problems.add(f"{path}.{key}", f"must be {kind}, got {value!r}")
        return default
    if (low is not None and value < low) or (high is not None and value > high):
        problems.add(f"{path}.{key}", f"{value} is outside [{low}, {high}]")
        return default
    return value


def _faults(table: Any, path: str, problems: _Problems) -> FaultSpec:
    if table is None:
        return FaultSpec()
    if not isinstance(table, dict):
        problems.add(path, "must be a table")
        return FaultSpec()
    known = {"dropout", "reject_events", "refuse_control", "jts_example", "malformed_rate"}
    for key in table:
        if key not in known:
            problems.add(f"{path}.{key}", f"unknown fault (known: {', '.join(sorted(known))})")
    every = duration = 0.0
    first: float | None = None
    reboot = False
    dropout = table.get("dropout")
    if dropout is not None:
        if not isinstance(dropout, dict):
            problems.add(f"{path}.dropout", "must be a table {every, duration, first, reboot}")
        else:
            every = _number(dropout, "every", 0.0, f"{path}.dropout", problems, low=0.1)
            duration = _number(dropout, "duration", 0.0, f"{path}.dropout", problems, low=0.0)
            reboot = bool(dropout.get("reboot", False))
            if "first" in dropout:
                first = _number(dropout, "first", 0.0, f"{path}.dropout", problems, low=0.0)
            if duration >= every:
                problems.add(f"{path}.dropout", f"duration {duration} must be below every {every}")
    reject = table.get("reject_events", False)
    if reject is True:
        rejects = frozenset({"*"})
    elif reject is False:
        rejects = frozenset()
    elif isinstance(reject, list) and all(isinstance(r, str) for r in reject):
        rejects = frozenset(reject)
    else:
        problems.add(f"{path}.reject_events", "must be true, false or a list of query names")
        rejects = frozenset()
    return FaultSpec(
        dropout_every=every,
        dropout_duration=duration,
        dropout_reboot=reboot,
        dropout_first=first,
        reject_events=rejects,
        refuse_control=bool(table.get("refuse_control", False)),
        jts_example=bool(table.get("jts_example", False)),
        malformed_rate=_number(table, "malformed_rate", 0.0, path, problems, low=0.0, high=100.0),
    )


def _vehicle(table: Any, index: int, seed: int, problems: _Problems) -> VehicleSpec | None:
    path = f"vehicles[{index}]"
    if not isinstance(table, dict):
        problems.add(path, "must be a table")
        return None
    name = table.get("name")
    if not isinstance(name, str) or not name:
        problems.add(f"{path}.name", "a non-empty vehicle name is required")
        name = f"vehicle-{index}"
    path = f"vehicles[{index}] ({name})"
    kind = table.get("kind", "ugv")
    if kind not in KINDS:
        problems.add(f"{path}.kind", f"{kind!r} is not one of {', '.join(KINDS)}")
        kind = "ugv"
    subsystem = _number(table, "subsystem", 0, path, problems, low=1, high=65534, integer=True)
    if "subsystem" not in table:
        problems.add(f"{path}.subsystem", "a subsystem id (1..65534) is required")
    link = table.get("link")
    if link != "pty":
        parts = urlsplit(link) if isinstance(link, str) else None
        try:
            port_ok = parts is not None and parts.port is not None
        except ValueError:
            port_ok = False
        if parts is None or parts.scheme != "udp" or not parts.hostname or not port_ok:
            problems.add(f"{path}.link", f"{link!r} must be 'udp://IP:PORT' or 'pty'")
            link = "udp://127.0.0.1:3794"
        elif not parts.hostname.startswith("127."):
            problems.add(f"{path}.link", f"{link!r}: simulated vehicles bind loopback (127.x)")
    origin_table = table.get("origin", {})
    if not isinstance(origin_table, dict):
        problems.add(f"{path}.origin", "must be a table {latitude, longitude}")
        origin_table = {}
    origin = Origin(
        _number(origin_table, "latitude", 36.5965, f"{path}.origin", problems, low=-89, high=89),
        _number(origin_table, "longitude", -121.8747, f"{path}.origin", problems,
                low=-180, high=180),
        _number(origin_table, "altitude", 0.0, f"{path}.origin", problems),
    )
    known = {
        "name", "kind", "subsystem", "node", "link", "pty_link", "pty_path_file", "baud",
        "origin", "heading", "max_speed", "max_yaw_rate", "control_timeout", "event_timeout",
        "default_authority", "max_event_rate", "init_time", "image_width", "image_height",
        "hello_period", "environment_period", "atr_period", "bulk_image_port", "atr_dir",
        "faults",
    }
    for key in table:
        if key not in known:
            problems.add(f"{path}.{key}", "unknown key")
    for key in ("pty_link", "pty_path_file", "atr_dir"):
        if not isinstance(table.get(key, ""), str):
            problems.add(f"{path}.{key}", "must be a path string")
    return VehicleSpec(
        name=name,
        subsystem=subsystem,
        link=link if isinstance(link, str) else "pty",
        kind=kind,
        node=_number(table, "node", 1, path, problems, low=1, high=254, integer=True),
        pty_link=str(table.get("pty_link", "")),
        pty_path_file=str(table.get("pty_path_file", "")),
        atr_dir=str(table.get("atr_dir", "")),
        baud=_number(table, "baud", 57600, path, problems, low=300, high=4_000_000, integer=True),
        origin=origin,
        heading=_number(table, "heading", 0.0, path, problems, low=-3.1416, high=3.1416),
        max_speed=_number(table, "max_speed", 3.0, path, problems, low=0.1, high=300),
        max_yaw_rate=_number(table, "max_yaw_rate", 1.0, path, problems, low=0.01, high=30),
        control_timeout=_number(table, "control_timeout", 5, path, problems, low=0, high=255,
                                integer=True),
        event_timeout=_number(table, "event_timeout", 1, path, problems, low=0, high=255,
                              integer=True),
        default_authority=_number(table, "default_authority", 0, path, problems, low=0,
                                  high=255, integer=True),
        max_event_rate=_number(table, "max_event_rate", 25.0, path, problems, low=0.1,
                               high=1092),
        init_time=_number(table, "init_time", 0.5, path, problems, low=0.0),
        image_width=_number(table, "image_width", 160, path, problems, low=8, high=2048,
                            integer=True),
        image_height=_number(table, "image_height", 120, path, problems, low=8, high=2048,
                             integer=True),
        hello_period=_number(table, "hello_period", 2.0, path, problems, low=0.05),
        environment_period=_number(table, "environment_period", 1.0, path, problems, low=0.0),
        atr_period=_number(table, "atr_period", 15.0, path, problems, low=0.0),
        bulk_image_port=_number(table, "bulk_image_port", 0, path, problems, low=0,
                                high=65535, integer=True),
        faults=_faults(table.get("faults"), f"{path}.faults", problems),
        seed=seed + index,
    )


def parse_profile(data: Mapping[str, Any], source: str = "") -> SimProfile:
    """Build a :class:`SimProfile` from parsed TOML; raise ConfigError listing every problem."""
    problems = _Problems(source)
    for key in data:
        if key not in ("seed", "vehicles"):
            problems.add(key, "unknown key (expected seed, vehicles)")
    seed = _number(data, "seed", 0, "", problems, integer=True)
    tables = data.get("vehicles", [])
    if not isinstance(tables, list) or not tables:
        problems.add("vehicles", "at least one [[vehicles]] table is required")
        tables = []
    vehicles = [v for i, t in enumerate(tables) if (v := _vehicle(t, i, seed, problems))]
    seen: dict[Any, str] = {}
    for v in vehicles:
        for key, what in ((v.name, "name"), (v.subsystem, "subsystem"),
                          (v.link if not v.is_pty else None, "link")):
            if key is None:
                continue
            if (what, key) in seen:
                problems.add(f"vehicles ({v.name}).{what}",
                             f"{key!r} is also used by {seen[(what, key)]}")
            seen[(what, key)] = v.name
    if problems.items:
        raise ConfigError(problems.items)
    return SimProfile(tuple(vehicles), source)


def load_profile(path: str | Path) -> SimProfile:
    """Read and check a simulation profile file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError([(str(path), "", f"cannot read: {exc.strerror or exc}")]) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([(str(path), "", f"not valid TOML: {exc}")]) from None
    return parse_profile(data, str(path))
