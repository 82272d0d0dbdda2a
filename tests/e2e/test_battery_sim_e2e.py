"""The README's battery example against the simulator: every file shipped, no Python.

The simulator runs ``profiles/examples/battery/sim.toml`` in this process (the pack as a
``kind = "custom"`` vehicle, from BatteryPack.xml and the values in the TOML); ``edge-vis
run`` runs the shipped relay.toml in a process of its own. Only the link addresses and the
DDS domain are moved to the test's. An operator's Cyclone DDS participant must see the pack
identified by its hello and its typed BatteryPack report with the simulated values.
"""

from __future__ import annotations

import asyncio
import shutil
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"
RELAY_IP, PACK_IP = "127.0.0.92", "127.0.0.93"


async def collect(operator: Any, topic: str, vehicle_id: str,
                  timeout: float = 10.0) -> dict[str, Any]:
    reader = operator.reader(topic)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in await asyncio.to_thread(reader.take, 0.2):
            if sample["vehicle_id"] == vehicle_id:
                return dict(sample)
    raise AssertionError(f"no {topic} sample of {vehicle_id} within {timeout} s")


def moved(path: Path, changes: tuple[tuple[str, str], ...]) -> str:
    text = path.read_text()
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new)
    path.write_text(text)
    return text


def test_simulated_battery_pack_from_jsidl_to_dds(domain_id: int, partition: str,
                                                  tmp_path: Path) -> None:
    from edge_vis.catalogue.jsidl import profile_catalogue
    from edge_vis.dds.topics import TopicRegistry
    from edge_vis.tools.sim.profile import load_profile
    from edge_vis.tools.sim.runner import Simulation
    from translators.generic import GenericTranslator

    for name in ("BatteryPack.xml", "battery-pack.toml", "relay.toml", "sim.toml"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    text = moved(tmp_path / "relay.toml", (
        ('url = "udp://127.0.0.1:3794"', f'url = "udp://{RELAY_IP}:3794?peers={PACK_IP}:3794"'),
        ("[dds]\ndomain = 0\n", f'[dds]\ndomain = {domain_id}\npartitions = ["{partition}"]\n')))
    moved(tmp_path / "sim.toml", (('link = "udp://127.0.0.88:3794"',
                                   f'link = "udp://{PACK_IP}:3794"'),))
    generic = GenericTranslator()
    generic.configure(tomllib.loads(text)["translators"]["generic"])
    generic.verify(profile_catalogue([EXAMPLE / "BatteryPack.xml"]))
    registry = TopicRegistry.standard()
    registry.register_all(generic.topic_types, owner="station")

    async def run() -> None:
        sim = Simulation(load_profile(tmp_path / "sim.toml"))
        await sim.start()
        relay = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "edge_vis", "run", "--profile", str(tmp_path / "relay.toml"),
            "--duration", "60", stdout=asyncio.subprocess.DEVNULL,
            stderr=asyncio.subprocess.PIPE)
        operator = dds.DdsBridge(domain_id, (partition,), registry)
        try:
            ident = await collect(operator, "VehicleIdentification", "BP-0042", 20.0)
            assert (ident["name"], ident["vehicle_type"]) == ("Aft pack", "LIFEPO4")
            assert ident["jaus_address"] == "77.1.3"
            report = await collect(operator, "BatteryPack", "BP-0042")
            assert report["voltage_v"] == pytest.approx(48.2, abs=0.01)
            assert report["current_a"] == pytest.approx(-12.5, abs=0.01)
            assert 60.0 < report["state_of_charge_pct"] <= 81.4  # 81 %, running down
            assert 22.0 < report["temperature_c"] < 26.0          # 24 degrees +- 1.5
            assert report["state"] == 2                            # DISCHARGING
            (endpoint,) = sim.endpoints
            assert endpoint.vehicle is not None
            assert endpoint.vehicle.counters["queries_answered"] >= 1  # the relay polled it
        finally:
            if relay.returncode is None:
                relay.terminate()
            _, err = await relay.communicate()
            operator.close()
            await sim.stop()
        assert relay.returncode in (0, -15), err.decode()[-2000:]

    asyncio.run(run())
