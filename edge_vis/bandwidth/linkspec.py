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

:func:`read_link_spec` validates such a table and records ``(file, key path, message)``
problems instead of raising, so ``edge-vis check`` can list them all.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

#: traffic classes, most urgent first; the scheduler serves them in this order
TRAFFIC_CLASSES: tuple[str, ...] = ("control", "command", "liveness", "telemetry", "bulk")

DEFAULT_PRIORITIES: Mapping[str, int] = {
    "control": 3, "command": 3, "liveness": 2, "telemetry": 1, "bulk": 0,
}

#: keys of a link profile (inline or file)
SPEC_KEYS = frozenset({"bit_rate", "overhead", "mtu", "latency", "half_duplex", "duty_cycle",
                       "budget", "priorities", "description", "bits_per_byte", "reserve"})

Problem = tuple[str, str, str]


@dataclass(frozen=True, slots=True)
class LinkSpec:
    """The medium of one link. ``bit_rate`` 0 = unknown: nothing is planned for it."""

    bit_rate: float = 0.0
    overhead: int = 18
    mtu: int = 4079
    latency: float = 0.0
    half_duplex: bool = True
    duty_cycle: float = 1.0
    budget: float = 0.8
    reserve: float = 0.1
    bits_per_byte: int = 8
    priorities: Mapping[str, int] = field(default_factory=lambda: dict(DEFAULT_PRIORITIES))
    description: str = ""
    source: str = ""

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


def _check(problems: list[Problem], file: str, path: str) -> Callable[[str, str], None]:
    def add(key: str, message: str) -> None:
        problems.append((file, f"{path}.{key}" if path else key, message))
    return add


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def read_link_spec(data: Mapping[str, Any], *, file: str, path: str,
                   problems: list[Problem], base: LinkSpec | None = None) -> LinkSpec:
    """Validate the link-profile keys of ``data`` on top of ``base``.

    Keys outside :data:`SPEC_KEYS` are left to the caller (the deployment's link table
    also holds ``url`` and ``profile``).
    """
    add = _check(problems, file, path)
    spec = base or LinkSpec(source=file)
    values: dict[str, Any] = {}

    def real(key: str, low: float, high: float, *, open_low: bool = False) -> None:
        if key not in data:
            return
        value = _number(data[key])
        if value is None or not math.isfinite(value):
            add(key, f"expected a number, got {data[key]!r}")
        elif value < low or value > high or (open_low and value == low):
            bound = f"> {low:g}" if open_low else f">= {low:g}"
            add(key, f"must be {bound} and <= {high:g}, got {value:g}")
        else:
            values[key] = value

    real("bit_rate", 0.0, 1e12)
    real("latency", 0.0, 60.0)
    real("duty_cycle", 0.0, 1.0, open_low=True)
    real("budget", 0.0, 1.0, open_low=True)
    real("reserve", 0.0, 0.9)
    for key, low, high in (("overhead", 0, 4096), ("mtu", 32, 4079), ("bits_per_byte", 8, 12)):
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, int):
                add(key, f"expected an integer, got {value!r}")
            elif not low <= value <= high:
                add(key, f"must be in {low}..{high}, got {value}")
            else:
                values[key] = value
    if "half_duplex" in data:
        if isinstance(data["half_duplex"], bool):
            values["half_duplex"] = data["half_duplex"]
        else:
            add("half_duplex", f"expected true or false, got {data['half_duplex']!r}")
    if "description" in data:
        values["description"] = str(data["description"])
    if "priorities" in data:
        table = data["priorities"]
        if not isinstance(table, Mapping):
            add("priorities", "expected a table {class = 0..3}")
        else:
            priorities = dict(spec.priorities)
            for name, value in table.items():
                if name not in TRAFFIC_CLASSES:
                    add(f"priorities.{name}", "unknown traffic class (classes: "
                                              f"{', '.join(TRAFFIC_CLASSES)})")
                elif isinstance(value, bool) or not isinstance(value, int) \
                        or not 0 <= value <= 3:
                    add(f"priorities.{name}", f"must be a JAUS priority 0..3, got {value!r}")
                else:
                    priorities[name] = value
            if priorities["command"] < priorities["telemetry"] \
                    or priorities["control"] < priorities["telemetry"]:
                add("priorities", "commands and control must not rank below telemetry")
            values["priorities"] = priorities
    return replace(spec, **values)


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


def load_link_spec(name: str, *, base_dir: Path | None, file: str, path: str,
                   problems: list[Problem]) -> LinkSpec | None:
    """Read link profile ``name`` (see :func:`find_link_profile`); None on a problem."""
    target = find_link_profile(name, base_dir)
    if target is None:
        problems.append((file, path, f"no link profile {name!r} (looked in "
                                     f"{', '.join(str(d) for d in link_profile_dirs(base_dir))})"))
        return None
    try:
        with open(target, "rb") as stream:
            data = tomllib.load(stream)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        problems.append((str(target), "", f"cannot read link profile: {exc}"))
        return None
    before = len(problems)
    for key in data:
        if key not in SPEC_KEYS:
            problems.append((str(target), key, "unknown key"))
    if "bit_rate" not in data:
        problems.append((str(target), "bit_rate", "missing: a link profile needs its bit rate"))
    spec = read_link_spec(data, file=str(target), path="", problems=problems,
                          base=LinkSpec(source=str(target)))
    return spec if len(problems) == before else None
