"""An operator station in a process of its own, for the DDS Security tests.

    python tests/secure_operator.py CONFIG_JSON

CONFIG: ``domain``, ``partitions`` (the relay's), ``security`` (a dict of
``[dds.security]`` file paths, or null for a station without DDS Security),
``write_partition`` (where its commands go), ``claim`` (the operator_id it puts in its
commands), ``seconds`` (how long it tries), ``stop`` (instead of driving: set the
vehicle's emergency stop as ``claim``, report it, then clear it as itself).
It prints one JSON object per line:

* ``{"event": "joined"}`` or ``{"event": "join_refused", "error": ...}`` (then it exits);
* ``{"event": "writer_refused", "error": ...}`` when its permissions deny a command writer;
* ``{"event": "pose", "vehicle_id": ...}`` for the first pose it reads, or ``{"event":
  "no_pose"}`` after ``seconds``;
* with writers and a pose: it requests control as ``claim`` and drives for ``seconds``,
  then ``{"event": "control", "status": <last ControlStatus>}``.

It uses edge-vis's DDS bridge as any DDS application would use its own; it imitates no
JAUS implementation.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from edge_vis.config.deployment import DdsSecurityProfile
from edge_vis.dds import DdsBridge, DdsError


def say(**event: object) -> None:
    print(json.dumps(event), flush=True)


def main(config: dict) -> int:
    files = config.get("security")
    security = None if files is None else DdsSecurityProfile(
        **{k: Path(v) if v else None for k, v in files.items()})
    try:
        bridge = DdsBridge(config["domain"], config["partitions"], security=security,
                           writer_partitions=[config["write_partition"]])
    except DdsError as exc:
        say(event="join_refused", error=str(exc))
        return 0
    say(event="joined")
    seconds = float(config["seconds"])
    try:
        try:
            bridge.open_writers(["ControlRequest", "WrenchEffortCommand", "EmergencyCommand"])
            writers = True
        except DdsError as exc:
            say(event="writer_refused", error=str(exc))
            writers = False
        poses = bridge.reader("GlobalPose")
        control = bridge.reader("ControlStatus", depth=16)
        got = poses.collect(1, seconds)
        if not got:
            say(event="no_pose")
            return 0
        vehicle = got[0]["vehicle_id"]
        say(event="pose", vehicle_id=vehicle)
        if not writers:
            return 0
        claim = config["claim"]
        if config.get("stop"):
            return emergency(bridge, vehicle, claim, config["write_as"], seconds)
        status: dict = {}
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            bridge.publish("ControlRequest", {"vehicle_id": vehicle, "operator_id": claim,
                                              "authority": 100, "action": "request"})
            bridge.publish("WrenchEffortCommand", {"vehicle_id": vehicle, "operator_id": claim,
                                                   "propulsive_linear_x": 40.0})
            time.sleep(0.05)
            for sample in control.take():
                status = sample
        say(event="control", status=status)
        return 0
    finally:
        bridge.close()


def emergency(bridge: DdsBridge, vehicle: str, claim: str, me: str, seconds: float) -> int:
    """SET as ``claim`` until VehicleStatus shows the stop (``{"event": "stopped",
    "status": ...}``, or ``{"event": "not_stopped"}``), then CLEAR as ``me``."""
    statuses = bridge.reader("VehicleStatus", depth=16)
    deadline = time.monotonic() + seconds
    stopped: dict | None = None
    while stopped is None and time.monotonic() < deadline:
        bridge.publish("EmergencyCommand", {"vehicle_id": vehicle, "operator_id": claim,
                                            "action": "SET", "reason": "secure test"})
        time.sleep(0.2)
        stopped = next((s for s in statuses.take() if s.get("emergency")), None)
    say(event="stopped", status=stopped) if stopped else say(event="not_stopped")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        bridge.publish("EmergencyCommand", {"vehicle_id": vehicle, "operator_id": me,
                                            "action": "CLEAR", "reason": "secure test"})
        time.sleep(0.2)
        if any(not s.get("emergency") for s in statuses.take()):
            say(event="cleared")
            break
    return 0


if __name__ == "__main__":
    sys.exit(main(json.loads(sys.argv[1])))
