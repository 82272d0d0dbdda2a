"""The deployment profile's schema: one relay's settings as frozen dataclasses. No I/O.

A *deployment profile* describes one relay: its JAUS address and authority, its radio
links, the DDS domain, which translators run, the discovery/liveness/command timing, the
report rates and the vehicles it knows in advance. These dataclasses are its schema: the
validation kit (:mod:`edge_vis.schema`) reads the TOML file against them, so each
setting's type, default, range and TOML key is written here once. The file layout::

    [relay]          jaus_id, authority, name           -> RelayProfile
    [links.NAME]     url, bandwidth, options, profile   -> LinkProfile (+ LinkSpec keys)
    [routing]        forward                            -> RoutingProfile
    [dds]            domain, partitions                 -> DdsProfile
    [dds.security]   identity_ca, certificate, ...      -> DdsSecurityProfile
    [serving]        relay_name, preference, prefer, hysteresis, heartbeat, lease, settle
    [translators]    enabled, disabled, [translators.NAME] tables -> TranslatorSelection
    [discovery] [control] [events] [commands] [emergency] [limits] [bulk]
    [report_rates]   Report = Hz or {desired, minimum, priority} (edge_vis.config.report_rates)
    [[vehicles]]     inline tables or {file = "..."} (edge_vis.config.vehicles)
    [[operators]]    id, max_authority; [access] any_operator  -> OperatorPolicy
    [catalogue]      jsidl = [files]

Reading the file and the files it references is :mod:`edge_vis.config.loader`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit

from edge_vis.bandwidth.linkspec import LinkSpec
from edge_vis.config.operators import OperatorPolicy
from edge_vis.config.report_rates import DEFAULT_MINIMUM_SHARE, DEFAULT_REPORT_PRIORITY
from edge_vis.config.vehicles import VehicleProfile
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.routing.link import LinkUrl
from edge_vis.schema import setting


def _link_url(url: str) -> str | None:
    """The URL's form only: what the plugin of its scheme says is the loader's to ask."""
    try:
        LinkUrl.parse(url)
    except ConfigError as exc:
        return exc.problems[0][2]
    return None


def _not_broadcast(address: JausAddress) -> str | None:
    return f"{address} is a broadcast address" if address.is_broadcast else None


def _host_port(value: str) -> str | None:
    host, _, port = value.rpartition(":")
    if host and port.isdigit() and int(port) < 65536:
        return None
    return f"{value!r} is not HOST:PORT"


def _non_empty(text: str) -> str | None:
    return None if text else "must not be empty"


def _option_text(value: Any) -> str:
    """A TOML option value as the text a URL query carries."""
    if isinstance(value, bool):
        return "1" if value else "0"
    return str(value)


@dataclass(frozen=True, slots=True)
class LinkProfile:
    """A radio or wired link ``[links.NAME]``. ``bandwidth`` in bit/s, 0 = unknown/unlimited.

    ``options`` are query options of the link plugin given as a table instead of in the
    URL. ``spec`` describes the medium (``profile = "serial-9600"`` naming a file of
    ``profiles/links/``, and/or the same keys inline): the rate planner and the link
    scheduler work from it. Without it only ``bandwidth`` paces the link.
    """

    name: str = setting(toml=False)
    url: str = setting(check=_link_url, doc="the link's URL, e.g. udp://0.0.0.0:3794")
    bandwidth: int = setting(0, ge=0, unit="bit/s")
    options: Mapping[str, str | int | float | bool] = setting(factory=dict)
    spec: LinkSpec | None = setting(None, toml=False)
    #: the link profile (file) ``spec`` starts from, by name or path
    profile: str = ""

    @property
    def scheme(self) -> str:
        """The URL scheme, which is also the link plugin's entry-point name."""
        return urlsplit(self.url).scheme

    @property
    def link_url(self) -> str:
        """The URL the link is opened with: ``url`` with ``options`` and ``bandwidth``
        added to its query (what the URL itself says is kept)."""
        query = dict(parse_qsl(urlsplit(self.url).query, keep_blank_values=True))
        extra = {k: _option_text(v) for k, v in self.options.items() if k not in query}
        if self.bandwidth and "bandwidth" not in query and "bandwidth" not in extra:
            extra["bandwidth"] = str(self.bandwidth)
        if not extra:
            return self.url
        separator = "&" if "?" in self.url else "?"
        return f"{self.url}{separator}{urlencode(extra)}"


@dataclass(frozen=True, slots=True)
class RoutingProfile:
    """``[routing]``: JAUS traffic the relay passes between its links, as a JAUS node
    manager does (``AllowRelay`` in the JAUS Toolset).

    ``forward`` lists groups of link names, e.g. ``[["lan", "radio"]]``: a message that
    arrives on one link of a group for a component behind another link of it is passed
    on, both ways, between every two links of the group. Off by default: without it,
    nothing crosses from one link to another; the relay only answers and commands what it
    serves itself. Which names are links is checked against ``[links]`` by the loader.
    """

    forward: tuple[tuple[str, ...], ...] = setting((), check=_non_empty)

    def validate(self) -> list[tuple[str, str]]:
        problems = []
        for i, group in enumerate(self.forward):
            twice = sorted({name for name in group if group.count(name) > 1})
            if twice:
                problems.append((f"forward[{i}]", f"link {twice[0]!r} is forwarded to "
                                                  "itself (named twice in one group)"))
            elif len(group) < 2:
                problems.append((f"forward[{i}]", "name at least two links to forward "
                                                  "between, e.g. [\"lan\", \"radio\"]"))
        return problems

    def pairs(self) -> frozenset[tuple[str, str]]:
        """Every (from link, to link) forwarded, both ways."""
        return frozenset((a, b) for group in self.forward for a in group for b in group
                         if a != b)


@dataclass(frozen=True, slots=True)
class DiscoveryProfile:
    """Discovery and liveness timing, in seconds.

    A vehicle is declared lost after ``lost_after`` liveness periods without any message.
    """

    period: float = setting(5.0, gt=0, unit="s")
    liveness_period: float = setting(1.0, gt=0, unit="s")
    lost_after: float = setting(3.0, gt=0)
    response_timeout: float = setting(3.0, gt=0, unit="s")

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

    ``holder_query_period``: how often each component with AccessControl is asked who
    controls it (QueryControl, QueryAuthority), besides right after control changes; 0 =
    only on changes. ``authority_from_operator``: the relay holds JAUS control with the
    holding operator's authority (capped at ``relay.authority``) instead of its own, and
    follows the operator's changes (SetAuthority to lower it, RequestControl to raise it).

    ``handoff_timeout``: how long the holding operator has to answer a hand-off request
    (HandoffRequest) before the requester is told TIMEOUT; ``handoff_reassert_timeout``:
    how long a requester may stay silent before its request lapses (it publishes the
    request again to keep it); 0 disables either, as in IOP EnhancedAccessControl. A
    request another JAUS client makes through the vehicle lapses after the vehicle's own
    hand-off timeout when it reports one.
    """

    renewal_period: float = setting(2.0, gt=0, unit="s")
    response_timeout: float = setting(2.0, gt=0, unit="s")
    retry_period: float = setting(5.0, gt=0, unit="s")
    max_ready_attempts: int = setting(3, ge=0)
    holder_query_period: float = setting(30.0, ge=0, unit="s")
    authority_from_operator: bool = False
    handoff_timeout: float = setting(30.0, ge=0, unit="s")
    handoff_reassert_timeout: float = setting(0.0, ge=0, unit="s")


@dataclass(frozen=True, slots=True)
class TimeProfile:
    """The vehicles' clocks (JAUS Time service).

    Each component offering Time is asked ReportTime on discovery and every
    ``query_period`` seconds (0 = on discovery only); the clock offset is published. With
    ``set_on_discovery`` a vehicle whose clock is off by more than ``set_threshold``
    seconds when it is discovered gets SetTime (the relay takes control of the Time
    component for it, as the Time service requires, and releases it afterwards).
    """

    query_period: float = setting(30.0, ge=0, unit="s")
    set_on_discovery: bool = False
    set_threshold: float = setting(1.0, gt=0, unit="s")


@dataclass(frozen=True, slots=True)
class EventsProfile:
    """JAUS event subscription timing.

    After ``attempts`` unanswered CreateEvent requests (``response_timeout`` s each), the
    report is polled instead. ``default_refresh`` is the renewal period when the provider
    does not report its event timeout.
    """

    response_timeout: float = setting(3.0, gt=0, unit="s")
    attempts: int = setting(2, ge=0)
    default_refresh: float = setting(60.0, gt=0, unit="s")


@dataclass(frozen=True, slots=True)
class CommandProfile:
    """Command throttling: max rate (Hz) per vehicle and kind, lifespan and dead-man (s)."""

    rate: float = setting(10.0, gt=0, unit="Hz")
    lifespan: float = setting(0.5, gt=0, unit="s")
    deadman_timeout: float = setting(1.0, gt=0, unit="s")


@dataclass(frozen=True, slots=True)
class EmergencyProfile:
    """``[emergency]``: who may set and clear an emergency stop through the relay, and how
    hard the relay tries to deliver it.

    The relay sends SetEmergency under its own JAUS id, so only the relay can clear it
    (the Management service accepts ClearEmergency only from a client that set one);
    these rules say which operators the relay does it for.

    * ``set_by``: ``"operators"`` - any operator the profile lets command through the
      relay ([[operators]] / access.any_operator, within its maximum authority);
      ``"anyone"`` - any station on the data model, listed or not.
    * ``clear_by``: ``"setter"`` - only the operator who set it; ``"authority"`` - the
      setter or any allowed operator asking with at least the setter's authority;
      ``"operators"`` - any allowed operator.
    * ``on_operator_lost``: set the emergency when the operator holding a vehicle
      vanishes (its DDS writers are gone), not only the dead-man stop.
    * ``retry_period``/``max_attempts``: SetEmergency (ClearEmergency) is sent again every
      ``retry_period`` until each component reports EMERGENCY (no longer EMERGENCY), at
      most ``max_attempts`` times per component and per time the vehicle is found.
    """

    set_by: str = setting("operators", choices=("operators", "anyone"))
    clear_by: str = setting("authority", choices=("setter", "authority", "operators"))
    on_operator_lost: bool = False
    retry_period: float = setting(0.25, gt=0, unit="s")
    max_attempts: int = setting(20, ge=1)


#: operators write commands in ``operator.<id>`` under DDS Security (see DdsSecurityProfile)
OPERATOR_PARTITION_PREFIX = "operator."


def operator_partition(operator_id: str) -> str:
    """The DDS partition ``operator_id``'s permissions confine its command writes to."""
    return f"{OPERATOR_PARTITION_PREFIX}{operator_id}"


@dataclass(frozen=True, slots=True)
class DdsSecurityProfile:
    """``[dds.security]``: the relay's DDS Security files (``edge-vis security init``
    writes them and prints this table).

    With it the relay joins only authenticated, encrypted DDS, and reads each listed
    operator's commands from that operator's own partition (``operator.<id>``), which
    only that operator's signed permissions let it write to: a command whose
    ``operator_id`` is not its partition's operator is refused and counted.
    ``crl``: the deployment CA's revocation list (optional; needed to revoke).
    """

    identity_ca: Path = setting(doc="the CA certificate identities are checked against")
    certificate: Path = setting(doc="the relay's identity certificate")
    private_key: Path = setting(doc="the relay's private key")
    permissions_ca: Path = setting(doc="the CA certificate the documents are signed by")
    governance: Path = setting(doc="the signed governance document")
    permissions: Path = setting(doc="the relay's signed permissions document")
    crl: Path | None = None


@dataclass(frozen=True, slots=True)
class DdsProfile:
    """The DDS domain and partitions the relay publishes in, and its DDS Security."""

    domain: int = setting(0, ge=0, le=232)
    partitions: tuple[str, ...] = ()
    security: DdsSecurityProfile | None = None


@dataclass(frozen=True, slots=True)
class ServingProfile:
    """``[serving]``: how relays on one DDS domain share the vehicles they reach.

    Every relay publishes ``RelayStatus`` every ``heartbeat`` seconds; a relay not heard
    for ``lease`` seconds is gone and its vehicles are taken over. ``relay_name`` names
    this relay on the data model (default: its JAUS id). ``preference`` is added to this
    relay's link quality (0..1) for every vehicle, and 1 more for the vehicles listed in
    ``prefer``: the best score serves, and a serving relay keeps a vehicle until another
    scores more than ``hysteresis`` above it. ``settle``: how long a relay's claim is out
    before it takes a vehicle nobody serves (its peers must have seen the claim).
    """

    relay_name: str = ""
    preference: float = setting(0.0, ge=0)
    prefer: tuple[str, ...] = ()
    hysteresis: float = setting(0.25, ge=0)
    heartbeat: float = setting(0.25, gt=0, unit="s")
    lease: float = setting(1.5, gt=0, unit="s")
    settle: float = setting(0.5, ge=0, unit="s")


@dataclass(frozen=True, slots=True)
class LimitsProfile:
    """Bounds on tables that grow with what the network sends (``[limits]``).

    Past a bound the newest entry is refused (vehicles, probes) or the oldest forgotten
    (routes), and a counter says so; nothing already accepted is lost.
    """

    max_vehicles: int = setting(256, ge=1)
    max_routes: int = setting(4096, ge=1)
    max_duplicates: int = setting(65536, ge=1)
    max_unidentified: int = setting(1024, ge=1)
    max_products: int = setting(256, ge=1)


@dataclass(frozen=True, slots=True)
class TranslatorSelection:
    """Which translators run. ``enabled`` of ``("*",)`` means every installed one.

    ``options`` are the sub-tables of ``[translators]`` by translator name (e.g.
    ``[[translators.generic.mappings]]``); each translator validates its own table
    against the options dataclass it declares.
    """

    enabled: tuple[str, ...] = ("*",)
    disabled: tuple[str, ...] = ()
    options: Mapping[str, Mapping[str, Any]] = setting(factory=dict, rest=True)

    def selects(self, name: str) -> bool:
        """True when translator ``name`` should run."""
        if name in self.disabled:
            return False
        return "*" in self.enabled or name in self.enabled


@dataclass(frozen=True, slots=True)
class BulkProfile:
    """``[bulk]``: the relay receives ATR images over UDT, spools and verifies them,
    publishes them on DDS and forwards them to downstream receivers."""

    listen: str = setting(check=_host_port, doc="HOST:PORT to receive on")
    directory: Path = setting(key="dir", doc="where images go")
    spool: Path | None = None
    forward: tuple[str, ...] = setting((), check=_host_port)
    #: bytes of spool (None: no quota; 0 in the file means none too)
    quota_bytes: int | None = setting(None, key="quota", ge=0, convert=lambda v: v or None)
    #: bit/s for forwarding (None: unlimited; 0 in the file means unlimited too)
    max_rate_bps: int | None = setting(None, key="max_rate", ge=0,
                                       convert=lambda v: v or None)
    #: parallel UDT connections per forwarded file; 0 adapts to the radio's loss and delay
    forward_lanes: int = setting(0, ge=0, le=16)
    keys: Path | None = None
    publish_data: bool = True
    #: vehicle id -> HOST:PORT of its image server (``serve-images``); "*" for any other.
    #: An image such a vehicle announces is fetched from there.
    sources: Mapping[str, str] = setting(factory=dict, check=_host_port)
    #: which announced image to fetch first
    fetch_priority: str = setting("confidence", choices=("confidence", "oldest", "newest"))
    #: bit/s the radio gives bulk data and JAUS together (0: no budget); fetches keep to
    #: what the relay's JAUS traffic leaves of it
    fetch_budget: int = setting(0, ge=0, unit="bit/s")


@dataclass(frozen=True, slots=True)
class OperatorEntry:
    """One ``[[operators]]`` entry: an operator station allowed to request control."""

    id: str = setting(doc="every operator needs an id", check=_non_empty)
    max_authority: int = setting(255, ge=0, le=255)


@dataclass(frozen=True, slots=True)
class AccessProfile:
    """``[access]``: ``any_operator`` admits operators the profile does not list.

    Not given, it is true only for a profile that lists no operator and is built in code
    (a profile file fails closed; see :mod:`edge_vis.config.operators`).
    """

    any_operator: bool | None = None


@dataclass(frozen=True, slots=True)
class RelayProfile:
    """A whole deployment profile."""

    jaus_id: JausAddress = setting(JausAddress(200, 1, 1), key="relay.jaus_id",
                                   check=_not_broadcast)
    authority: int = setting(100, key="relay.authority", ge=0, le=255)
    name: str = setting("edge-vis", key="relay.name")
    links: tuple[LinkProfile, ...] = setting((), custom=True)
    routing: RoutingProfile = field(default_factory=RoutingProfile)
    dds: DdsProfile = field(default_factory=DdsProfile)
    translators: TranslatorSelection = field(default_factory=TranslatorSelection)
    discovery: DiscoveryProfile = field(default_factory=DiscoveryProfile)
    control: ControlProfile = field(default_factory=ControlProfile)
    time: TimeProfile = field(default_factory=TimeProfile)
    events: EventsProfile = field(default_factory=EventsProfile)
    commands: CommandProfile = field(default_factory=CommandProfile)
    emergency: EmergencyProfile = field(default_factory=EmergencyProfile)
    report_rates: Mapping[str, float] = setting(factory=dict, custom=True)
    vehicles: tuple[VehicleProfile, ...] = setting((), custom=True)
    jsidl: tuple[Path, ...] = setting((), key="catalogue.jsidl")
    source: str = setting("", toml=False)
    report_minimums: Mapping[str, float] = setting(factory=dict, key="report_rates",
                                                   custom=True)
    report_priorities: Mapping[str, int] = setting(factory=dict, key="report_rates",
                                                   custom=True)
    #: who may request control (:mod:`edge_vis.config.operators`); a profile file that lists no
    #: ``[[operators]]`` refuses everyone unless ``access.any_operator = true``
    operators: OperatorPolicy = setting(factory=OperatorPolicy.open, custom=True)
    limits: LimitsProfile = field(default_factory=LimitsProfile)
    bulk: BulkProfile | None = None
    serving: ServingProfile = field(default_factory=ServingProfile)

    @property
    def relay_name(self) -> str:
        """This relay's name on the data model: ``[serving] relay_name`` or its JAUS id."""
        return self.serving.relay_name or str(self.jaus_id)

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
