"""Deployment and vehicle profiles: TOML -> validated frozen dataclasses.

Reads files: :func:`load_profile` the profile itself, :func:`from_mapping` the vehicle
profiles a deployment references with ``file =`` (and it checks that ``catalogue.jsidl``
files exist). A mapping without such references is validated without touching the disk.

A *deployment profile* describes one relay: its JAUS address and authority, its radio
links, the DDS domain, which translators run, the discovery/liveness/command timing, the
report rates and the vehicles it knows in advance. A *vehicle profile* (inline in the
deployment profile, or a separate file referenced by ``file =``) names a vehicle and, for
robots that do not answer standard discovery, gives its static address and services.

Validation collects every problem before raising one :class:`~edge_vis.errors.ConfigError`
whose ``problems`` are ``(file, key path, message)`` triples, e.g.
``("profiles/site.toml", "vehicles[1].address", "JAUS address '1.2' is not of the form S.N.C")``.

The built-in default deployment is ``profiles/default.toml`` beside the package (found in
a source checkout or editable install) or, failing that, the copy packaged as
``edge_vis/data/default.toml``; :func:`default_profile_path` says which.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, TypeVar
from urllib.parse import urlsplit

from edge_vis.bandwidth.linkspec import SPEC_KEYS, LinkSpec, load_link_spec, read_link_spec
from edge_vis.config.operators import OperatorPolicy
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress

T = TypeVar("T")

# -- the dataclasses --------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LinkProfile:
    """A radio or wired link. ``bandwidth`` in bit/s, 0 = unknown/unlimited.

    ``spec`` describes the medium (``profile = "serial-9600"`` naming a file of
    ``profiles/links/``, and/or the same keys inline): the rate planner and the link
    scheduler work from it. Without it only ``bandwidth`` paces the link.
    """

    name: str
    url: str
    bandwidth: int = 0
    options: Mapping[str, Any] = field(default_factory=dict)
    spec: LinkSpec | None = None

    @property
    def scheme(self) -> str:
        """The URL scheme, which is also the link plugin's entry-point name."""
        return urlsplit(self.url).scheme


@dataclass(frozen=True, slots=True)
class ServiceProfile:
    """A service a component offers: URI and ``major.minor`` version."""

    uri: str
    version: str = "1.0"


@dataclass(frozen=True, slots=True)
class ComponentProfile:
    """A component of a statically described vehicle."""

    address: JausAddress
    services: tuple[ServiceProfile, ...] = ()


@dataclass(frozen=True, slots=True)
class VehicleProfile:
    """What is known about a vehicle in advance.

    ``subsystem`` ties a discovered JAUS subsystem to this ``vehicle_id``. With
    ``components`` the vehicle is *static*: it is declared at start-up with those
    services, and standard discovery (identification, services) is not needed for it.
    ``report_rates`` (Hz, by report message name) override the deployment's rates.
    """

    vehicle_id: str
    subsystem: int | None = None
    name: str = ""
    vehicle_type: str = ""
    link: str = ""
    components: tuple[ComponentProfile, ...] = ()
    report_rates: Mapping[str, float] = field(default_factory=dict)
    source: str = ""
    #: minimum useful rate (Hz) and planning priority (higher = kept longer) by report
    report_minimums: Mapping[str, float] = field(default_factory=dict)
    report_priorities: Mapping[str, int] = field(default_factory=dict)

    @property
    def is_static(self) -> bool:
        """True when the profile lists the vehicle's components and services."""
        return bool(self.components)


@dataclass(frozen=True, slots=True)
class DiscoveryProfile:
    """Discovery and liveness timing, in seconds.

    A vehicle is declared lost after ``lost_after`` liveness periods without any message.
    """

    period: float = 5.0
    liveness_period: float = 1.0
    lost_after: float = 3.0
    response_timeout: float = 3.0

    @property
    def silence_timeout(self) -> float:
        """Seconds of silence after which a vehicle is declared lost."""
        return self.liveness_period * self.lost_after


@dataclass(frozen=True, slots=True)
class ControlProfile:
    """Access control and management timing.

    ``renewal_period`` is used when a component does not report its control timeout
    (the JTS example never answers QueryTimeout). ``max_ready_attempts`` bounds how long
    a component that never leaves INITIALIZE can hold up commanding.
    """

    renewal_period: float = 2.0
    response_timeout: float = 2.0
    retry_period: float = 5.0
    max_ready_attempts: int = 3


@dataclass(frozen=True, slots=True)
class EventsProfile:
    """JAUS event subscription timing.

    After ``attempts`` unanswered CreateEvent requests (``response_timeout`` s each), the
    report is polled instead. ``default_refresh`` is the renewal period when the provider
    does not report its event timeout.
    """

    response_timeout: float = 3.0
    attempts: int = 2
    default_refresh: float = 60.0


@dataclass(frozen=True, slots=True)
class CommandProfile:
    """Command throttling: max rate (Hz) per vehicle and kind, lifespan and dead-man (s)."""

    rate: float = 10.0
    lifespan: float = 0.5
    deadman_timeout: float = 1.0


@dataclass(frozen=True, slots=True)
class DdsProfile:
    """The DDS domain and partitions the relay publishes in."""

    domain: int = 0
    partitions: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class LimitsProfile:
    """Bounds on tables that grow with what the network sends (``[limits]``).

    Past a bound the newest entry is refused (vehicles, probes) or the oldest forgotten
    (routes), and a counter says so; nothing already accepted is lost.
    """

    max_vehicles: int = 256
    max_routes: int = 4096
    max_duplicates: int = 65536
    max_unidentified: int = 1024
    max_products: int = 256


@dataclass(frozen=True, slots=True)
class TranslatorSelection:
    """Which translators run. ``enabled`` of ``("*",)`` means every installed one.

    ``options`` are the sub-tables of ``[translators]`` by translator name (e.g.
    ``[[translators.generic.mappings]]``); the translator validates its own table.
    """

    enabled: tuple[str, ...] = ("*",)
    disabled: tuple[str, ...] = ()
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def selects(self, name: str) -> bool:
        """True when translator ``name`` should run."""
        if name in self.disabled:
            return False
        return "*" in self.enabled or name in self.enabled


@dataclass(frozen=True, slots=True)
class BulkProfile:
    """``[bulk]``: the relay receives ATR images over UDT, spools and verifies them,
    publishes them on DDS and forwards them to downstream receivers."""

    listen: str
    directory: Path
    spool: Path | None = None
    forward: tuple[str, ...] = ()
    quota_bytes: int | None = None
    max_rate_bps: int | None = None
    forward_lanes: int = 1
    keys: Path | None = None
    publish_data: bool = True


@dataclass(frozen=True, slots=True)
class RelayProfile:
    """A whole deployment profile."""

    jaus_id: JausAddress = field(default_factory=lambda: JausAddress(200, 1, 1))
    authority: int = 100
    name: str = "edge-vis"
    links: tuple[LinkProfile, ...] = ()
    dds: DdsProfile = field(default_factory=DdsProfile)
    translators: TranslatorSelection = TranslatorSelection()
    discovery: DiscoveryProfile = DiscoveryProfile()
    control: ControlProfile = ControlProfile()
    events: EventsProfile = EventsProfile()
    commands: CommandProfile = CommandProfile()
    report_rates: Mapping[str, float] = field(default_factory=dict)
    vehicles: tuple[VehicleProfile, ...] = ()
    jsidl: tuple[Path, ...] = ()
    source: str = ""
    report_minimums: Mapping[str, float] = field(default_factory=dict)
    report_priorities: Mapping[str, int] = field(default_factory=dict)
    #: who may request control (:mod:`edge_vis.config.operators`); a profile file that lists no
    #: ``[[operators]]`` refuses everyone unless ``access.any_operator = true``
    operators: OperatorPolicy = field(default_factory=OperatorPolicy.open)
    limits: LimitsProfile = field(default_factory=LimitsProfile)
    bulk: BulkProfile | None = None

    def vehicle_by_subsystem(self, subsystem: int) -> VehicleProfile | None:
        """The vehicle profile claiming JAUS ``subsystem``, if any."""
        for vehicle in self.vehicles:
            if vehicle.subsystem == subsystem:
                return vehicle
        return None

    def report_rate(self, report: str, default: float, vehicle: VehicleProfile | None) -> float:
        """Rate in Hz for ``report``: vehicle override, then deployment, then ``default``."""
        if vehicle is not None and report in vehicle.report_rates:
            return vehicle.report_rates[report]
        return self.report_rates.get(report, default)

    def report_minimum(self, report: str, desired: float,
                       vehicle: VehicleProfile | None) -> float:
        """Minimum useful rate of ``report`` (default: a tenth of ``desired``)."""
        if vehicle is not None and report in vehicle.report_minimums:
            value = vehicle.report_minimums[report]
        else:
            value = self.report_minimums.get(report, desired * DEFAULT_MINIMUM_SHARE)
        return min(value, desired)

    def report_priority(self, report: str, vehicle: VehicleProfile | None) -> int:
        """Planning priority of ``report``: higher is degraded later (default 5)."""
        if vehicle is not None and report in vehicle.report_priorities:
            return vehicle.report_priorities[report]
        return self.report_priorities.get(report, DEFAULT_REPORT_PRIORITY)


#: minimum useful rate of a report without one in the profile, as a share of its rate
DEFAULT_MINIMUM_SHARE = 0.1
#: planning priority of a report without one in the profile
DEFAULT_REPORT_PRIORITY = 5


# -- validation machinery ---------------------------------------------------------------


class _Problems:
    """Collects ``(file, key path, message)`` triples."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str, str]] = []

    def add(self, file: str, path: str, message: str) -> None:
        self.items.append((file, path, message))


class _Reader:
    """Typed access to one TOML table, recording problems instead of raising."""

    def __init__(self, data: Mapping[str, Any], file: str, path: str, problems: _Problems):
        self.data = data
        self.file = file
        self.path = path
        self.problems = problems
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def problem(self, name: str, message: str) -> None:
        self.problems.add(self.file, self.key(name), message)

    def get(self, name: str, kind: type | tuple[type, ...], default: T,
            check: Callable[[Any], str | None] | None = None) -> Any:
        self.used.add(name)
        if name not in self.data:
            return default
        value = self.data[name]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if float in kinds and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if isinstance(value, bool) and bool not in kinds:
            ok = False
        else:
            ok = isinstance(value, kinds)
        if not ok:
            names = " or ".join(k.__name__ for k in kinds)
            self.problem(name, f"expected {names}, got {type(value).__name__} {value!r}")
            return default
        if check is not None:
            message = check(value)
            if message:
                self.problem(name, message)
                return default
        return value

    def table(self, name: str) -> _Reader:
        self.used.add(name)
        value = self.data.get(name, {})
        if not isinstance(value, Mapping):
            self.problem(name, f"expected a table, got {type(value).__name__}")
            value = {}
        return _Reader(value, self.file, self.key(name), self.problems)

    def finish(self) -> None:
        """Flag keys nobody asked for: a typo must not be silently ignored."""
        for name in self.data:
            if name not in self.used:
                self.problem(name, "unknown key")


def _positive(value: float) -> str | None:
    if not math.isfinite(value) or value <= 0:
        return f"must be a positive number, got {value!r}"
    return None


def _non_negative(value: float) -> str | None:
    if not math.isfinite(value) or value < 0:
        return f"must be zero or positive, got {value!r}"
    return None


def _byte(value: int) -> str | None:
    return None if 0 <= value <= 255 else f"must be in 0..255, got {value}"


def _address(reader: _Reader, name: str, default: JausAddress | None) -> JausAddress | None:
    text = reader.get(name, str, None)
    if text is None:
        return default
    try:
        address = JausAddress.parse(text)
    except ValueError as exc:
        reader.problem(name, str(exc))
        return default
    return address


def _rates(reader: _Reader) -> dict[str, float]:
    return _report_table(reader)[0]


def _report_table(reader: _Reader) -> tuple[dict[str, float], dict[str, float], dict[str, int]]:
    """``[report_rates]``: ``Report = 5.0`` or ``Report = {desired = 5.0, minimum = 1.0,
    priority = 7}``; returns (desired rates, minimum rates, priorities)."""
    rates: dict[str, float] = {}
    minimums: dict[str, float] = {}
    priorities: dict[str, int] = {}
    for report in reader.data:
        if isinstance(reader.data[report], Mapping):
            sub = reader.table(report)
            desired = sub.get("desired", float, None, _positive)
            if "desired" not in sub.data:
                sub.problem("desired", "missing: the rate (Hz) wanted when the link allows")
            minimum = sub.get("minimum", float, None, _positive)
            priority = sub.get("priority", int, None,
                               lambda v: None if 0 <= v <= 9 else f"must be in 0..9, got {v}")
            sub.finish()
            if desired is not None:
                rates[report] = desired
                if minimum is not None and minimum > desired:
                    sub.problem("minimum", f"{minimum:g} Hz is above the desired "
                                           f"{desired:g} Hz")
            if minimum is not None:
                minimums[report] = minimum
            if priority is not None:
                priorities[report] = priority
            continue
        rate = reader.get(report, float, None, _positive)
        if rate is not None:
            rates[report] = rate
    return rates, minimums, priorities


def _str_list(reader: _Reader, name: str, default: tuple[str, ...]) -> tuple[str, ...]:
    values = reader.get(name, list, None)
    if values is None:
        return default
    out = []
    for i, item in enumerate(values):
        if not isinstance(item, str):
            reader.problem(f"{name}[{i}]", f"expected str, got {type(item).__name__}")
        else:
            out.append(item)
    return tuple(out)


def _link_spec(sub: _Reader, base_dir: Path | None, problems: _Problems) -> LinkSpec | None:
    """The medium of a link: ``profile = "name"`` and/or the link-profile keys inline."""
    inline = {k: v for k, v in sub.data.items() if k in SPEC_KEYS}
    sub.used.update(inline)
    profile_name = sub.get("profile", str, "")
    if not profile_name and not inline:
        return None
    found: list[tuple[str, str, str]] = []
    base = None
    if profile_name:
        base = load_link_spec(profile_name, base_dir=base_dir, file=sub.file,
                              path=sub.key("profile"), problems=found)
    spec = read_link_spec(inline, file=sub.file, path=sub.path, problems=found,
                          base=base or LinkSpec(source=sub.file))
    if not profile_name and "bit_rate" not in inline:
        found.append((sub.file, sub.key("bit_rate"),
                      "missing: name a link 'profile' or give the link's bit_rate"))
    for item in found:
        problems.add(*item)
    return None if found else spec


# -- vehicles ---------------------------------------------------------------------------


def _service(item: Any, reader: _Reader, key: str) -> ServiceProfile | None:
    if isinstance(item, str):
        return ServiceProfile(item)
    if not isinstance(item, Mapping):
        reader.problem(key, "expected a URI string or a table {uri, version}")
        return None
    sub = _Reader(item, reader.file, reader.key(key), reader.problems)
    uri = sub.get("uri", str, "")
    version = sub.get("version", (str, float), "1.0")
    sub.finish()
    if not uri.startswith("urn:"):
        sub.problem("uri", f"service URI {uri!r} does not start with 'urn:'")
        return None
    return ServiceProfile(uri, str(version))


def _vehicle(data: Mapping[str, Any], file: str, path: str, problems: _Problems,
             base_dir: Path | None) -> VehicleProfile | None:
    if "file" in data:
        ref = _Reader(data, file, path, problems)
        name = ref.get("file", str, "")
        ref.finish()
        if not name:
            return None
        target = Path(name)
        if not target.is_absolute() and base_dir is not None:
            target = base_dir / target
        try:
            with open(target, "rb") as stream:
                loaded = tomllib.load(stream)
        except OSError as exc:
            ref.problem("file", f"cannot read {target}: {exc.strerror or exc}")
            return None
        except tomllib.TOMLDecodeError as exc:
            problems.add(str(target), "", f"invalid TOML: {exc}")
            return None
        return _vehicle(loaded, str(target), "", problems, target.parent)
    reader = _Reader(data, file, path, problems)
    vehicle_id = reader.get("vehicle_id", str, "")
    if not vehicle_id:
        reader.problem("vehicle_id", "missing: every vehicle needs a vehicle_id")
    subsystem = reader.get("subsystem", int, None,
                           lambda v: None if 1 <= v <= 65534 else f"must be in 1..65534, got {v}")
    address = _address(reader, "address", None)
    components: list[ComponentProfile] = []
    services_raw = reader.get("services", list, [])
    if address is not None:
        if subsystem is None:
            subsystem = address.subsystem
        elif subsystem != address.subsystem:
            reader.problem("address", f"subsystem {address.subsystem} differs from "
                                      f"subsystem = {subsystem}")
        services = [s for i, item in enumerate(services_raw)
                    if (s := _service(item, reader, f"services[{i}]")) is not None]
        if services:
            components.append(ComponentProfile(address, tuple(services)))
    elif services_raw:
        reader.problem("services", "static services need an 'address'")
    for i, item in enumerate(reader.get("components", list, [])):
        key = f"components[{i}]"
        if not isinstance(item, Mapping):
            reader.problem(key, "expected a table {address, services}")
            continue
        sub = _Reader(item, file, reader.key(key), problems)
        comp_addr = _address(sub, "address", None)
        if comp_addr is None and "address" not in item:
            sub.problem("address", "missing")
        comp_services = [s for j, entry in enumerate(sub.get("services", list, []))
                         if (s := _service(entry, sub, f"services[{j}]")) is not None]
        sub.finish()
        if comp_addr is not None:
            if subsystem is None:
                subsystem = comp_addr.subsystem
            elif comp_addr.subsystem != subsystem:
                sub.problem("address", f"subsystem {comp_addr.subsystem} differs from "
                                       f"the vehicle's {subsystem}")
            components.append(ComponentProfile(comp_addr, tuple(comp_services)))
    rates, minimums, priorities = _report_table(reader.table("report_rates"))
    name = reader.get("name", str, "")
    vehicle_type = reader.get("vehicle_type", str, "")
    link = reader.get("link", str, "")
    reader.finish()
    if not vehicle_id:
        return None
    return VehicleProfile(vehicle_id, subsystem, name, vehicle_type, link, tuple(components),
                          rates, file, minimums, priorities)


# -- the deployment profile -------------------------------------------------------------


def from_mapping(data: Mapping[str, Any], *, file: str = "",
                 base_dir: Path | None = None,
                 any_operator_default: bool = True) -> RelayProfile:
    """Validate a parsed deployment profile; raise ConfigError listing every problem.

    ``base_dir`` resolves relative ``file =`` vehicle references and JSIDL paths.
    ``any_operator_default``: ``access.any_operator`` when the mapping does not say;
    :func:`load_profile` (deployment files) passes False, so they fail closed.
    """
    problems = _Problems()
    root = _Reader(data, file, "", problems)

    relay = root.table("relay")
    jaus_id = _address(relay, "jaus_id", JausAddress(200, 1, 1)) or JausAddress(200, 1, 1)
    if jaus_id.is_broadcast:
        relay.problem("jaus_id", f"{jaus_id} is a broadcast address")
    authority = relay.get("authority", int, 100, _byte)
    name = relay.get("name", str, "edge-vis")
    relay.finish()

    links: list[LinkProfile] = []
    links_table = root.table("links")
    for link_name, value in links_table.data.items():
        links_table.used.add(link_name)
        if not isinstance(value, Mapping):
            links_table.problem(link_name, "expected a table {url, bandwidth}")
            continue
        sub = links_table.table(link_name)
        url = sub.get("url", str, "")
        if not url:
            sub.problem("url", "missing")
        elif not urlsplit(url).scheme:
            sub.problem("url", f"{url!r} has no scheme (e.g. udp://0.0.0.0:3794)")
        bandwidth = sub.get("bandwidth", int, 0, lambda v: None if v >= 0 else "must be >= 0")
        options = sub.get("options", dict, {})
        spec = _link_spec(sub, base_dir, problems)
        sub.finish()
        if url:
            links.append(LinkProfile(link_name, url, bandwidth, options, spec))

    dds_t = root.table("dds")
    dds = DdsProfile(dds_t.get("domain", int, 0,
                               lambda v: None if 0 <= v <= 232 else f"must be in 0..232, got {v}"),
                     _str_list(dds_t, "partitions", ()))
    dds_t.finish()

    tr = root.table("translators")
    translator_options: dict[str, Mapping[str, Any]] = {}
    for key, value in tr.data.items():
        if key not in ("enabled", "disabled") and isinstance(value, Mapping):
            tr.used.add(key)  # a translator's own table, checked by the translator
            translator_options[key] = dict(value)
    translators = TranslatorSelection(_str_list(tr, "enabled", ("*",)),
                                      _str_list(tr, "disabled", ()), translator_options)
    tr.finish()

    d = root.table("discovery")
    discovery = DiscoveryProfile(
        d.get("period", float, 5.0, _positive),
        d.get("liveness_period", float, 1.0, _positive),
        d.get("lost_after", float, 3.0, _positive),
        d.get("response_timeout", float, 3.0, _positive),
    )
    d.finish()

    c = root.table("control")
    control = ControlProfile(
        c.get("renewal_period", float, 2.0, _positive),
        c.get("response_timeout", float, 2.0, _positive),
        c.get("retry_period", float, 5.0, _positive),
        c.get("max_ready_attempts", int, 3, _non_negative),
    )
    c.finish()

    e = root.table("events")
    events = EventsProfile(
        e.get("response_timeout", float, 3.0, _positive),
        e.get("attempts", int, 2, _non_negative),
        e.get("default_refresh", float, 60.0, _positive),
    )
    e.finish()

    m = root.table("commands")
    commands = CommandProfile(
        m.get("rate", float, 10.0, _positive),
        m.get("lifespan", float, 0.5, _positive),
        m.get("deadman_timeout", float, 1.0, _positive),
    )
    m.finish()

    report_rates, report_minimums, report_priorities = _report_table(root.table("report_rates"))
    operators = _operators(root, any_operator_default)
    limits = _limits(root)

    vehicles: list[VehicleProfile] = []
    for i, item in enumerate(root.get("vehicles", list, [])):
        key = f"vehicles[{i}]"
        if not isinstance(item, Mapping):
            problems.add(file, key, "expected a table")
            continue
        vehicle = _vehicle(item, file, key, problems, base_dir)
        if vehicle is not None:
            vehicles.append(vehicle)
    seen_ids: dict[str, int] = {}
    seen_subsystems: dict[int, str] = {}
    link_names = {link.name for link in links}
    for i, vehicle in enumerate(vehicles):
        key = f"vehicles[{i}]"
        if vehicle.vehicle_id in seen_ids:
            problems.add(file, f"{key}.vehicle_id",
                         f"duplicate vehicle_id {vehicle.vehicle_id!r}")
        seen_ids[vehicle.vehicle_id] = i
        if vehicle.subsystem is not None:
            other = seen_subsystems.get(vehicle.subsystem)
            if other is not None:
                problems.add(file, f"{key}.subsystem", f"subsystem {vehicle.subsystem} "
                                                       f"already belongs to {other!r}")
            seen_subsystems[vehicle.subsystem] = vehicle.vehicle_id
        if vehicle.link and vehicle.link not in link_names:
            problems.add(vehicle.source, f"{key}.link" if vehicle.source == file else "link",
                         f"unknown link {vehicle.link!r} (links: "
                         f"{', '.join(sorted(link_names)) or 'none'})")
        if vehicle.subsystem == jaus_id.subsystem:
            problems.add(vehicle.source, f"{key}.subsystem" if vehicle.source == file
                         else "subsystem", f"subsystem {vehicle.subsystem} is the relay's own")

    bulk = _bulk(root.table("bulk"), base_dir) if "bulk" in root.data else None

    cat = root.table("catalogue")
    jsidl = []
    for i, entry in enumerate(_str_list(cat, "jsidl", ())):
        path = Path(entry)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        if not path.exists():
            cat.problem(f"jsidl[{i}]", f"no such file: {path}")
        jsidl.append(path)
    cat.finish()
    root.finish()

    if problems.items:
        raise ConfigError(problems.items)
    return RelayProfile(jaus_id, authority, name, tuple(links), dds, translators, discovery,
                        control, events, commands, report_rates, tuple(vehicles), tuple(jsidl),
                        file, report_minimums, report_priorities, operators, limits, bulk)


def _bulk(b: _Reader, base_dir: Path | None) -> BulkProfile | None:
    """``[bulk] listen, dir, spool, forward, quota, max_rate, forward_lanes, keys, ...``."""

    def path(value: str) -> Path:
        p = Path(value)
        return base_dir / p if base_dir is not None and not p.is_absolute() else p

    def host_port(value: str) -> str | None:
        host, _, port = value.rpartition(":")
        return None if host and port.isdigit() and int(port) < 65536 else \
            f"{value!r} is not HOST:PORT"

    for required, what in (("listen", "HOST:PORT to receive on"), ("dir", "where images go")):
        if required not in b.data:
            b.problem(required, f"missing ({what})")
    listen = b.get("listen", str, "", host_port)
    directory = b.get("dir", str, "")
    spool = b.get("spool", str, "")
    forward = _str_list(b, "forward", ())
    for i, target in enumerate(forward):
        problem = host_port(target)
        if problem:
            b.problem(f"forward[{i}]", problem)
    quota = b.get("quota", int, 0, _non_negative)
    max_rate = b.get("max_rate", int, 0, _non_negative)
    lanes = b.get("forward_lanes", int, 1,
                  lambda v: None if 1 <= v <= 16 else f"must be 1..16, got {v}")
    keys = b.get("keys", str, "")
    if keys and not path(keys).is_file():
        b.problem("keys", f"no such file: {path(keys)}")
    publish_data = b.get("publish_data", bool, True)
    b.finish()
    if not listen or not directory:
        return None
    return BulkProfile(listen, path(directory), path(spool) if spool else None, forward,
                       quota or None, max_rate or None, lanes, path(keys) if keys else None,
                       publish_data)


def _operators(root: _Reader, any_operator_default: bool) -> OperatorPolicy:
    """``[[operators]] {id, max_authority}`` and ``[access] any_operator``.

    ``any_operator`` defaults to ``any_operator_default`` only when no operator is
    listed: a list is an allowlist unless the profile opens it explicitly.
    """
    allowed: dict[str, int] = {}
    for i, item in enumerate(root.get("operators", list, [])):
        key = f"operators[{i}]"
        if not isinstance(item, Mapping):
            root.problem(key, "expected a table {id, max_authority}")
            continue
        sub = _Reader(item, root.file, key, root.problems)
        operator_id = sub.get("id", str, "")
        max_authority = sub.get("max_authority", int, 255, _byte)
        sub.finish()
        if not operator_id:
            sub.problem("id", "missing: every operator needs an id")
        elif operator_id in allowed:
            sub.problem("id", f"duplicate operator id {operator_id!r}")
        else:
            allowed[operator_id] = max_authority
    access = root.table("access")
    listed = bool(root.data.get("operators"))
    any_operator = access.get("any_operator", bool, any_operator_default and not listed)
    access.finish()
    return OperatorPolicy(MappingProxyType(allowed), any_operator)


def _limits(root: _Reader) -> LimitsProfile:
    t = root.table("limits")

    def at_least_one(value: int) -> str | None:
        return None if value >= 1 else f"must be at least 1, got {value}"

    base = LimitsProfile()
    limits = LimitsProfile(
        t.get("max_vehicles", int, base.max_vehicles, at_least_one),
        t.get("max_routes", int, base.max_routes, at_least_one),
        t.get("max_duplicates", int, base.max_duplicates, at_least_one),
        t.get("max_unidentified", int, base.max_unidentified, at_least_one),
        t.get("max_products", int, base.max_products, at_least_one),
    )
    t.finish()
    return limits


def load_profile(path: str | Path) -> RelayProfile:
    """Read and validate the deployment profile at ``path``."""
    path = Path(path)
    try:
        with open(path, "rb") as stream:
            data = tomllib.load(stream)
    except OSError as exc:
        raise ConfigError([(str(path), "", f"cannot read: {exc.strerror or exc}")]) from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([(str(path), "", f"invalid TOML: {exc}")]) from exc
    return from_mapping(data, file=str(path), base_dir=path.parent, any_operator_default=False)


def default_profile_path() -> Path:
    """Where the built-in default deployment profile lives.

    ``profiles/default.toml`` next to the ``edge_vis`` package (source checkout or
    editable install); otherwise the copy shipped inside the package.
    """
    package = Path(__file__).resolve().parents[1]
    beside = package.parent / "profiles" / "default.toml"
    if beside.is_file():
        return beside
    return package / "data" / "default.toml"


def load_default_profile() -> RelayProfile:
    """The built-in default deployment profile."""
    return load_profile(default_profile_path())
