"""The validation kit: dataclasses as the schema, one reader, every problem with its path.

Also: each schema's defaults live on its fields only (what the reader yields for an empty
table is the dataclass's own default), for every profile kind, link and translator.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import pytest

from edge_vis.bandwidth.linkspec import LinkSpec, read_link_profile
from edge_vis.config import (
    BulkProfile,
    CommandProfile,
    ControlProfile,
    DdsProfile,
    DiscoveryProfile,
    EventsProfile,
    LimitsProfile,
    RelayProfile,
    TranslatorSelection,
    from_mapping,
)
from edge_vis.config.vehicles import VehicleProfile, read_vehicle
from edge_vis.errors import ConfigError
from edge_vis.jaus.address import JausAddress
from edge_vis.routing.link import LinkOptions, check_link_url
from edge_vis.schema import Reader, read_table, setting
from edge_vis.tools.sim.profile import FaultSpec, SimProfile, VehicleSpec, parse_profile
from edge_vis.tools.testing import MemoryOptions
from translators.generic import GenericOptions
from translators.mobility import MobilityOptions


class Colour(enum.Enum):
    RED = "red"
    BLUE = "blue"


@dataclass(frozen=True, slots=True)
class Inner:
    toml_shorthand: ClassVar[str] = "size"

    size: int = setting(ge=1, le=10, doc="how big")
    label: str = ""


@dataclass(frozen=True, slots=True)
class Sample:
    name: str = setting(doc="what it is called")
    rate: float = setting(1.0, gt=0, le=100, unit="Hz")
    count: int = setting(3, key="limits.count", ge=0)
    on: bool = False
    mode: Literal["fast", "slow"] = "slow"
    colour: Colour = Colour.RED
    tags: tuple[str, ...] = ()
    weights: Mapping[str, float] = setting(factory=dict, ge=0)
    inner: Inner = field(default_factory=lambda: Inner(5))
    items: tuple[Inner, ...] = ()
    where: Path | None = None
    address: JausAddress | None = None
    low: int = setting(0, ge=0)
    high: int = setting(9, ge=0)

    def validate(self) -> Iterator[tuple[str, str]]:
        if self.high < self.low:
            yield "high", f"{self.high} is below low {self.low}"


def problems_of(data: Any, cls: type = Sample, **kwargs: Any) -> dict[str, str]:
    with pytest.raises(ConfigError) as info:
        read_table(cls, data, file="f.toml", **kwargs)
    assert all(f == "f.toml" for f, _k, _m in info.value.problems)
    return {key: message for _f, key, message in info.value.problems}


def test_a_table_becomes_the_dataclass(tmp_path: Path) -> None:
    sample = read_table(Sample, {
        "name": "x", "rate": 5, "limits": {"count": 7}, "on": True, "mode": "fast",
        "colour": "blue", "tags": ["a", "b"], "weights": {"w": 1}, "inner": {"label": "L"},
        "items": [3, {"size": 4, "label": "four"}], "where": "sub/file.txt",
        "address": "1.2.3",
    }, base_dir=tmp_path)
    assert sample == Sample(
        "x", 5.0, 7, True, "fast", Colour.BLUE, ("a", "b"), {"w": 1.0}, Inner(5, "L"),
        (Inner(3), Inner(4, "four")), tmp_path / "sub" / "file.txt", JausAddress(1, 2, 3))
    assert isinstance(sample.rate, float)


def test_defaults_are_the_fields_own() -> None:
    assert read_table(Sample, {"name": "x"}) == Sample("x")
    # a partial sub-table keeps the default instance's other values
    assert read_table(Sample, {"name": "x", "inner": {"label": "L"}}).inner == Inner(5, "L")


def test_every_kind_of_problem_is_named_with_its_key_path() -> None:
    problems = problems_of({
        "rate": "fast", "limits": {"count": -1, "extra": 1}, "on": "yes", "mode": "medium",
        "colour": "green", "tags": ["a", 3], "weights": {"w": -2.0},
        "items": [0, "big"], "address": "1.2", "colour2": 1,
    })
    assert problems == {
        "name": "missing: what it is called",
        "rate": "expected float (Hz), got str 'fast'",
        "limits.count": "must be at least 0, got -1",
        "limits.extra": "unknown key",
        "on": "expected bool, got str 'yes'",
        "mode": "'medium' is not one of fast, slow",
        "colour": "'green' is not one of red, blue",
        "tags[1]": "expected str, got int 3",
        "weights.w": "must be at least 0, got -2.0",
        "items[0]": "must be in 1..10, got 0",
        "items[1]": "expected int, got str 'big'",
        "address": "JAUS address '1.2' is not of the form S.N.C",
        "colour2": "unknown key",
    }


@pytest.mark.parametrize(("data", "key", "message"), [
    ({"rate": 0}, "rate", "must be > 0 and <= 100, got 0.0 Hz"),
    ({"rate": 101.5}, "rate", "must be > 0 and <= 100, got 101.5 Hz"),
    ({"rate": float("nan")}, "rate", "must be a finite number, got nan"),
    ({"limits": 3}, "limits", "expected a table, got int 3"),
    ({"inner": [1]}, "inner", "expected a table {size, label}"),
    ({"items": {"size": 1}}, "items", "expected an array of tables, got dict {'size': 1}"),
    ({"inner": {}, "items": [{}]}, "items[0].size", "missing: how big"),
])
def test_types_ranges_and_tables(data: dict[str, Any], key: str, message: str) -> None:
    assert problems_of({"name": "x", **data})[key] == message


def test_cross_field_checks_run_once_the_fields_are_valid() -> None:
    assert problems_of({"name": "x", "low": 5, "high": 2}) == {"high": "2 is below low 5"}
    # a refused value is not checked again: its default (9) stands in for it
    assert problems_of({"name": "x", "low": 20, "high": -1}) == {
        "high": "must be at least 0, got -1"}


def test_text_mode_reads_values_from_their_text() -> None:
    assert read_table(Sample, {"name": "x", "rate": "2.5", "on": "yes", "tags": "a, b",
                               "limits": {"count": "0x10"}}, text=True) == \
        Sample("x", 2.5, 16, True, tags=("a", "b"))
    assert problems_of({"name": "x", "rate": "fast", "on": "maybe"}, text=True) == {
        "rate": "rate='fast' is not a number",
        "on": "on='maybe' is not a boolean (1/0, true/false, yes/no, on/off)"}
    assert read_table(Sample, {"name": "x", "rate": ""}, text=True).rate == 1.0  # absent


def test_problems_of_several_files_share_one_list(tmp_path: Path) -> None:
    reader = Reader("main.toml")
    other = reader.for_file("other.toml")
    reader.read(Inner, {"size": 0})
    other.read(Inner, {"colour": 1}, "x")
    assert reader.problems == [("main.toml", "size", "must be in 1..10, got 0"),
                               ("other.toml", "x.size", "missing: how big"),
                               ("other.toml", "x.colour", "unknown key")]
    with pytest.raises(ConfigError, match=r"other.toml: x.colour: unknown key"):
        reader.raise_problems()


# -- one place for defaults: what an empty table yields is the dataclass default ----------


@pytest.mark.parametrize("cls", [
    DiscoveryProfile, ControlProfile, EventsProfile, CommandProfile, DdsProfile,
    LimitsProfile, TranslatorSelection, FaultSpec, LinkOptions, MemoryOptions,
    GenericOptions, MobilityOptions,
], ids=lambda c: c.__name__)
def test_an_empty_table_yields_the_dataclass_defaults(cls: type) -> None:
    assert read_table(cls, {}) == cls()
    assert read_table(cls, {}, text=True) == cls()


def test_empty_profiles_yield_the_dataclass_defaults(tmp_path: Path) -> None:
    assert from_mapping({}) == RelayProfile()
    assert from_mapping({"relay": {}, "dds": {}, "limits": {}}) == RelayProfile()
    vehicle = read_vehicle(Reader(), {"vehicle_id": "v"})
    assert vehicle == VehicleProfile("v")
    spec = read_link_profile(Reader("l.toml"), {"bit_rate": 9600})
    assert spec == LinkSpec(bit_rate=9600.0, source="l.toml")
    sim = parse_profile({"vehicles": [{"name": "a", "subsystem": 1, "link": "pty"}]})
    assert sim == SimProfile((VehicleSpec("a", 1, "pty"),))
    bulk = from_mapping({"bulk": {"listen": "0.0.0.0:9000", "dir": "img"}}).bulk
    assert bulk == BulkProfile("0.0.0.0:9000", Path("img"))


def test_link_options_defaults_are_the_plugins_own() -> None:
    from links.serial import SerialOptions
    from links.udp import UdpOptions

    assert check_link_url("udp://127.0.0.1:3794") == UdpOptions()
    assert check_link_url("serial:///dev/ttyUSB0") == SerialOptions()
    assert check_link_url("loop://bus") == MemoryOptions()
