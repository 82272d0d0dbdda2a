"""Benchmark: what discovery profiles and the shipped JSIDL set cost.

* start-up: reading the ``uuv`` set's JSIDL (``edge_vis/data/jsidl/uuv``) into the default
  catalogue, against building the whole default catalogue;
* reports/s through ``Engine.receive_message`` (decoded messages in, samples out, no DDS)
  for a vehicle found by JAUS discovery (ReportGlobalPose, mobility translator), one
  declared by its hello and one found passively (ReportBatteryPack of the battery example,
  generic mapping): the per-message cost a discovery profile adds.

Run: ``.venv/bin/python bench/discovery_profiles.py`` (figures, not pass/fail).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from edge_vis.catalogue import default_catalogue, shipped_jsidl_sets
from edge_vis.catalogue.jsidl import load_jsidl, profile_catalogue
from edge_vis.config import from_mapping, load_profile
from edge_vis.engine.engine import Engine
from edge_vis.engine.manager import TranslationManager
from edge_vis.jaus.address import JausAddress

EXAMPLE = Path(__file__).resolve().parents[1] / "profiles" / "examples" / "battery"
N = 20_000


def best_of(run: Any, times: int = 5) -> float:
    best = float("inf")
    for _ in range(times):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def rate(engine: Engine, source: JausAddress, message: Any) -> float:
    """Messages per second through receive_message (actions drained each time)."""
    now = [10.0]

    def run() -> None:
        for _ in range(N):
            now[0] += 0.001
            engine.receive_message(source, message, now[0])
            engine.drain_actions()

    return N / best_of(run, 3)


def engine_for(profile: Any, catalogue: Any) -> Engine:
    manager = TranslationManager.from_selection(profile.translators)
    manager.verify(catalogue, profile.source)
    engine = Engine(profile, manager, catalogue=catalogue)
    engine.on_timer(0.0)
    return engine


def main() -> None:
    folder = shipped_jsidl_sets()["uuv"]
    jsidl = best_of(lambda: load_jsidl(folder, service_set="uuv"))
    default_catalogue.cache_clear()
    whole = best_of(lambda: (default_catalogue.cache_clear(), default_catalogue()))
    print(f"uuv JSIDL read: {jsidl * 1000:.1f} ms of {whole * 1000:.1f} ms to build the "
          "default catalogue (modules already imported)")

    catalogue = profile_catalogue([EXAMPLE / "BatteryPack.xml"])
    report = catalogue.decode(catalogue.encode("ReportBatteryPack", {
        "voltage": 48.2, "current": -12.5, "state_of_charge": 81.0, "pack_state": 2}))
    hello = catalogue.decode(catalogue.encode("ReportBatteryHello", {
        "pack_serial": "BP-0042", "pack_name": "Aft pack", "chemistry": 1,
        "services": ["urn:example:battery:BatteryPack"]}))
    pack = JausAddress(77, 1, 3)

    generic = load_profile(EXAMPLE / "relay.toml").translators.options["generic"]
    mapped = {"translators": {"enabled": ["core", "mobility", "generic"], "generic": generic},
              "catalogue": {"jsidl": [str(EXAMPLE / "BatteryPack.xml")]}}

    # found by JAUS discovery: identification and services, then reports
    jaus = engine_for(from_mapping(mapped), catalogue)
    robot = JausAddress(150, 1, 1)
    services = [{"uri": uri, "major_version_number": 1, "minor_version_number": 0}
                for uri in ("urn:jaus:jss:mobility:GlobalPoseSensor",
                            "urn:example:battery:BatteryPack")]
    for name, fields in (("ReportIdentification", {"query_type": 2, "type": 10001,
                                                   "identification": "Robot"}),
                         ("ReportServices", {"node_list": [{"node_rec": {"node_id": 1},
                          "component_list": [{"component_rec": {"component_id": 1,
                                                                "instance_id": 0},
                                              "service_list": services}]}]})):
        jaus.receive_message(robot, catalogue.decode(catalogue.encode(name, fields)), 1.0)
    pose = catalogue.decode(catalogue.encode("ReportGlobalPose",
                                             {"latitude": 36.6, "longitude": -121.9}))
    print(f"discovered by JAUS, ReportGlobalPose: {rate(jaus, robot, pose):,.0f} msg/s")
    print(f"discovered by JAUS, ReportBatteryPack: {rate(jaus, robot, report):,.0f} msg/s")

    by_hello = engine_for(load_profile(EXAMPLE / "relay.toml"), catalogue)
    by_hello.receive_message(pack, hello, 1.0)
    assert by_hello.vehicle("BP-0042") is not None
    print(f"declared by its hello, ReportBatteryPack: {rate(by_hello, pack, report):,.0f} "
          "msg/s")

    passive = engine_for(from_mapping({**mapped, "vehicles": [
        {"file": str(EXAMPLE / "battery-pack-passive.toml")}]}), catalogue)
    spare = JausAddress(311, 1, 2)
    passive.receive_message(spare, report, 1.0)
    assert passive.vehicle("battery-311") is not None
    print(f"found passively, ReportBatteryPack: {rate(passive, spare, report):,.0f} msg/s")


if __name__ == "__main__":
    main()
