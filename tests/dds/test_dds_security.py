"""DDS Security end to end: a secure relay with a simulated vehicle in this process, operator
stations in processes of their own (tests/secure_operator.py), identities and signed
documents from ``edge-vis security init``.

Needs the Cyclone DDS binding built against Debian's Cyclone DDS (``scripts/setup.sh
--secure``, the .venv-secure pass of scripts/test.sh); skipped on the PyPI wheel, which has
no DDS Security.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("cyclonedds")

from edge_vis.cli import main as cli
from edge_vis.config import load_profile
from edge_vis.dds.secure_qos import HOW_TO_SECURE, security_available
from edge_vis.tools.access_documents import OPERATOR
from edge_vis.tools.deployment_keys import SecurityDirectory

pytestmark = pytest.mark.skipif(not security_available(), reason=HOW_TO_SECURE)

PEER = Path(__file__).resolve().parents[1] / "secure_operator.py"
RELAY_IP, VEHICLE_IP = "127.0.0.206", "127.0.0.207"
SECONDS = 6.0


def _profile_text(domain: int, partition: str, security: str = "") -> str:
    return f"""
[relay]
jaus_id = "200.1.1"
authority = 150
name = "relay1"
[links.lan]
url = "udp://{RELAY_IP}:3794?peers={VEHICLE_IP}:3794"
[dds]
domain = {domain}
partitions = ["{partition}"]
{security}
[translators]
enabled = ["core", "mobility", "emergency"]
[discovery]
period = 0.5
liveness_period = 0.5
[report_rates]
ReportGlobalPose = 10.0
[[operators]]
id = "op1"
max_authority = 100
[[operators]]
id = "op2"
max_authority = 100
"""


class Deployment:
    """A secured deployment on disk, a foreign one (another CA), and the running relay."""

    def __init__(self, root: Path) -> None:
        self.domain = 200 + os.getpid() % 30
        self.partition = f"edge-vis-sec-{uuid.uuid4().hex[:8]}"
        self.profile = root / "relay.toml"
        self.profile.write_text(_profile_text(self.domain, self.partition))
        self.ours = SecurityDirectory(root / "security")
        self.foreign = SecurityDirectory(root / "foreign")
        for directory in (self.ours, self.foreign):
            assert cli(["security", "init", "--profile", str(self.profile), "--dir",
                        str(directory.directory), "--observer", "mon"]) == 0
        table = _table(self.ours, "relay", "relay1")
        self.profile.write_text(_profile_text(self.domain, self.partition, table))
        self.runtime: Any = None
        self.vehicle: Any = None

    def files(self, directory: SecurityDirectory, role: str, name: str) -> dict[str, str]:
        settings = directory.profile_for(directory.identity(role, name))
        return {k: str(v) for k, v in asdict(settings).items()}

    def operator(self, security: dict[str, str] | None, *, write_as: str,
                 claim: str | None = None, stop: bool = False) -> list[dict[str, Any]]:
        """Run an operator station process until it is done; its events."""
        config = {"domain": self.domain, "partitions": [self.partition],
                  "security": security, "write_partition": f"operator.{write_as}",
                  "write_as": write_as, "claim": claim or write_as, "seconds": SECONDS,
                  "stop": stop}
        done = subprocess.run([sys.executable, str(PEER), json.dumps(config)],
                              capture_output=True, text=True, timeout=60, check=False)
        assert done.returncode == 0, done.stderr[-2000:]
        return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def _table(directory: SecurityDirectory, role: str, name: str) -> str:
    settings = directory.profile_for(directory.identity(role, name))
    lines = ["[dds.security]"]
    lines += [f'{k} = "{v}"' for k, v in asdict(settings).items() if v is not None]
    return "\n".join(lines)


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory,
               loopback_cyclone: str) -> Iterator[Deployment]:
    """The secure relay and a simulated vehicle, running in a thread of this process."""
    from edge_vis.shell.relay import Runtime
    from edge_vis.tools.sim.profile import VehicleSpec
    from edge_vis.tools.sim.runner import UdpVehicle

    dep = Deployment(tmp_path_factory.mktemp("secure"))
    profile = load_profile(dep.profile)
    loop = asyncio.new_event_loop()
    started = threading.Event()
    failure: list[BaseException] = []

    async def start() -> None:
        dep.vehicle = UdpVehicle(VehicleSpec("ugv-sec", 133, f"udp://{VEHICLE_IP}:3794",
                                             init_time=0.1))
        await dep.vehicle.start()
        dep.runtime = Runtime(profile)
        await dep.runtime.start()

    def serve() -> None:
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(start())
        except BaseException as exc:  # reported to the test
            failure.append(exc)
        started.set()
        if not failure:
            loop.run_forever()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert started.wait(30)
    if failure:
        raise failure[0]

    async def stop() -> None:
        await dep.runtime.stop()
        await dep.vehicle.stop()

    try:
        yield dep
    finally:
        asyncio.run_coroutine_threadsafe(stop(), loop).result(30)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)


def _event(events: list[dict[str, Any]], name: str) -> dict[str, Any] | None:
    return next((e for e in events if e["event"] == name), None)


def test_a_listed_operator_drives(deployment: Deployment) -> None:
    sim = deployment.vehicle.vehicle
    before = sim.counters["commands_obeyed"]
    events = deployment.operator(deployment.files(deployment.ours, OPERATOR, "op1"),
                                 write_as="op1")
    assert _event(events, "pose"), events
    control = _event(events, "control")
    assert control is not None and control["status"]["operator_id"] == "op1", events
    assert sim.counters["commands_obeyed"] > before


def test_an_operator_claiming_another_operator_id_is_refused_and_counted(
        deployment: Deployment) -> None:
    runtime, sim = deployment.runtime, deployment.vehicle.vehicle
    key = "commands refused: operator_id is not the sender"
    obeyed = -1
    while obeyed != sim.counters["commands_obeyed"]:  # earlier tests' commands have landed
        obeyed = sim.counters["commands_obeyed"]
        time.sleep(1.0)
    before = runtime.counters[key]
    # op2's own identity and partition, but every command says it is op1
    events = deployment.operator(deployment.files(deployment.ours, OPERATOR, "op2"),
                                 write_as="op2", claim="op1")
    assert _event(events, "pose"), events
    control = _event(events, "control")
    assert control is not None, events
    status = control["status"]
    assert "operator_id 'op1' refused: sent by op2" in status["last_rejection"]
    assert status["operator_id"] != "op2"
    assert runtime.counters[key] - before >= 10
    assert runtime.totals()[key] >= 10  # what the totals line logs
    assert runtime.engine.counters["samples_refused_sender"] >= 10
    # whoever holds the vehicle (op1, from the test before), none of op2's commands
    # claiming to be op1 reached it
    assert sim.counters["commands_obeyed"] == obeyed


def test_an_emergency_stop_claiming_another_operator_is_obeyed_as_its_sender(
        deployment: Deployment) -> None:
    """A stop is never lost: op2's SET that says it is op1 stops the vehicle, in op2's
    name (so op1's authority cannot be borrowed to clear it), and op2 can clear it."""
    runtime = deployment.runtime
    key = "emergency stops taken as their sender"
    before = runtime.counters[key]
    events = deployment.operator(deployment.files(deployment.ours, OPERATOR, "op2"),
                                 write_as="op2", claim="op1", stop=True)
    stopped = _event(events, "stopped")
    assert stopped is not None, events
    assert stopped["status"]["emergency_operator"] == "op2", stopped
    assert runtime.counters[key] > before
    assert _event(events, "cleared"), events


def test_a_read_only_identity_cannot_create_a_command_writer(deployment: Deployment) -> None:
    events = deployment.operator(deployment.files(deployment.ours, "observer", "mon"),
                                 write_as="mon")
    refused = _event(events, "writer_refused")
    assert refused is not None and "NOT_ALLOWED_BY_SECURITY" in refused["error"], events
    assert _event(events, "pose"), "its reader still receives"


@pytest.mark.parametrize("case", ["foreign deployment", "foreign-CA permissions",
                                  "foreign-CA certificate"])
def test_material_from_another_ca_never_matches(deployment: Deployment, case: str) -> None:
    ours = deployment.files(deployment.ours, OPERATOR, "op1")
    theirs = deployment.files(deployment.foreign, OPERATOR, "op1")
    if case == "foreign deployment":  # a whole PKI of its own, same names
        files = theirs
    elif case == "foreign-CA permissions":  # our certificate, permissions signed elsewhere
        files = {**ours, "permissions": theirs["permissions"]}
    else:  # a certificate from another CA, presented with our CA and permissions
        files = {**ours, "certificate": theirs["certificate"],
                 "private_key": theirs["private_key"]}
    received = deployment.runtime.counters["samples in"]
    events = deployment.operator(files, write_as="op1")
    assert _event(events, "pose") is None, events
    assert _event(events, "join_refused") or _event(events, "no_pose"), events
    assert deployment.runtime.counters["samples in"] == received


def test_a_station_without_security_and_the_secure_relay_never_talk(
        deployment: Deployment) -> None:
    received = deployment.runtime.counters["samples in"]
    events = deployment.operator(None, write_as="op1")
    assert _event(events, "joined"), events
    assert _event(events, "no_pose"), events
    assert deployment.runtime.counters["samples in"] == received


def test_relay_reads_commands_only_from_listed_operators_partitions(
        deployment: Deployment) -> None:
    bridge = deployment.runtime.publisher
    # every command topic is read only in the listed operators' partitions (RelayStatus,
    # from the other relays, in the relay's own)
    partitions = sorted({s.partition for s in bridge._subscriptions
                         if s.spec.name != "RelayStatus"})
    assert partitions == ["operator.op1", "operator.op2"]
    assert {s.partition for s in bridge._subscriptions if s.spec.name == "RelayStatus"} \
        == {None}
    assert bridge.secure


def test_a_revoked_operator_never_matches_a_relay_with_the_new_list(
        deployment: Deployment, tmp_path: Path) -> None:
    from edge_vis.dds import DdsBridge

    # a deployment of its own (permissions name their domain), op2 revoked after issue
    domain, partition = deployment.domain - 30, f"edge-vis-rev-{uuid.uuid4().hex[:8]}"
    profile = tmp_path / "relay.toml"
    profile.write_text(_profile_text(domain, partition))
    keys = SecurityDirectory(tmp_path / "security")
    assert cli(["security", "init", "--profile", str(profile), "--dir",
                str(keys.directory)]) == 0
    old_list = tmp_path / "crl-before.pem"
    old_list.write_bytes(keys.ca.crl.read_bytes())
    assert cli(["security", "revoke", "--dir", str(keys.directory), "op2"]) == 0

    relay = DdsBridge(domain, (partition,),
                      security=keys.profile_for(keys.identity("relay", "relay1")))
    stop = threading.Event()

    def publish() -> None:
        while not stop.is_set():
            relay.publish("GlobalPose", {"vehicle_id": "ugv-rev", "latitude": 1.0,
                                         "longitude": 2.0, "altitude": 0.0, "roll": 0.0,
                                         "pitch": 0.0, "yaw": 0.0, "timestamp_ms": 0})
            time.sleep(0.1)

    writer = threading.Thread(target=publish, daemon=True)
    writer.start()
    try:
        dep = Deployment.__new__(Deployment)
        dep.domain, dep.partition = domain, partition
        events = dep.operator(dep.files(keys, OPERATOR, "op1"), write_as="op1")
        assert _event(events, "pose"), events  # the others match
        op2 = {**dep.files(keys, OPERATOR, "op2"), "crl": str(old_list)}  # kept the old list
        events = dep.operator(op2, write_as="op2")
        assert _event(events, "pose") is None, events
    finally:
        stop.set()
        writer.join(5)
        relay.close()


class LoopbackCapture:
    """Every frame on the loopback interface while it runs, searched for ``marker``: a raw
    AF_PACKET socket (root or CAP_NET_RAW), as tcpdump would capture it."""

    def __init__(self, marker: bytes) -> None:
        try:
            self._sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW,
                                       socket.htons(0x0003))  # ETH_P_ALL
        except (PermissionError, AttributeError) as exc:
            pytest.skip(f"capturing loopback traffic needs a raw socket (root): {exc}")
        self._sock.bind(("lo", 0))
        self._sock.settimeout(0.2)
        self.marker = marker
        self.rtps_frames = 0  # UDP datagrams of DDS (RTPS), any participant's
        self.with_marker = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                frame = self._sock.recv(1 << 16)
            except TimeoutError:
                continue
            # Ethernet (14) + IPv4 without options (20) + UDP (8): RTPS starts with "RTPS"
            if frame[23:24] == b"\x11" and frame[42:46] == b"RTPS":
                self.rtps_frames += 1
            if self.marker in frame:
                self.with_marker += 1

    def stop(self) -> LoopbackCapture:
        self._stop.set()
        self._thread.join(5)
        self._sock.close()
        return self


def _marker() -> str:
    return f"zq{uuid.uuid4().hex}"  # in no other traffic: only where these tests put it


def test_encrypted_on_the_wire_a_command_never_appears_in_plaintext(
        deployment: Deployment) -> None:
    """op1 claims a distinctive operator_id: its commands cross to the relay (which refuses
    them and says so in ControlStatus, back across the wire), and no frame on loopback
    carries those bytes."""
    marker = _marker()
    key = "commands refused: operator_id is not the sender"
    before = deployment.runtime.counters[key]
    capture = LoopbackCapture(marker.encode())
    try:
        events = deployment.operator(deployment.files(deployment.ours, OPERATOR, "op1"),
                                     write_as="op1", claim=marker)
    finally:
        capture.stop()
    control = _event(events, "control")
    assert control is not None, events
    assert f"operator_id '{marker}' refused: sent by op1" in control["status"]["last_rejection"]
    assert deployment.runtime.counters[key] > before  # the commands did reach the relay
    assert capture.rtps_frames > 50, "the capture saw the DDS traffic"
    assert capture.with_marker == 0, "a command's payload appeared in plaintext"


def test_without_security_the_same_command_is_in_plaintext_on_the_wire(
        loopback_cyclone: str) -> None:
    """The control for the test above: the same operator station without DDS Security, and
    a plain participant in this process publishing a vehicle's pose and reading the
    station's commands."""
    from edge_vis.dds import DdsBridge

    marker = _marker()
    domain, partition = 140 + os.getpid() % 30, f"edge-vis-plain-{uuid.uuid4().hex[:8]}"
    relay = DdsBridge(domain, (partition,))
    relay.subscribe(["ControlRequest"], partition="operator.op1")
    stop = threading.Event()
    received: list[dict[str, Any]] = []

    def publish() -> None:
        while not stop.is_set():
            relay.publish("GlobalPose", {"vehicle_id": "ugv-plain", "latitude": 1.0,
                                         "longitude": 2.0, "altitude": 0.0, "roll": 0.0,
                                         "pitch": 0.0, "yaw": 0.0, "timestamp_ms": 0})
            received.extend(sample for _, sample in relay.take())
            time.sleep(0.1)

    writer = threading.Thread(target=publish, daemon=True)
    capture = LoopbackCapture(marker.encode())
    writer.start()
    try:
        dep = Deployment.__new__(Deployment)
        dep.domain, dep.partition = domain, partition
        events = dep.operator(None, write_as="op1", claim=marker)
    finally:
        capture.stop()
        stop.set()
        writer.join(5)
    try:
        assert _event(events, "pose"), events
        assert any(s["operator_id"] == marker for s in received), received
        assert capture.with_marker > 0, "the command's bytes were expected in plaintext"
    finally:
        relay.close()
