"""Where one ``edge-vis demo`` runs: loopback addresses, pty paths and a DDS domain.

Several demos - or a demo beside a simulator or relay started by hand - must be able to
share one computer, so a demo does not simply bind the addresses its profiles name.
Address *slot* 0 is the profiles as written (``127.0.0.10``-``12:3794`` for the shipped
fleet); slot ``n`` moves every loopback address ``127.a.b.c`` to ``127.77.n.c`` (the JAUS
port stays unless something holds it there) and the fleet's pseudo-terminal links into
the run's own folder. The DDS domain is the lowest one nobody on this computer uses.

Two checks decide what is free. Demos *claim* a slot or a domain with an abstract Unix
socket (Linux): binding one is atomic, and the kernel drops it however the demo ends, so
two demos started at the same instant never pick the same one and a crashed demo leaves
nothing behind. Any other program is found by *probing*: binding the UDP address (or a
domain's Cyclone DDS discovery ports) briefly, without address reuse.

Does I/O: binds and closes sockets. Rewriting profiles (:func:`move_fleet`,
:func:`move_relay`, :func:`dump_toml`) works on parsed TOML and does none.
"""

from __future__ import annotations

import copy
import errno
import json
import re
import socket
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

from edge_vis.errors import EdgeVisError

#: second octet of the loopback addresses of slots 1 and up
MOVED_NET = 77
#: how many address slots a computer offers demos
SLOTS = 200
#: DDS domain ids whose Cyclone port numbers fit in 16 bits
DDS_DOMAINS = range(0, 233)
#: participants per domain the loopback DDS configuration allows (see edge_vis.dds)
DDS_PARTICIPANTS = 32
JUDP_PORT = 3794

Address = tuple[str, int]


class PlacementError(EdgeVisError):
    """No free slot or DDS domain was found."""


# -- claims and probes --------------------------------------------------------------------


class Claim:
    """A name this process holds until :meth:`release` or its exit (abstract Unix socket)."""

    def __init__(self, sock: socket.socket | None) -> None:
        self._sock = sock

    def release(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def claim(name: str) -> Claim | None:
    """Hold ``name`` among demos on this computer; None when another process holds it.

    Where abstract sockets do not exist (not Linux) every claim succeeds and only the
    probes protect a demo.
    """
    if not sys.platform.startswith("linux"):
        return Claim(None)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    try:
        sock.bind(f"\0edge-vis-demo/{name}")
    except OSError as exc:
        sock.close()
        return None if exc.errno == errno.EADDRINUSE else Claim(None)
    return Claim(sock)


def udp_free(host: str, port: int) -> bool:
    """Whether ``host:port`` can be bound now (no reuse: any holder, wildcard too, counts)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def free_udp_port(host: str) -> int:
    """A UDP port the kernel considers free on ``host`` right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def dds_ports(domain: int, participants: int = DDS_PARTICIPANTS) -> list[int]:
    """Cyclone DDS's UDP ports of ``domain``: discovery and data, multicast and per participant."""
    base = 7400 + 250 * domain
    return [base, base + 1] + [base + 10 + 2 * i + k for i in range(participants)
                               for k in (0, 1)]


def dds_domain_free(domain: int) -> bool:
    """Whether no DDS participant on this computer uses ``domain``."""
    return all(udp_free("0.0.0.0", port) for port in dds_ports(domain))


# -- placement ----------------------------------------------------------------------------


@dataclass
class Placement:
    """Where a demo runs; :meth:`release` (or exit) lets another demo have it."""

    slot: int
    domain: int
    addresses: dict[Address, Address] = field(default_factory=dict)
    claims: list[Claim] = field(default_factory=list)

    @property
    def moved(self) -> bool:
        """Whether anything differs from the profiles as written."""
        return any(a != b for a, b in self.addresses.items())

    def address(self, host: str, port: int) -> Address:
        """Where ``host:port`` of the profiles is in this run."""
        return self.addresses.get((host, port), (host, port))

    def release(self) -> None:
        for item in self.claims:
            item.release()
        self.claims.clear()


def is_loopback(host: str) -> bool:
    return host.startswith("127.")


def moved_hosts(hosts: Iterable[str], slot: int) -> dict[str, str]:
    """Loopback ``hosts`` moved to slot ``slot``: ``127.a.b.c`` -> ``127.77.slot.c``."""
    unique = list(dict.fromkeys(h for h in hosts if is_loopback(h)))
    lasts = [h.rsplit(".", 1)[1] for h in unique]
    if len(set(lasts)) != len(lasts):  # two hosts end alike: number them instead
        lasts = [str(10 + i) for i in range(len(unique))]
    return {h: f"127.{MOVED_NET}.{slot}.{last}" for h, last in zip(unique, lasts, strict=True)}


def _slot_addresses(wanted: list[Address], slot: int, *, any_port: bool
                    ) -> dict[Address, Address] | None:
    """``wanted`` moved to ``slot``; None when an address there is taken (and not
    ``any_port``) or cannot be bound at all."""
    hosts = moved_hosts((h for h, _ in wanted), slot)
    out: dict[Address, Address] = {}
    for host, port in wanted:
        if host not in hosts:
            out[(host, port)] = (host, port)
            continue
        new = (hosts[host], port)
        if not udp_free(*new):
            if not any_port:
                return None
            try:
                new = (hosts[host], free_udp_port(hosts[host]))
            except OSError:
                return None
        out[(host, port)] = new
    return out


def place_addresses(wanted: Iterable[Address]) -> tuple[int, dict[Address, Address], Claim]:
    """A slot whose addresses are free: the ones given if possible, else moved ones."""
    wanted = list(dict.fromkeys(wanted))
    for any_port in (False, True):
        for slot in range(SLOTS):
            held = claim(f"slot/{slot}")
            if held is None:
                continue
            if slot == 0:
                if all(udp_free(*a) for a in wanted):
                    return 0, {a: a for a in wanted}, held
            else:
                mapping = _slot_addresses(wanted, slot, any_port=any_port)
                if mapping is not None:
                    return slot, mapping, held
            held.release()
    raise PlacementError("no free loopback addresses for the demo (every slot is taken)")


def place_domain() -> tuple[int, Claim]:
    """The lowest DDS domain no demo has claimed and no participant here uses."""
    for domain in DDS_DOMAINS:
        held = claim(f"domain/{domain}")
        if held is None:
            continue
        if dds_domain_free(domain):
            return domain, held
        held.release()
    raise PlacementError("no free DDS domain on this computer; give one with --domain")


def place(wanted: Iterable[Address], domain: int | None, *, as_written: bool = False
          ) -> Placement:
    """Addresses for ``wanted`` and a DDS domain (``domain`` when given).

    With ``as_written`` the addresses are used as they are (the profiles name them).
    """
    placement = Placement(slot=0, domain=domain if domain is not None else 0)
    try:
        if as_written:
            placement.addresses = {a: a for a in wanted}
        else:
            placement.slot, placement.addresses, held = place_addresses(wanted)
            placement.claims.append(held)
        if domain is None:
            placement.domain, held = place_domain()
            placement.claims.append(held)
    except BaseException:
        placement.release()
        raise
    return placement


# -- moving profiles ----------------------------------------------------------------------


def _host_port(url: str, default_port: int = JUDP_PORT) -> Address | None:
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        return None
    if not parts.hostname:
        return None
    return parts.hostname, port if port is not None else default_port


def fleet_addresses(data: Mapping[str, Any]) -> list[Address]:
    """The UDP addresses the vehicles of a parsed simulation profile bind (JAUS links and
    UDT image servers)."""
    out = []
    for vehicle in data.get("vehicles", []) or []:
        link = vehicle.get("link") if isinstance(vehicle, Mapping) else None
        if isinstance(link, str) and link.startswith("udp:"):
            address = _host_port(link)
            if address is not None:
                out.append(address)
        served = vehicle.get("image_server") if isinstance(vehicle, Mapping) else None
        if isinstance(served, str) and served:
            address = _host_port(f"udp://{served}")
            if address is not None and address[1]:
                out.append(address)
    return out


def relay_addresses(data: Mapping[str, Any]) -> list[Address]:
    """The loopback UDP addresses the links of a parsed relay profile bind."""
    out = []
    for link in (data.get("links") or {}).values():
        url = link.get("url") if isinstance(link, Mapping) else None
        if isinstance(url, str) and url.startswith("udp:"):
            address = _host_port(url)
            if address is not None and is_loopback(address[0]):
                out.append(address)
    return out


def move_fleet(data: Mapping[str, Any], placement: Placement, folder: Path
               ) -> tuple[dict[str, Any], dict[str, str]]:
    """A parsed simulation profile moved to ``placement``, and its moved paths (old -> new).

    Pseudo-terminal links, their path files and ATR image folders go into ``folder``.
    """
    out = copy.deepcopy(dict(data))
    paths: dict[str, str] = {}
    for vehicle in out.get("vehicles", []) or []:
        if not isinstance(vehicle, dict):
            continue
        name = str(vehicle.get("name", "vehicle"))
        link = vehicle.get("link")
        if isinstance(link, str) and link.startswith("udp:"):
            address = _host_port(link)
            if address is not None:
                vehicle["link"] = "udp://{}:{}".format(*placement.address(*address))
        served = vehicle.get("image_server")
        if isinstance(served, str) and served:
            address = _host_port(f"udp://{served}")
            if address is not None:
                vehicle["image_server"] = "{}:{}".format(*placement.address(*address))
        for key, new in (("pty_link", folder / f"{name}.pty"),
                         ("pty_path_file", folder / f"{name}.pty-path"),
                         ("atr_dir", folder / "atr")):
            old = vehicle.get(key)
            if isinstance(old, str) and old:
                paths[old] = vehicle[key] = str(new)
    return out, paths


def move_url(url: str, placement: Placement, paths: Mapping[str, str]) -> str:
    """A link URL of a relay profile moved to ``placement`` (UDP addresses, serial paths)."""
    parts = urlsplit(url)
    if parts.scheme == "serial":  # urlunsplit would drop the empty host: serial:/dev/...
        tail = f"?{parts.query}" if parts.query else ""
        return f"serial://{parts.netloc}{paths.get(parts.path, parts.path)}{tail}"
    if parts.scheme != "udp":
        return url
    bind = _host_port(url)
    netloc = parts.netloc
    if bind is not None:
        netloc = "{}:{}".format(*placement.address(*bind))
    options: list[tuple[str, str]] = []
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key == "peers":
            peers = []
            for item in filter(None, (p.strip() for p in value.split(","))):
                host, sep, port = item.rpartition(":")
                if not sep:
                    host, port = item, str(JUDP_PORT)
                if not port.isdigit():  # not ours to judge: the relay reports it
                    peers.append(item)
                    continue
                peers.append("{}:{}".format(*placement.address(host, int(port))))
            value = ",".join(peers)
        options.append((key, value))
    return urlunsplit((parts.scheme, netloc, parts.path, urlencode(options, safe=",:/"),
                       parts.fragment))


def move_relay(data: Mapping[str, Any], placement: Placement, paths: Mapping[str, str]
               ) -> dict[str, Any]:
    """A parsed relay profile whose links reach the moved fleet from the moved relay."""
    out = copy.deepcopy(dict(data))
    for link in (out.get("links") or {}).values():
        if isinstance(link, dict) and isinstance(link.get("url"), str):
            link["url"] = move_url(link["url"], placement, paths)
    return out


# -- writing TOML -------------------------------------------------------------------------

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key, ensure_ascii=False)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def _table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, Mapping) for v in value)


def dump_toml(data: Mapping[str, Any], header: str = "") -> str:
    """``data`` (as :mod:`tomllib` reads it, no dates) as TOML; nested tables inline."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    for key, value in data.items():
        if not isinstance(value, Mapping) and not _table_array(value):
            lines.append(f"{_key(key)} = {_value(value)}")
    for key, value in data.items():
        tables = [value] if isinstance(value, Mapping) else value if _table_array(value) else []
        for table in tables:
            lines += ["", f"[{_key(key)}]" if isinstance(value, Mapping) else f"[[{_key(key)}]]"]
            lines += [f"{_key(k)} = {_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"
