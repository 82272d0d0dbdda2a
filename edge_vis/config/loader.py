"""Reading profiles: TOML files -> validated frozen dataclasses. Reads files.

:func:`load_profile` reads a deployment profile and :func:`from_mapping` validates one
already parsed; both read the files it references (vehicle profiles given with
``file =``, link profiles named by ``profile =``) and check that ``catalogue.jsidl`` and
``bulk.keys`` files exist. A profile file (:func:`load_profile`, what ``edge-vis run`` and
``edge-vis check`` read) also has every link URL validated by its link plugin exactly as
the relay opens it (:func:`edge_vis.routing.link.check_link_url`), without opening
anything; :func:`from_mapping` checks a URL's form only and imports no plugin.
:func:`load_vehicle_profile` reads a vehicle profile on its own.

Validation collects every problem before raising one :class:`~edge_vis.errors.ConfigError`
whose ``problems`` are ``(file, key path, message)`` triples, e.g.
``("profiles/site.toml", "vehicles[1].address", "JAUS address '1.2' is not of the form S.N.C")``.

The built-in default deployment is ``profiles/default.toml`` beside the package (found in
a source checkout or editable install) or, failing that, the copy packaged as
``edge_vis/data/default.toml``; :func:`default_profile_path` says which.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from edge_vis.bandwidth.linkspec import SPEC_KEYS, LinkSpec, load_link_spec, read_link_spec
from edge_vis.config.deployment import AccessProfile, LinkProfile, OperatorEntry, RelayProfile
from edge_vis.config.operators import OperatorPolicy
from edge_vis.config.report_rates import REPORT_RATES, split_rates
from edge_vis.config.vehicles import VehicleProfile, read_vehicle
from edge_vis.errors import ConfigError, PluginError
from edge_vis.routing.link import check_link_url
from edge_vis.schema import Reader


def read_toml(path: str | Path) -> dict[str, Any]:
    """The parsed TOML file at ``path``; ConfigError when unreadable or invalid."""
    path = Path(path)
    try:
        with open(path, "rb") as stream:
            return tomllib.load(stream)
    except OSError as exc:
        raise ConfigError([(str(path), "", f"cannot read: {exc.strerror or exc}")]) from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([(str(path), "", f"invalid TOML: {exc}")]) from exc


def load_profile(path: str | Path) -> RelayProfile:
    """Read and validate the deployment profile at ``path``, its links by their plugins."""
    path = Path(path)
    reader = Reader(str(path), base_dir=path.parent)
    profile = read_profile_file(reader, read_toml(path))
    reader.raise_problems()
    assert profile is not None
    return profile


def read_profile_file(reader: Reader, data: Mapping[str, Any]) -> RelayProfile | None:
    """What :func:`load_profile` checks in a parsed deployment profile file (and so what
    ``edge-vis check`` does): the schema, the files it references, and every link by the
    plugin that would open it. Problems are left in ``reader``."""
    profile = read_deployment(reader, data, any_operator_default=False)
    if profile is not None:
        for link in profile.links:
            for key, reason in link_problems(link):
                reader.problem(f"links.{link.name}.{key}", reason)
    return profile


def from_mapping(data: Mapping[str, Any], *, file: str = "",
                 base_dir: Path | None = None,
                 any_operator_default: bool = True) -> RelayProfile:
    """Validate a parsed deployment profile; raise ConfigError listing every problem.

    ``base_dir`` resolves relative ``file =`` vehicle references and paths.
    ``any_operator_default``: ``access.any_operator`` when the mapping does not say;
    :func:`load_profile` (deployment files) passes False, so they fail closed.
    """
    reader = Reader(file, base_dir=base_dir)
    profile = read_deployment(reader, data, any_operator_default=any_operator_default)
    reader.raise_problems()
    assert profile is not None
    return profile


def read_deployment(reader: Reader, data: Mapping[str, Any], *,
                    any_operator_default: bool = False) -> RelayProfile | None:
    """A parsed deployment profile -> :class:`RelayProfile`, problems left in ``reader``."""
    relay = reader.read(RelayProfile, data, handled=("access",))
    if relay is None:
        return None
    rates = reader.take(data, "report_rates", REPORT_RATES, "", {})
    desired, minimums, priorities = split_rates(rates)
    profile = replace(
        relay, source=reader.file, links=tuple(_links(reader, data.get("links"))),
        vehicles=tuple(_vehicles(reader, data.get("vehicles"))), report_rates=desired,
        report_minimums=minimums, report_priorities=priorities,
        operators=_operators(reader, data, any_operator_default))
    _check_vehicles(reader, profile)
    _check_routing(reader, profile)
    _check_files(reader, profile)
    return profile


def load_vehicle_profile(path: str | Path) -> VehicleProfile:
    """Read and validate a vehicle profile file on its own (as a deployment's
    ``file =`` reference reads it)."""
    path = Path(path)
    reader = Reader(str(path), base_dir=path.parent)
    vehicle = read_vehicle(reader, read_toml(path))
    reader.raise_problems()
    assert vehicle is not None
    return vehicle


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


# -- links ---------------------------------------------------------------------------------


def _links(reader: Reader, table: Any) -> list[LinkProfile]:
    if table is None:
        return []
    if not isinstance(table, Mapping):
        reader.problem("links", "expected a table of [links.NAME] tables")
        return []
    links = []
    for name, item in table.items():
        path = f"links.{name}"
        if not isinstance(item, Mapping):
            reader.problem(path, "expected a table {url, bandwidth, options, profile, ...}")
            continue
        own = {k: v for k, v in item.items() if k not in SPEC_KEYS}
        link = reader.read(LinkProfile, own, path, values={"name": name})
        named = item.get("profile")
        spec = _link_spec(reader, item, named if isinstance(named, str) else "", path)
        if link is None:
            continue
        links.append(replace(link, spec=spec))
    return links


def _link_spec(reader: Reader, item: Mapping[str, Any], profile: str,
               path: str) -> LinkSpec | None:
    """The medium of a link: ``profile = "name"`` and/or the link-profile keys inline."""
    inline = {k: v for k, v in item.items() if k in SPEC_KEYS}
    if not profile and not inline:
        return None
    before = len(reader.problems)
    base = None
    if profile:
        base = load_link_spec(profile, base_dir=reader.base_dir, reader=reader,
                              path=f"{path}.profile")
    spec = read_link_spec(reader, inline, path, base=base or LinkSpec(source=reader.file))
    if not profile and "bit_rate" not in inline:
        reader.problem(f"{path}.bit_rate",
                       "missing: name a link 'profile' or give the link's bit_rate")
    return spec if len(reader.problems) == before else None


def _check_routing(reader: Reader, profile: RelayProfile) -> None:
    """Every link ``[routing] forward`` names must be one of ``[links]``."""
    names = [link.name for link in profile.links]
    for i, group in enumerate(profile.routing.forward):
        for name in dict.fromkeys(group):
            if name not in names:
                reader.problem(f"routing.forward[{i}]",
                               f"unknown link {name!r} (links: {', '.join(names) or 'none'})")


def link_problems(link: LinkProfile) -> list[tuple[str, str]]:
    """What the link plugin says of ``link`` (its URL with ``options`` and ``bandwidth``),
    as ``(key relative to the link's table, reason)``; opens nothing.

    The plugin is the one ``edge-vis run`` opens the link with, and it checks the URL the
    same way, so a URL that passes here does not fail there for its options.
    """
    query = dict(parse_qsl(urlsplit(link.url).query, keep_blank_values=True))
    problems = [(f"options.{key}", f"also given in the url ({key}={query[key]})")
                for key in link.options if key in query]
    try:
        check_link_url(link.link_url)
    except ConfigError as exc:
        for _file, key, reason in exc.problems:
            option = key.partition(".")[2]
            if option in link.options and option not in query:
                key = f"options.{option}"
            elif option == "bandwidth" and "bandwidth" not in query:
                key = "bandwidth"
            problems.append((key or "url", reason))
    except PluginError as exc:
        problems.append(("url", str(exc)))
    return problems


# -- vehicles and operators ---------------------------------------------------------------


def _vehicles(reader: Reader, items: Any) -> list[VehicleProfile]:
    if items is None:
        return []
    if not isinstance(items, list):
        reader.problem("vehicles", "expected an array of tables [[vehicles]]")
        return []
    vehicles = []
    for i, item in enumerate(items):
        path = f"vehicles[{i}]"
        if isinstance(item, Mapping) and "file" in item:
            vehicle = _vehicle_file(reader, item, path)
        else:
            vehicle = read_vehicle(reader, item, path)
        if vehicle is not None:
            vehicles.append(vehicle)
    return vehicles


def _vehicle_file(reader: Reader, item: Mapping[str, Any], path: str) -> VehicleProfile | None:
    """A ``{file = "vehicles/x.toml"}`` entry: the vehicle profile of that file."""
    for key in item:
        if key != "file":
            reader.problem(f"{path}.{key}", "unknown key (a vehicle given by 'file' is "
                                            "described in that file)")
    name = reader.take(item, "file", str, path, "")
    if not name:
        return None
    target = Path(name)
    if not target.is_absolute() and reader.base_dir is not None:
        target = reader.base_dir / target
    own = reader.for_file(str(target), target.parent)
    try:
        with open(target, "rb") as stream:
            data = tomllib.load(stream)
    except OSError as exc:
        reader.problem(f"{path}.file", f"cannot read {target}: {exc.strerror or exc}")
        return None
    except tomllib.TOMLDecodeError as exc:
        own.problem("", f"invalid TOML: {exc}")
        return None
    return read_vehicle(own, data)


def _check_vehicles(reader: Reader, profile: RelayProfile) -> None:
    """Vehicles must not collide with each other, the relay or the links.

    A problem of a vehicle described in its own file is reported in that file.
    """
    ids: set[str] = set()
    subsystems: dict[int, str] = {}
    families: dict[str, str] = {}
    link_names = {link.name for link in profile.links}
    for i, vehicle in enumerate(profile.vehicles):
        key = f"vehicles[{i}]"
        inline = vehicle.source == reader.file
        own = reader.for_file(vehicle.source)

        def where(name: str, key: str = key, inline: bool = inline) -> str:
            return f"{key}.{name}" if inline else name

        if vehicle.vehicle_id and vehicle.vehicle_id in ids:
            reader.problem(f"{key}.vehicle_id", f"duplicate vehicle_id {vehicle.vehicle_id!r}")
        ids.add(vehicle.vehicle_id)
        if vehicle.is_family and vehicle.discovery is not None:
            for claim in ((vehicle.discovery.hello,) if vehicle.discovery.hello
                          else vehicle.discovery.messages):
                other_key = families.get(claim)
                if other_key is not None:
                    reader.problem(f"{key}.discovery", f"{claim} already declares the "
                                                       f"vehicles of {other_key}")
                families[claim] = key
        if vehicle.subsystem is not None:
            other = subsystems.get(vehicle.subsystem)
            if other is not None:
                reader.problem(f"{key}.subsystem", f"subsystem {vehicle.subsystem} already "
                                                   f"belongs to {other!r}")
            subsystems[vehicle.subsystem] = vehicle.vehicle_id
            if vehicle.subsystem == profile.jaus_id.subsystem:
                own.problem(where("subsystem"), f"subsystem {vehicle.subsystem} is the "
                                                "relay's own")
        if vehicle.link and vehicle.link not in link_names:
            own.problem(where("link"), f"unknown link {vehicle.link!r} (links: "
                                       f"{', '.join(sorted(link_names)) or 'none'})")


def _operators(reader: Reader, data: Mapping[str, Any],
               any_operator_default: bool) -> OperatorPolicy:
    """``[[operators]] {id, max_authority}`` and ``[access] any_operator``.

    ``any_operator`` defaults to ``any_operator_default`` only when no operator is
    listed: a list is an allowlist unless the profile opens it explicitly.
    """
    items = data.get("operators", [])
    if not isinstance(items, list):
        reader.problem("operators", "expected an array of tables [[operators]]")
        items = []
    allowed: dict[str, int] = {}
    for i, item in enumerate(items):
        entry = reader.read(OperatorEntry, item, f"operators[{i}]")
        if entry is None or not entry.id:
            continue
        if entry.id in allowed:
            reader.problem(f"operators[{i}].id", f"duplicate operator id {entry.id!r}")
            continue
        allowed[entry.id] = entry.max_authority
    access = reader.read(AccessProfile, data.get("access", {}), "access") or AccessProfile()
    any_operator = access.any_operator
    if any_operator is None:
        any_operator = any_operator_default and not items
    return OperatorPolicy(MappingProxyType(allowed), any_operator)


def _check_files(reader: Reader, profile: RelayProfile) -> None:
    """Files the relay reads at start must exist (nothing else is read here)."""
    for i, path in enumerate(profile.jsidl):
        if not path.exists():
            reader.problem(f"catalogue.jsidl[{i}]", f"no such file: {path}")
    keys = profile.bulk.keys if profile.bulk is not None else None
    if keys is not None and not keys.is_file():
        reader.problem("bulk.keys", f"no such file: {keys}")
