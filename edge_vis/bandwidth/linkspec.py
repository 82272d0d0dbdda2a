"""Radio link profiles: what a link can carry and how edge-vis may use it. Reads files.

A link profile (``profiles/links/*.toml``, or inline in a deployment's ``[links.NAME]``
table) describes the medium, not the transport plugin::

    bit_rate = 9600          # usable bit/s of the medium (after FEC, before framing)
    overhead = 18            # bytes the medium adds per packet (JAUS serial framing...)
    mtu = 256                # largest JAUS payload per packet; larger messages fragment
    latency = 0.05           # one-way latency, s (turn-around of a half-duplex radio)
    half_duplex = true       # both directions share the air time
    bits_per_byte = 10       # 10 on an asynchronous serial line (8N1), 8 otherwise
    duty_cycle = 1.0         # share of time the radio may transmit (regulatory limits)
    budget = 0.8             # share of the usable rate edge-vis may use
    reserve = 0.1            # share of that budget kept for commands and control

    [priorities]             # JAUS header priority (0..3) per traffic class
    control = 3
    command = 3
    liveness = 2
    telemetry = 1
    bulk = 0

:class:`LinkSpec` is the schema of such a table: the validation kit (:mod:`edge_vis.schema`)
reads it, so each key's type, default and range is written once, on its field, and every
problem is recorded as ``(file, key path, message)`` for ``edge-vis check`` to list.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from edge_vis.schema import Reader, setting, toml_keys

#: traffic classes, most urgent first; the scheduler serves them in this order
TRAFFIC_CLASSES: tuple[str, ...] = ("control", "command", "liveness", "telemetry", "bulk")

DEFAULT_PRIORITIES: Mapping[str, int] = {
    "control": 3, "command": 3, "liveness": 2, "telemetry": 1, "bulk": 0,
}


@dataclass(frozen=True, slots=True)
class LinkSpec:
    """The medium of one link. ``bit_rate`` 0 = unknown: nothing is planned for it."""

    bit_rate: float = setting(0.0, ge=0, le=1e12, unit="bit/s")
    overhead: int = setting(18, ge=0, le=4096, unit="bytes")
    mtu: int = setting(4079, ge=32, le=4079, unit="bytes")
    latency: float = setting(0.0, ge=0, le=60, unit="s")
    half_duplex: bool = True
    duty_cycle: float = setting(1.0, gt=0, le=1)
    budget: float = setting(0.8, gt=0, le=1)
    reserve: float = setting(0.1, ge=0, le=0.9)
    bits_per_byte: int = setting(8, ge=8, le=12)
    priorities: Mapping[str, int] = setting(factory=lambda: dict(DEFAULT_PRIORITIES), ge=0,
                                            le=3, keys=TRAFFIC_CLASSES, merge=True)
    description: str = ""
    source: str = setting("", toml=False)

    @property
    def limited(self) -> bool:
        """True when the link has a known rate, i.e. is planned and paced."""
        return self.bit_rate > 0

    @property
    def capacity_bytes(self) -> float:
        """Bytes per second the medium carries (duty cycle applied)."""
        return self.bit_rate / self.bits_per_byte * self.duty_cycle

    @property
    def budget_bytes(self) -> float:
        """Bytes per second edge-vis plans to use."""
        return self.capacity_bytes * self.budget

    @property
    def planned_bytes(self) -> float:
        """Bytes per second the rate planner may fill (the budget less the reserve that
        operators' commands and access control need)."""
        return self.budget_bytes * (1.0 - self.reserve)

    @property
    def budget_bps(self) -> float:
        """The budget as 8-bit bytes per second x 8 (what the router paces at)."""
        return self.budget_bytes * 8

    def serialization_time(self, payload: int) -> float:
        """Seconds one packet of ``payload`` bytes occupies the medium."""
        if not self.limited:
            return 0.0
        return (payload + 14 + self.overhead) / self.capacity_bytes

    def with_rate(self, bit_rate: float) -> LinkSpec:
        """The same link at a measured ``bit_rate``."""
        return replace(self, bit_rate=bit_rate)

    def priority_of(self, traffic_class: str) -> int:
        """JAUS header priority of ``traffic_class``."""
        return self.priorities.get(traffic_class, DEFAULT_PRIORITIES.get(traffic_class, 1))

    def validate(self) -> Iterator[tuple[str, str]]:
        """Telemetry must never delay commands or access control on a busy link."""
        priorities = {**DEFAULT_PRIORITIES, **self.priorities}
        if min(priorities["command"], priorities["control"]) < priorities["telemetry"]:
            yield "priorities", "commands and control must not rank below telemetry"


#: keys of a link profile (inline or file)
SPEC_KEYS = toml_keys(LinkSpec)


def read_link_spec(reader: Reader, data: Mapping[str, Any], path: str = "",
                   base: LinkSpec | None = None) -> LinkSpec | None:
    """The link-profile keys of ``data`` (a link table of a deployment, or a whole link
    profile file) on top of ``base``; keys outside :data:`SPEC_KEYS` are the caller's."""
    own = {k: v for k, v in data.items() if k in SPEC_KEYS}
    base = base or LinkSpec(source=reader.file)
    return reader.read(LinkSpec, own, path, base=base)


def read_link_profile(reader: Reader, data: Mapping[str, Any]) -> LinkSpec | None:
    """A whole link profile file (``profiles/links/*.toml``): it must give its bit rate."""
    if "bit_rate" not in data:
        reader.problem("bit_rate", "missing: a link profile needs its bit rate")
    before = len(reader.problems)
    spec = reader.read(LinkSpec, data, "", base=LinkSpec(source=reader.file))
    return spec if "bit_rate" in data and len(reader.problems) == before else None


def link_profile_dirs(base_dir: Path | None) -> list[Path]:
    """Where a link profile named without a path is looked for."""
    dirs = []
    if base_dir is not None:
        dirs += [base_dir / "links", base_dir.parent / "links", base_dir]
    dirs.append(Path(__file__).resolve().parents[1] / "data" / "links")  # shipped, in the package
    return dirs


def find_link_profile(name: str, base_dir: Path | None) -> Path | None:
    """The file of link profile ``name`` (``serial-9600`` or a path to a ``.toml``)."""
    candidate = Path(name)
    if candidate.suffix == ".toml" or "/" in name:
        if not candidate.is_absolute() and base_dir is not None:
            candidate = base_dir / candidate
        return candidate if candidate.is_file() else None
    for directory in link_profile_dirs(base_dir):
        path = directory / f"{name}.toml"
        if path.is_file():
            return path
    return None


def load_link_spec(name: str, *, base_dir: Path | None, reader: Reader,
                   path: str) -> LinkSpec | None:
    """Read link profile ``name`` (see :func:`find_link_profile`) for the key ``path`` of
    ``reader``'s file; None on a problem, which ``reader`` records."""
    target = find_link_profile(name, base_dir)
    if target is None:
        reader.problem(path, f"no link profile {name!r} (looked in "
                             f"{', '.join(str(d) for d in link_profile_dirs(base_dir))})")
        return None
    own = reader.for_file(str(target), target.parent)
    try:
        with open(target, "rb") as stream:
            data = tomllib.load(stream)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        own.problem("", f"cannot read link profile: {exc}")
        return None
    return read_link_profile(own, data)
