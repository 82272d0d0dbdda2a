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

    [vehicles.manipulator]                    # optional: an arm and a pan-tilt
    version = "2.0"                           # or "1.0" (its services and wire layouts)

    [vehicles.faults]
    dropout = { every = 60.0, duration = 5.0, reboot = true }  # optional first = 10.0
    reject_events = ["QueryRangeSensorData"]  # or true for every CreateEvent
    refuse_control = false
    jts_example = false                       # ignore CreateEvent/QueryTimeout, INITIALIZE forever
    malformed_rate = 0.2                      # malformed frames per second

A ``ugv`` with ``iop = true`` has a fourth component offering the IOP and UGV services
(hand-off, cost map and no-go zones, CBRN, digital resources, skid-steer and Ackermann
drivers, capabilities, a battery): :mod:`edge_vis.tools.sim.iop_sim`.

A ``uuv`` does not implement JAUS Discovery: it announces itself with the vendor
``VendorHello`` message and reports ocean environment and ATR image notices unsolicited;
with ``atr_dir`` set, each announced ATR image is also written there as ``atr-<id>.png``
(ready for ``edge-vis send-image``).

A ``custom`` vehicle is one component (``component``, default 1) whose messages come from
the user's JSIDL, with no Python (:mod:`edge_vis.tools.sim.scripted`)::

    [[vehicles]]
    name = "pack"
    kind = "custom"
    subsystem = 77
    component = 3
    link = "udp://127.0.0.88:3794"
    jsidl = ["BatteryPack.xml"]               # relative to the profile file
    hello_period = 2.0
    hello = { message = "ReportBatteryHello", services_field = "services",
              fields = { pack_serial = "BP-0042", chemistry = "LIFEPO4" } }

    [[vehicles.reports]]
    message = "ReportBatteryPack"
    query = "QueryBatteryPack"                # answered when asked; period = N: also sent
    fields = { voltage = 48.2, pack_state = "DISCHARGING" }
    drift = { voltage = { amplitude = 0.3, period = 20.0 } }

Its services (``services``, default: those its JSIDL says declare the hello and reports)
are what a ``services_field`` of the hello lists. Messages it does not know are counted.
The dataclasses below are the schema: the validation kit (:mod:`edge_vis.schema`) reads
the file against them, so each key's default and range is written once, on its field.
Every problem is collected and raised together as one :class:`~edge_vis.errors.ConfigError`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from edge_vis.config.loader import read_toml
from edge_vis.schema import Reader, setting
from edge_vis.tools.sim import scripted
from edge_vis.tools.sim.arm import ArmSpec
from edge_vis.tools.sim.kinematics import Origin
from edge_vis.tools.sim.scripted import HelloSpec, ReportSpec

KINDS = ("ugv", "uuv", "custom")


def _rejects(value: bool | tuple[str, ...]) -> frozenset[str]:
    if value is True:
        return frozenset({"*"})
    return frozenset() if value is False else frozenset(value)  # type: ignore[arg-type]


def _sim_link(link: str) -> str | None:
    """A simulated vehicle binds a loopback UDP address, or talks over a pseudo-terminal."""
    if link == "pty":
        return None
    parts = urlsplit(link)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "udp" or not parts.hostname or port is None:
        return f"{link!r} must be 'udp://IP:PORT' or 'pty'"
    if not parts.hostname.startswith("127."):
        return f"{link!r}: simulated vehicles bind loopback (127.x)"
    return None


def _non_empty(text: str) -> str | None:
    return None if text else "a non-empty vehicle name is required"


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """Misbehaviour injected into one vehicle (``[vehicles.faults]``)."""

    dropout_every: float = setting(0.0, key="dropout.every", ge=0.1, unit="s")
    dropout_duration: float = setting(0.0, key="dropout.duration", ge=0.0, unit="s")
    #: seconds after start; default: ``dropout_every``
    dropout_first: float | None = setting(None, key="dropout.first", ge=0.0, unit="s")
    dropout_reboot: bool = setting(False, key="dropout.reboot")
    #: query names, or {"*"} (``reject_events = true``)
    reject_events: frozenset[str] = setting(frozenset(), read_as=bool | tuple[str, ...],
                                            convert=_rejects)
    refuse_control: bool = False
    jts_example: bool = False
    malformed_rate: float = setting(0.0, ge=0.0, le=100.0, unit="per second")

    def rejects_event(self, query_name: str) -> bool:
        """Whether a CreateEvent for ``query_name`` must be rejected."""
        return "*" in self.reject_events or query_name in self.reject_events

    def validate(self) -> Iterable[tuple[str, str]]:
        """A dropout must leave the vehicle some time on the air."""
        every, duration = self.dropout_every, self.dropout_duration
        if (every or duration) and duration >= every:
            yield "dropout", f"duration {duration:g} must be below every {every:g}"


@dataclass(frozen=True, slots=True)
class VehicleSpec:
    """One simulated vehicle (a JAUS subsystem)."""

    name: str = setting(check=_non_empty, doc="a non-empty vehicle name is required")
    subsystem: int = setting(ge=1, le=65534, doc="a subsystem id (1..65534) is required")
    link: str = setting(check=_sim_link, doc="'udp://127.x.x.x:PORT' or 'pty'")
    kind: str = setting("ugv", choices=KINDS)
    node: int = setting(1, ge=1, le=254)
    pty_link: str = ""
    pty_path_file: str = ""
    baud: int = setting(57600, ge=300, le=4_000_000)
    origin: Origin = field(default_factory=lambda: Origin(36.5965, -121.8747))
    heading: float = setting(0.0, ge=-3.1416, le=3.1416, unit="rad")
    max_speed: float = setting(3.0, ge=0.1, le=300, unit="m/s")
    max_yaw_rate: float = setting(1.0, ge=0.01, le=30, unit="rad/s")
    control_timeout: int = setting(5, ge=0, le=255, unit="s")
    event_timeout: int = setting(1, ge=0, le=255, unit="min")
    default_authority: int = setting(0, ge=0, le=255)
    #: how far the vehicle's clock (JAUS Time) is off UTC at start
    clock_offset: float = setting(0.0, ge=-1e9, le=1e9, unit="s")
    max_event_rate: float = setting(25.0, ge=0.1, le=1092, unit="Hz")
    init_time: float = setting(0.5, ge=0.0, unit="s")
    image_width: int = setting(160, ge=8, le=2048)
    image_height: int = setting(120, ge=8, le=2048)
    hello_period: float = setting(2.0, ge=0.05, unit="s")
    environment_period: float = setting(1.0, ge=0.0, unit="s")
    atr_period: float = setting(15.0, ge=0.0, unit="s")
    bulk_image_port: int = setting(0, ge=0, le=65535)
    atr_dir: str = ""
    #: HOST:PORT where the vehicle serves ``atr_dir`` over UDT, as ``edge-vis serve-images``
    #: does (port 0: a free one, printed with the vehicle); "" serves nothing
    image_server: str = ""
    #: ugv: a fourth component with the IOP and UGV services (edge_vis.tools.sim.iop_sim)
    iop: bool = False
    faults: FaultSpec = field(default_factory=FaultSpec)
    #: ugv: a manipulator and a pan-tilt (``[vehicles.manipulator]``, version 2.0 or 1.0)
    manipulator: ArmSpec | None = None
    #: custom: the component id of its one component
    component: int = setting(1, ge=1, le=254)
    #: custom: JSIDL files of its messages (relative to the profile)
    jsidl: tuple[Path, ...] = ()
    #: custom: the services it offers (default: those declaring its hello and reports)
    services: tuple[str, ...] = ()
    hello: HelloSpec | None = None
    reports: tuple[ReportSpec, ...] = ()
    #: the profile's seed plus the vehicle's index
    seed: int = setting(0, toml=False)

    @property
    def is_pty(self) -> bool:
        """Whether the vehicle talks over a serial pseudo-terminal."""
        return self.link == "pty"

    @property
    def udp_address(self) -> tuple[str, int]:
        """The (ip, port) a UDP vehicle binds."""
        parts = urlsplit(self.link)
        return parts.hostname or "127.0.0.1", parts.port if parts.port is not None else 3794

    def validate(self) -> Iterable[tuple[str, str]]:
        """Only a custom vehicle says what it sends, and it must send something."""
        custom = self.kind == "custom"
        for key, given in (("jsidl", self.jsidl), ("services", self.services),
                           ("hello", self.hello), ("reports", self.reports)):
            if given and not custom:
                yield key, f"only a vehicle of kind = \"custom\" takes {key} (this is {self.kind})"
        if self.manipulator is not None and self.kind != "ugv":
            yield "manipulator", f"only a vehicle of kind = \"ugv\" carries one ({self.kind})"
        if custom and self.hello is None and not self.reports:
            yield "kind", "a custom vehicle needs a hello, reports, or both"


@dataclass(frozen=True, slots=True)
class SimProfile:
    """Every vehicle of one simulation run."""

    vehicles: tuple[VehicleSpec, ...] = setting(custom=True)
    source: str = setting("", toml=False)
    #: one seed for every vehicle's random generator
    seed: int = 0


def read_sim_profile(reader: Reader, data: Mapping[str, Any]) -> SimProfile | None:
    """A parsed simulation profile -> :class:`SimProfile`, problems left in ``reader``."""
    tables = data.get("vehicles", [])
    if not isinstance(tables, list) or not tables:
        reader.problem("vehicles", "at least one [[vehicles]] table is required")
        tables = []
    found = [(i, reader.read(VehicleSpec, t, f"vehicles[{i}]")) for i, t in enumerate(tables)]
    vehicles = [(i, v) for i, v in found if v is not None]
    profile = reader.read(SimProfile, data, values={"vehicles": (), "source": reader.file})
    seen: dict[tuple[str, Any], str] = {}
    for i, table in enumerate(tables):  # as written: a vehicle refused for another reason
        if not isinstance(table, Mapping):  # still claims its name, subsystem and link
            continue
        name = table.get("name")
        for what in ("name", "subsystem", "link"):
            key = table.get(what)
            if key is None or isinstance(key, Mapping | list) or key == "pty":
                continue
            if (what, key) in seen:
                reader.problem(f"vehicles[{i}].{what}",
                               f"{key!r} is also used by {seen[(what, key)]}")
            seen[(what, key)] = str(name)
    for i, vehicle in vehicles:
        if vehicle.kind == "custom":
            for key, reason in scripted.problems(vehicle.jsidl, vehicle.hello,
                                                 vehicle.reports, f"vehicles[{i}]"):
                reader.problem(key, reason)
    if profile is None:
        return None
    return replace(profile, vehicles=tuple(replace(v, seed=profile.seed + i)
                                           for i, v in vehicles))


def parse_profile(data: Mapping[str, Any], source: str = "",
                  base_dir: Path | None = None) -> SimProfile:
    """Build a :class:`SimProfile` from parsed TOML; raise ConfigError listing every problem.
    Relative JSIDL paths are taken from ``base_dir``."""
    reader = Reader(source, base_dir=base_dir)
    profile = read_sim_profile(reader, data)
    reader.raise_problems()
    assert profile is not None
    return profile


def load_profile(path: str | Path) -> SimProfile:
    """Read and check a simulation profile file."""
    return parse_profile(read_toml(path), str(path), Path(path).parent)
