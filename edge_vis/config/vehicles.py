"""Vehicle profiles: what is known about a vehicle in advance. No I/O.

A vehicle profile is a table inline in a deployment's ``[[vehicles]]``, or a file of its
own (``profiles/vehicles/*.toml``) that a deployment references with ``file =``::

    vehicle_id = "ugv-static"          # required: the vehicle's id on DDS
    subsystem = 150                    # ties a discovered JAUS subsystem to this id
    name = "Static UGV"
    vehicle_type = "UGV"
    link = "radio"                     # a [links.NAME] of the deployment
    address = "150.1.1"                # a robot that does not answer discovery: its
    services = ["urn:jaus:jss:core:Management"]   # component and services, or
    [[components]]                     # several components
    address = "150.1.2"
    services = [{ uri = "urn:jaus:jss:mobility:PrimitiveDriver", version = "1.0" }]
    [report_rates]
    ReportGlobalPose = 1.0

A vehicle that does not answer JAUS Discovery may be found from what it sends instead,
declared in a ``[discovery]`` table (:class:`VehicleDiscovery`): a *hello* message of the
user's JSIDL whose fields give the vehicle's JAUS ID, id, name, type and services, or
*passive* discovery, where the first message from the subsystem declares the vehicle. A
profile with a ``[discovery]`` table and no ``subsystem`` describes a family: every vehicle
that sends the hello (or, passive, one of ``messages``) is declared, its ``vehicle_id``
from the hello (``vehicle_id_field``) or its name and subsystem::

    vehicle_type = "AUV"
    [discovery]
    hello = "VendorHello"
    address_field = "jaus_id"          # S.N.C of the vehicle (default: the sender)
    name_field = "vehicle_name"
    type_field = "vehicle_type"        # an enumeration: its label is the type
    services_field = "services"        # a list of {uri, major_version, minor_version}

:func:`read_vehicle` builds a :class:`VehicleProfile` from such a table with the
validation kit (:mod:`edge_vis.schema`); what needs the deployment (link names, duplicate
ids) is checked by the deployment loader.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any, ClassVar

from edge_vis.config.report_rates import REPORT_RATES, split_rates
from edge_vis.jaus.address import JausAddress
from edge_vis.schema import Reader, setting


def _urn(uri: str) -> str | None:
    return None if uri.startswith("urn:") else f"service URI {uri!r} does not start with 'urn:'"


@dataclass(frozen=True, slots=True)
class ServiceProfile:
    """A service a component offers: URI and ``major.minor`` version; a bare string is
    the URI."""

    toml_shorthand: ClassVar[str] = "uri"

    uri: str = setting(check=_urn, doc="the service URI (urn:...)")
    version: str = setting("1.0", read_as=str | float, convert=str)


@dataclass(frozen=True, slots=True)
class ComponentProfile:
    """A component of a statically described vehicle."""

    address: JausAddress = setting(doc="the component's JAUS address S.N.C")
    services: tuple[ServiceProfile, ...] = ()


def _dialect(name: str) -> str | None:
    from edge_vis.catalogue import default_catalogue

    known = default_catalogue().dialects()
    if name in known:
        return None
    return f"no dialect {name!r} (dialects: {', '.join(sorted(known)) or 'none'})"


def _hello_field(path: str) -> str | None:
    return None if all(path.split(".")) else f"{path!r}: a dotted field path of the hello"


@dataclass(frozen=True, slots=True)
class VehicleDiscovery:
    """How a vehicle that does not answer JAUS Discovery is found.

    ``hello``: the message (of the catalogue, the profile's JSIDL included) that announces
    a vehicle; the ``*_field`` keys are paths of its fields. ``passive``: the first message
    from the subsystem (or any of ``messages`` from any subsystem) declares the vehicle,
    its services those that the catalogue says declare the messages it sends, plus
    ``services``. Such a vehicle is alive while it sends anything: without a Liveness or
    Management service it is never asked for a sign of life, and is lost after
    ``silence_timeout`` seconds of silence (0: the deployment's).
    """

    hello: str = ""
    passive: bool = False
    messages: tuple[str, ...] = ()
    address_field: str = setting("", check=_hello_field)
    vehicle_id_field: str = setting("", check=_hello_field)
    name_field: str = setting("", check=_hello_field)
    type_field: str = setting("", check=_hello_field)
    services_field: str = setting("", check=_hello_field)
    #: in each element of ``services_field``: the URI and version fields (an element that
    #: is a string is the URI itself)
    service_uri: str = "uri"
    service_major: str = "major_version"
    service_minor: str = "minor_version"
    services: tuple[ServiceProfile, ...] = ()
    silence_timeout: float = setting(0.0, ge=0, unit="s")

    def validate(self) -> Iterator[tuple[str, str]]:
        """Exactly one way to be found; hello keys only with a hello."""
        if bool(self.hello) == self.passive:
            yield "hello", "give either hello = \"MESSAGE\" or passive = true"
        if self.passive:
            for key in self.hello_fields():
                yield key, "only a hello has fields to read (passive = true)"
        if self.hello and self.messages:
            yield "messages", "only passive discovery takes messages"

    def hello_fields(self) -> dict[str, str]:
        """The hello's field paths by key (those given)."""
        return {key: getattr(self, key) for key in (
            "address_field", "vehicle_id_field", "name_field", "type_field",
            "services_field") if getattr(self, key)}


@dataclass(frozen=True, slots=True)
class VehicleProfile:
    """What is known about a vehicle in advance.

    ``subsystem`` ties a discovered JAUS subsystem to this ``vehicle_id``. With
    ``components`` the vehicle is *static*: it is declared at start-up with those
    services, and standard discovery (identification, services) is not needed for it.
    ``report_rates`` (Hz, by report message name) override the deployment's rates.
    ``discovery`` says how a vehicle without JAUS Discovery is found; with it and no
    ``subsystem`` the profile is a family and ``vehicle_id`` comes from each vehicle.
    ``dialects`` names the message dialects it speaks when its services do not tell.
    """

    vehicle_id: str = ""
    subsystem: int | None = setting(None, ge=1, le=65534)
    name: str = ""
    vehicle_type: str = ""
    link: str = ""
    components: tuple[ComponentProfile, ...] = ()
    report_rates: Mapping[str, float] = setting(factory=dict, custom=True)
    discovery: VehicleDiscovery | None = None
    #: the message dialects it speaks (``manipulator-1.0``, ``iop``); None: recognised
    #: from the services it reports; [] : the base definitions only
    dialects: tuple[str, ...] | None = setting(
        None, check=_dialect, doc="message dialects it speaks (default: recognised from "
                                  "its services)")
    source: str = setting("", toml=False)
    #: minimum useful rate (Hz) and planning priority (higher = kept longer) by report
    report_minimums: Mapping[str, float] = setting(factory=dict, key="report_rates",
                                                   custom=True)
    report_priorities: Mapping[str, int] = setting(factory=dict, key="report_rates",
                                                   custom=True)

    @property
    def is_static(self) -> bool:
        """True when the profile lists the vehicle's components and services."""
        return bool(self.components)

    @property
    def is_family(self) -> bool:
        """True for a discovery profile that any number of subsystems may match."""
        return self.discovery is not None and self.subsystem is None

    def validate(self) -> Iterator[tuple[str, str]]:
        """A vehicle_id (unless a family's); components in the vehicle's subsystem."""
        if not self.vehicle_id and not (self.discovery is not None and not self.subsystem
                                        and not self.components):
            yield "vehicle_id", "missing (every vehicle needs a vehicle_id; only a " \
                                "[discovery] profile without a subsystem may leave it out)"
        if self.discovery is not None and self.discovery.passive and self.subsystem is None \
                and not self.discovery.messages:
            yield "discovery.passive", "passive discovery needs a subsystem, or the " \
                                       "messages that declare a vehicle (messages = [...])"
        if self.discovery is not None and self.components:
            yield "discovery", "a static vehicle (components) is not discovered"
        for i, component in enumerate(self.components):
            if self.subsystem is not None and component.address.subsystem != self.subsystem:
                yield (f"components[{i}].address", f"subsystem {component.address.subsystem} "
                                                   f"differs from the vehicle's {self.subsystem}")


def read_vehicle(reader: Reader, table: Any, path: str = "") -> VehicleProfile | None:
    """A vehicle profile table (inline or a whole file) -> :class:`VehicleProfile`.

    ``address`` and ``services`` are the short form of one component; the subsystem, when
    not given, is the components'.
    """
    vehicle = reader.read(VehicleProfile, table, path, values={"source": reader.file},
                          handled=("address", "services"))
    if vehicle is None:
        return None
    at = f"{path}." if path else ""
    address = reader.take(table, "address", JausAddress, path)
    services = reader.take(table, "services", tuple[ServiceProfile, ...], path, ())
    rates = reader.take(table, "report_rates", REPORT_RATES, path, {})
    components = vehicle.components
    if address is not None:
        if vehicle.subsystem is not None and address.subsystem != vehicle.subsystem:
            reader.problem(f"{at}address", f"subsystem {address.subsystem} differs from "
                                           f"subsystem = {vehicle.subsystem}")
        if services:
            components = (ComponentProfile(address, services), *components)
    elif services:
        reader.problem(f"{at}services", "static services need an 'address'")
    subsystem = vehicle.subsystem
    if subsystem is None and (address is not None or components):
        subsystem = address.subsystem if address is not None else components[0].address.subsystem
        for i, component in enumerate(vehicle.components):
            if component.address.subsystem != subsystem:
                reader.problem(f"{at}components[{i}].address",
                               f"subsystem {component.address.subsystem} differs from the "
                               f"vehicle's {subsystem}")
    desired, minimums, priorities = split_rates(rates)
    return replace(vehicle, subsystem=subsystem, components=components, report_rates=desired,
                   report_minimums=minimums, report_priorities=priorities)
