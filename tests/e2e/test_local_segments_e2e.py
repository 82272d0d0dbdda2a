"""Local path segments end to end: a real Cyclone DDS operator sends a PathSegmentPlan in
the LOCAL frame, the relay loads it into a simulated UGV's Local Path Segment Driver over
real UDP, the vehicle drives it, and the operator sees the segments it holds, the one it
is driving and its progress."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest

from .test_plans_spooler_e2e import Latest, name, run_with_sim

pytestmark = pytest.mark.dds

#: segment end points (x north, y east, metres from the vehicle's origin)
ENDS = ((12.0, 0.0), (12.0, 12.0))


def test_local_path_segments_are_loaded_driven_and_read_back(domain_id: int,
                                                            partition: str) -> None:
    async def body(operator: Any, vehicle: Any, vid: str) -> None:
        plans = Latest(operator, "VehiclePlan")
        missions = Latest(operator, "MissionStatus")
        assert operator.wait_for_subscribers("PathSegmentPlan", 1, 5.0)
        operator.publish("PathSegmentPlan", {
            "vehicle_id": vid, "operator_id": "op1", "plan_id": "local-bend", "frame": "LOCAL",
            "speed": 3.0, "segments": [
                {"x": x, "y": y, "control_x": ENDS[0][0] if i else 0.0, "control_y": 0.0,
                 "weighting_factor": float(i), "tolerance": 1.5}
                for i, (x, y) in enumerate(ENDS)]})
        held = await plans.until(
            lambda s: s["complete"] and len(s["elements"]) == 2
            and all(e["message"] == "SetLocalPathSegment" for e in s["elements"]),
            "the local segments read back")
        assert held["component"] == "161.1.2"
        for element, (x, y) in zip(held["elements"], ENDS, strict=True):
            assert (element["x"], element["y"]) == (pytest.approx(x, abs=0.01),
                                                    pytest.approx(y, abs=0.01))
            assert math.isnan(element["latitude"])
        assert held["elements"][1]["control_x"] == pytest.approx(ENDS[0][0], abs=0.01)
        assert held["elements"][1]["weighting_factor"] == pytest.approx(1.0, abs=0.01)
        # the driver reports the local segment it is driving
        driving = await plans.until(lambda s: s["current"]["message"] == "SetLocalPathSegment",
                                    "the segment being driven")
        assert (driving["current"]["x"], driving["current"]["y"]) in [
            (pytest.approx(x, abs=0.01), pytest.approx(y, abs=0.01)) for x, y in ENDS]
        done = await missions.until(
            lambda s: s["plan_id"] == "local-bend" and name(s["state"]) == "MISSION_COMPLETED",
            "the segments driven", timeout=30.0)
        assert done["active_waypoint"] == -1
        assert vehicle.waypoints.reached == [1, 2]
        assert math.hypot(vehicle.motion.x - ENDS[1][0], vehicle.motion.y - ENDS[1][1]) <= 1.5

    asyncio.run(run_with_sim(245, domain_id, partition, body))
