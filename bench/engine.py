"""Benchmark: JAUS reports in → DDS samples out, through the relay's own pipeline.

Measured in one run, on one core, with real Cyclone DDS writers:

* reports/s: a JUDP datagram carrying ReportGlobalPose goes through
  ``unpack_datagram`` → ``Router.receive`` → ``Catalogue.decode`` →
  ``Engine.receive_message`` → the mobility translator → ``DdsBridge.publish``;
* the bare limit: ``DataWriter.write`` of the same GlobalPose type in a loop;
* added latency p50/p99 at a paced 2,000 reports/s: from the datagram handed in to
  the sample written;
* resident memory with every installed translator loaded and 20 vehicles discovered.

Each figure is measured twice in one run when the binding has DDS Security (``scripts/
setup.sh --secure``): security off, then on (a deployment PKI made in a temporary folder by
``edge-vis security``'s code; authenticated, every topic encrypted). Both times one reader
of GlobalPose runs in another process (an observer identity when secured), so samples
really leave the writer, encrypted or not.

Run: ``.venv-secure/bin/python bench/engine.py`` (both), or ``.venv/bin/python
bench/engine.py`` (security off only). Figures, not pass/fail.
"""

from __future__ import annotations

import dataclasses
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from edge_vis.dds.cyclone_config import loopback_config

# loopback, with unicast discovery so the reader process is found
os.environ.setdefault("CYCLONEDDS_URI", loopback_config())

from edge_vis.catalogue import default_catalogue
from edge_vis.config import DdsProfile, DdsSecurityProfile, load_default_profile
from edge_vis.config.operators import OperatorPolicy
from edge_vis.dds.bridge import DdsBridge
from edge_vis.dds.secure_qos import security_available
from edge_vis.engine.engine import Engine
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.kit.actions import Publish
from edge_vis.routing.router import Deliver, Router

VEHICLES = 20
DOMAIN, PARTITION = 7, "bench-engine"
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


def reader_process(security: dict[str, str] | None) -> subprocess.Popen[str]:
    """A GlobalPose reader in another process (this script with ``--reader``)."""
    return subprocess.Popen([sys.executable, __file__, "--reader", json.dumps(security)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)


def read_until_stdin_closes(security: dict[str, str] | None) -> None:
    settings = None if security is None else DdsSecurityProfile(
        **{k: Path(v) if v else None for k, v in security.items()})
    bridge = DdsBridge(DOMAIN, (PARTITION,), security=settings)
    reader = bridge.reader("GlobalPose")
    import threading

    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    received = 0
    while not done.is_set():
        received += len(reader.take(timeout=0.2))
    bridge.close()
    print(received, flush=True)


def deployment_keys(folder: Path) -> tuple[DdsSecurityProfile, dict[str, str]]:
    """A relay identity and an observer's files, made as ``edge-vis security init`` does."""
    from edge_vis.tools.access_documents import OBSERVER
    from edge_vis.tools.deployment_keys import SecurityDirectory

    profile = dataclasses.replace(load_default_profile(), name="bench",
                                  dds=DdsProfile(domain=DOMAIN, partitions=(PARTITION,)),
                                  operators=OperatorPolicy())
    keys = SecurityDirectory(folder)
    written = keys.issue_all(profile, "bench", observers=["reader"])
    relay, observer = written[0], written[-1]  # relays first, observers last
    assert observer.role == OBSERVER
    files = {k: str(v) for k, v in asdict(keys.profile_for(observer)).items()}
    return keys.profile_for(relay), files


def measure(security: DdsSecurityProfile | None,
            reader_files: dict[str, str] | None) -> dict[str, Any]:
    """One pass of every figure; the reader process runs throughout."""
    reader = reader_process(reader_files)
    figures: dict[str, Any] = {}
    try:
        figures = _measure(security)
    finally:
        out, _ = reader.communicate("", timeout=30)
        figures["received"] = int(out.strip() or 0)
    return figures


def _measure(security: DdsSecurityProfile | None) -> dict[str, Any]:
    base_rss = rss_mb()
    bridge = DdsBridge(domain_id=DOMAIN, partitions=(PARTITION,), security=security)
    pipeline = Pipeline(bridge)
    matched = bridge.wait_for_subscribers("GlobalPose", 1, timeout=15.0)
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
    return {"translators": translators, "rate": rate, "published": published,
            "cpu": cpu_per_report, "bare": bare, "p50": p50, "p99": p99, "memory": memory,
            "base": base_rss, "peak": peak, "matched": matched}


ROWS = (
    ("reports in -> GlobalPose samples out (reports/s)", "rate", "{:,.0f}"),
    ("  samples published", "published", "{:,}"),
    ("  CPU per report, all threads (us)", "cpu", "{:.1f}"),
    ("bare Cyclone DataWriter.write (samples/s)", "bare", "{:,.0f}"),
    ("  ratio relay / bare", "ratio", "{:.2f}"),
    ("added latency p50 at 2,000 reports/s (ms)", "p50", "{:.3f}"),
    ("added latency p99 at 2,000 reports/s (ms)", "p99", "{:.3f}"),
    ("resident memory, 20 vehicles discovered (MiB)", "memory", "{:.1f}"),
    ("  of which before edge-vis set-up (interpreter+imports)", "base", "{:.1f}"),
    ("peak resident memory during the run (MiB)", "peak", "{:.1f}"),
    ("a reader in another process matched", "matched", "{}"),
    ("  GlobalPose samples it received (best-effort)", "received", "{:,}"),
)


def main() -> None:
    from importlib.metadata import version

    import cyclonedds

    runs = {"security off": measure(None, None)}
    if security_available():
        with tempfile.TemporaryDirectory() as folder:
            relay, reader = deployment_keys(Path(folder))
            runs["security on"] = measure(relay, reader)
    else:
        print("DDS Security: not in this Cyclone DDS binding (scripts/setup.sh --secure)")
    for figures in runs.values():
        figures["ratio"] = figures["rate"] / figures["bare"]
    print(f"cyclonedds {version('cyclonedds')} ({Path(cyclonedds.__file__).parent})")
    print(f"translators loaded: {next(iter(runs.values()))['translators']}")
    print(f"{'measure':<56}" + "".join(f"{name:>14}" for name in runs))
    for label, key, form in ROWS:
        print(f"{label:<56}" + "".join(f"{form.format(r[key]):>14}" for r in runs.values()))
    print("(memory figures of the second column include the first pass's)")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--reader"]:
        read_until_stdin_closes(json.loads(sys.argv[2]))
    else:
        main()
