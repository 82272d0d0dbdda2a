"""Benchmark: JAUS reports in → DDS samples out, through the relay's own pipeline.

Measured in one run, on one core, with real Cyclone DDS writers:

* reports/s: a JUDP datagram carrying ReportGlobalPose goes through
  ``unpack_datagram`` → ``Router.receive`` → ``Catalogue.decode`` →
  ``Engine.receive_message`` → the mobility translator → ``DdsBridge.publish``;
* the bare limit: ``DataWriter.write`` of the same GlobalPose type in a loop;
* added latency p50/p99 at a paced 2,000 reports/s: from the datagram handed in to
  the sample written;
* resident memory with every installed translator loaded and 20 vehicles discovered.

Run: ``.venv/bin/python bench/engine.py`` (figures, not pass/fail).
"""

from __future__ import annotations

import dataclasses
import os
import resource
import statistics
import time

os.environ.setdefault(
    "CYCLONEDDS_URI",
    '<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/>'
    "</Interfaces><AllowMulticast>false</AllowMulticast></General></Domain></CycloneDDS>",
)

from edge_vis.catalogue import default_catalogue
from edge_vis.config import load_default_profile
from edge_vis.dds.bridge import DdsBridge
from edge_vis.engine.engine import Engine
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.kit.actions import Publish
from edge_vis.routing.router import Deliver, Router

VEHICLES = 20
SERVICES = ("urn:jaus:jss:core:Events", "urn:jaus:jss:core:AccessControl",
            "urn:jaus:jss:core:Management", "urn:jaus:jss:core:Liveness",
            "urn:jaus:jss:mobility:GlobalPoseSensor", "urn:jaus:jss:mobility:PrimitiveDriver")


def rss_mb() -> float:
    """Current resident set size in MiB (Linux /proc)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


class Pipeline:
    """The relay's receive path without sockets: datagram bytes in, DDS write out."""

    def __init__(self, bridge: DdsBridge) -> None:
        profile = load_default_profile()
        self.profile = dataclasses.replace(profile, links=())
        self.catalogue = default_catalogue()
        self.engine = Engine(self.profile, catalogue=self.catalogue)
        self.router = Router([self.profile.jaus_id])
        self.router.add_link("lan")
        self.bridge = bridge
        self.published = 0
        published, _ = self.engine.manager.topics()
        bridge.open_writers(published)

    def feed(self, datagram: bytes, now: float) -> None:
        for action in self.router.receive("lan", ("127.0.0.9", 3794),
                                          unpack_datagram(datagram), now):
            if isinstance(action, Deliver):
                message = self.catalogue.decode(action.packet.payload)
                self.engine.receive_message(action.packet.source, message, now)
        for action in self.engine.drain_actions():
            if isinstance(action, Publish):
                self.bridge.publish(action.topic, action.sample)
                self.published += 1

    def datagram(self, source: JausAddress, name: str, fields: dict, seq: int) -> bytes:
        payload = self.catalogue.encode(name, fields)
        return pack_datagram([Packet(self.profile.jaus_id, source, payload, sequence=seq)])

    def discover(self, source: JausAddress, now: float) -> None:
        self.feed(self.datagram(source, "ReportIdentification",
                                {"query_type": 2, "type": 10001,
                                 "identification": f"Bench{source.subsystem}"}, 1), now)
        self.feed(self.datagram(source, "ReportConfiguration", {"node_list": [{
            "node_rec": {"node_id": 1},
            "component_list": [{"component_id": 1, "instance_id": 0}]}]}, 2), now)
        self.feed(self.datagram(source, "ReportServices", {"node_list": [{
            "node_rec": {"node_id": 1},
            "component_list": [{
                "component_rec": {"component_id": 1, "instance_id": 0},
                "service_list": [{"uri": u, "major_version_number": 1,
                                  "minor_version_number": 0} for u in SERVICES]}]}]}, 3), now)


def pose(i: int) -> dict:
    return {"latitude": 28.5 + i * 1e-6, "longitude": -81.25, "altitude": 12.0,
            "position_rms": 0.5, "roll": 0.01, "pitch": 0.02, "yaw": 0.3,
            "attitude_rms": 0.01,
            "time_stamp": {"milliseconds": 1, "seconds": 2, "minutes": 3, "hour": 4,
                           "day": 5}}


def main() -> None:
    base_rss = rss_mb()
    bridge = DdsBridge(domain_id=7, partitions=("bench-engine",))
    pipeline = Pipeline(bridge)
    vehicles = [JausAddress(1000 + i, 1, 1) for i in range(VEHICLES)]
    for v in vehicles:
        pipeline.discover(v, 0.0)
    memory = rss_mb()
    translators = ", ".join(t.name for t in pipeline.engine.manager.translators)

    # pre-encode the reports with distinct sequence numbers (duplicates would be dropped)
    n = 20_000
    datagrams = [pipeline.datagram(vehicles[i % VEHICLES], "ReportGlobalPose", pose(i),
                                   (10 + i // VEHICLES) & 0xFFFF) for i in range(n)]
    before = pipeline.published
    start = time.perf_counter()
    cpu0 = time.process_time()  # every thread: Cyclone's writer work included
    for i, data in enumerate(datagrams):
        pipeline.feed(data, 1.0 + i * 1e-6)
    elapsed = time.perf_counter() - start
    cpu_per_report = (time.process_time() - cpu0) / n * 1e6
    published = pipeline.published - before
    rate = n / elapsed

    # the bare limit: the same DDS type written directly
    from edge_vis.dds.model import GlobalPose

    writer = bridge._writers["GlobalPose"]  # the bridge's own writer for the topic
    samples = [GlobalPose(vehicle_id=f"v{i % VEHICLES}", latitude=28.5, longitude=-81.25,
                          altitude=12.0, roll=0.01, pitch=0.02, yaw=0.3, timestamp_ms=i)
               for i in range(n)]
    start = time.perf_counter()
    for s in samples:
        writer.write(s)
    bare = n / (time.perf_counter() - start)

    # latency at a paced 2,000 reports/s
    latencies = []
    period = 1 / 2000
    lat_data = [pipeline.datagram(vehicles[i % VEHICLES], "ReportGlobalPose", pose(i),
                                  (40000 + i // VEHICLES) & 0xFFFF) for i in range(4000)]
    next_at = time.perf_counter()
    for i, data in enumerate(lat_data):
        while time.perf_counter() < next_at:
            pass
        t0 = time.perf_counter()
        pipeline.feed(data, 1.5 + i * period)
        latencies.append(time.perf_counter() - t0)
        next_at += period
    latencies.sort()
    p50 = statistics.median(latencies) * 1e3
    p99 = latencies[int(len(latencies) * 0.99)] * 1e3
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    bridge.close()

    print(f"translators loaded: {translators}")
    print(f"{'measure':<52}{'value':>14}")
    print(f"{'reports in -> GlobalPose samples out (reports/s)':<52}{rate:>14,.0f}")
    print(f"{'  samples published':<52}{published:>14,}")
    print(f"{'  CPU per report, all threads (us)':<52}{cpu_per_report:>14.1f}")
    print(f"{'bare Cyclone DataWriter.write (samples/s)':<52}{bare:>14,.0f}")
    print(f"{'  ratio relay / bare':<52}{rate / bare:>14.2f}")
    print(f"{'added latency p50 at 2,000 reports/s (ms)':<52}{p50:>14.3f}")
    print(f"{'added latency p99 at 2,000 reports/s (ms)':<52}{p99:>14.3f}")
    print(f"{'resident memory, 20 vehicles discovered (MiB)':<52}{memory:>14.1f}")
    print(f"{'  of which before edge-vis set-up (interpreter+imports)':<52}{base_rss:>14.1f}")
    print(f"{'peak resident memory during the run (MiB)':<52}{peak:>14.1f}")


if __name__ == "__main__":
    main()
