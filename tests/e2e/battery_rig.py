"""The shipped battery example as its end-to-end tests run it: the files copied, the relay's
link and DDS domain moved to the test's, ``edge-vis run`` in a process of its own, and an
operator's Cyclone DDS participant reading the topics typed from BatteryPack.xml."""

from __future__ import annotations

import asyncio
import shutil
import sys
import time
import tomllib
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import pytest

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"


def moved(path: Path, changes: tuple[tuple[str, str], ...]) -> str:
    """Rewrite ``path`` with each (old, new) replaced; every old text must be there."""
    text = path.read_text()
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new)
    path.write_text(text)
    return text


def prepare(tmp_path: Path, domain_id: int, partition: str, relay_ip: str, pack_ip: str,
            *extra: str) -> tuple[Path, Any]:
    """Copy the example (and ``extra`` files of it) to ``tmp_path`` and move the relay to the
    test's addresses; return relay.toml and the operator's topic registry."""
    from edge_vis.catalogue.jsidl import profile_catalogue
    from edge_vis.dds.topics import TopicRegistry
    from translators.generic import GenericTranslator

    for name in ("BatteryPack.xml", "battery-pack.toml", "relay.toml", *extra):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    relay_toml = tmp_path / "relay.toml"
    text = moved(relay_toml, (
        ('url = "udp://127.0.0.1:3794"', f'url = "udp://{relay_ip}:3794?peers={pack_ip}:3794"'),
        ("[dds]\ndomain = 0\n", f'[dds]\ndomain = {domain_id}\npartitions = ["{partition}"]\n')))
    # the operator's side: the topic the mapping publishes, typed from the JSIDL
    generic = GenericTranslator()
    generic.configure(tomllib.loads(text)["translators"]["generic"])
    generic.verify(profile_catalogue([EXAMPLE / "BatteryPack.xml"]))
    registry = TopicRegistry.standard()
    registry.register_all(generic.topic_types, owner="station")
    return relay_toml, registry


@asynccontextmanager
async def relay_and_operator(relay_toml: Path, domain_id: int, partition: str,
                             registry: Any) -> AsyncIterator[Any]:
    """``edge-vis run`` on ``relay_toml`` and an operator's bridge; the relay must end well."""
    from edge_vis import dds

    relay = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "edge_vis", "run", "--profile", str(relay_toml),
        "--duration", "60", stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE)
    operator = dds.DdsBridge(domain_id, (partition,), registry)
    try:
        yield operator
    finally:
        if relay.returncode is None:
            relay.terminate()
        _, err = await relay.communicate()
        operator.close()
    assert relay.returncode in (0, -15), err.decode()[-2000:]


async def collect(operator: Any, topic: str, vehicle_id: str,
                  timeout: float = 10.0) -> dict[str, Any]:
    """The first ``topic`` sample of ``vehicle_id`` the operator reads."""
    reader = operator.reader(topic)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in await asyncio.to_thread(reader.take, 0.2):
            if sample["vehicle_id"] == vehicle_id:
                return dict(sample)
    raise AssertionError(f"no {topic} sample of {vehicle_id} within {timeout} s")


async def identified_and_reporting(operator: Any) -> dict[str, Any]:
    """The pack is identified by its hello; return its first BatteryPack report."""
    ident = await collect(operator, "VehicleIdentification", "BP-0042", 20.0)
    assert (ident["name"], ident["vehicle_type"]) == ("Aft pack", "LIFEPO4")
    assert ident["jaus_address"] == "77.1.3"
    report = await collect(operator, "BatteryPack", "BP-0042")
    assert report["voltage_v"] == pytest.approx(48.2, abs=0.01)
    assert report["current_a"] == pytest.approx(-12.5, abs=0.01)
    assert report["state"] == 2  # DISCHARGING
    return report
