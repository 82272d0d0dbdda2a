"""The emergency stop against the simulated vehicle (real UDP, the relay in-process, a real
Cyclone DDS operator): the sim obeys the Management JSIDL, the relay drives it."""

from __future__ import annotations

import asyncio

from .harness import RELAY_ID, Rig, until
from .test_fault_matrix import establish


def test_emergency_stops_the_sim_without_control_and_clear_lets_it_drive_again(
        domain_id: int, partition: str) -> None:
    rig = Rig("udp", domain_id, partition)

    async def main() -> None:
        await rig.start()
        try:
            await establish(rig)
            assert rig.driving()
            obeyed = rig.commands_obeyed
            rig.emergency("SET", "op-late", 10)  # listed, holds nothing: no control needed
            await until(rig.in_emergency, 2, "the sim in EMERGENCY")
            assert not rig.driving(), "still moving in EMERGENCY"
            for comp in rig.sim.components.values():
                if comp.state is not None:
                    assert comp.emergency_ids == {RELAY_ID}
            await asyncio.sleep(1.0)  # the operator keeps driving meanwhile
            assert rig.commands_obeyed == obeyed and not rig.driving()
            assert rig.commands_ignored == 0, "motion was sent to the vehicle in EMERGENCY"
            assert rig.vehicle_controlled(), "control is kept through the emergency"
            rig.emergency("CLEAR", "op-late", 10)
            await until(lambda: not rig.in_emergency(), 2, "the sim out of EMERGENCY")
            await until(lambda: rig.commands_obeyed > obeyed and rig.driving(), 3,
                        "driving again")
            assert rig.commands_ignored == 0
        finally:
            await rig.stop()

    asyncio.run(main())
