"""A relay and an operator station in two processes, discovering each other over loopback.

The child process inherits ``CYCLONEDDS_URI`` (loopback discovery) from conftest.py; this
is the path real deployments take: separate participants, real RTPS over UDP.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from edge_vis.dds import DdsBridge

pytestmark = pytest.mark.dds

OPERATOR_STATION = r"""
import json, sys
from edge_vis.dds import DdsBridge

domain, partition = int(sys.argv[1]), sys.argv[2]
with DdsBridge(domain_id=domain, partitions=[partition]) as station:
    idents = station.reader("VehicleIdentification").collect(1, timeout=10.0)
    print(json.dumps(idents), flush=True)
    if not station.wait_for_subscribers("ControlRequest", timeout=10.0):
        sys.exit("relay never subscribed")
    station.publish("ControlRequest", {"vehicle_id": idents[0]["vehicle_id"],
                                       "operator_id": "station-2", "action": "REQUEST",
                                       "authority": 10})
    station._writer("ControlRequest").wait_for_acks(5_000_000_000)
"""


def test_an_operator_station_in_another_process(domain_id: int, partition: str) -> None:
    with DdsBridge(domain_id=domain_id, partitions=[partition]) as relay:
        relay.publish("VehicleIdentification", {"vehicle_id": "ugv1", "name": "Husky",
                                                "jaus_subsystem": 126})
        got: list[tuple[str, dict[str, object]]] = []
        # taken on arrival by the delivery thread: no lifespan expiry while the child exits
        relay.subscribe(["ControlRequest"], lambda topic, sample: got.append((topic, sample)))
        child = subprocess.run(
            [sys.executable, "-c", OPERATOR_STATION, str(domain_id), partition],
            capture_output=True, text=True, timeout=30,
        )
        assert child.returncode == 0, child.stderr
        (ident,) = json.loads(child.stdout)
        assert (ident["vehicle_id"], ident["name"], ident["jaus_subsystem"]) == (
            "ugv1", "Husky", 126
        )
        deadline = time.monotonic() + 3.0
        while not got and time.monotonic() < deadline:
            time.sleep(0.01)
        assert got == [("ControlRequest", {"vehicle_id": "ugv1", "operator_id": "station-2",
                                           "action": "REQUEST", "authority": 10})]
