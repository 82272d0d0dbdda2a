"""The README's battery example against the simulator: every file shipped, no Python.

The simulator runs ``profiles/examples/battery/sim.toml`` in this process (the pack as a
``kind = "custom"`` vehicle, from BatteryPack.xml and the values in the TOML); ``edge-vis
run`` runs the shipped relay.toml in a process of its own. Only the link addresses and the
DDS domain are moved to the test's. An operator's Cyclone DDS participant must see the pack
identified by its hello and its typed BatteryPack report with the simulated values.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from .battery_rig import identified_and_reporting, moved, prepare, relay_and_operator

pytestmark = pytest.mark.dds

pytest.importorskip("edge_vis.dds")

RELAY_IP, PACK_IP = "127.0.0.92", "127.0.0.93"


def test_simulated_battery_pack_from_jsidl_to_dds(domain_id: int, partition: str,
                                                  tmp_path: Path) -> None:
    from edge_vis.tools.sim.profile import load_profile
    from edge_vis.tools.sim.runner import Simulation

    relay_toml, registry = prepare(tmp_path, domain_id, partition, RELAY_IP, PACK_IP,
                                   "sim.toml")
    moved(tmp_path / "sim.toml", (('link = "udp://127.0.0.88:3794"',
                                   f'link = "udp://{PACK_IP}:3794"'),))

    async def run() -> None:
        sim = Simulation(load_profile(tmp_path / "sim.toml"))
        await sim.start()
        try:
            async with relay_and_operator(relay_toml, domain_id, partition,
                                          registry) as operator:
                report = await identified_and_reporting(operator)
                assert 60.0 < report["state_of_charge_pct"] <= 81.4  # 81 %, running down
                assert 22.0 < report["temperature_c"] < 26.0          # 24 degrees +- 1.5
                (endpoint,) = sim.endpoints
                assert endpoint.vehicle is not None
                assert endpoint.vehicle.counters["queries_answered"] >= 1  # it was polled
        finally:
            await sim.stop()

    asyncio.run(run())
