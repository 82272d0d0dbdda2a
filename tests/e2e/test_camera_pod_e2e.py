"""The shipped camera pod example end to end: its JSIDL and profile, a JAUS vehicle written
here on real UDP, the relay, and Cyclone DDS readers in other processes.

A custom report arrives as a typed topic that ``cyclonedds subscribe`` reads member by
member; a custom command from DDS reaches the vehicle only while the operator holds it,
throttled as the profile says; a snapshot message of several hundred kilobytes, many JAUS
fragments on the wire, arrives as an image whose bytes hash as the vehicle's did.
"""

from __future__ import annotations

import asyncio
import hashlib
import itertools
import json
import random
import shutil
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import pytest

from edge_vis.catalogue.jsidl import profile_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.fragments import fragment
from edge_vis.jaus.transport import Packet, pack_datagram

from .peer_sets import SetPeer
from .test_translators_e2e import relay_with, take_control, wait_for

pytestmark = pytest.mark.dds

dds = pytest.importorskip("edge_vis.dds")

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "camera_pod"
PROFILE = tomllib.loads((EXAMPLE / "relay.toml").read_text())
CATALOGUE = profile_catalogue([EXAMPLE / "CameraPod.xml"])
POD = "urn:example:CameraPod"
VEHICLE = JausAddress(86, 1, 1)
VEHICLE_ID = "CameraBot-86"

STATUS = {"camera_status_rec": {"pan": 0.75, "tilt": -0.25, "zoom": 12, "mode": 2,
                                "label": "bow"},
          "lens_list": [{"lens_id": 1, "focal_length": 0.035},
                        {"lens_id": 2, "focal_length": 0.2}]}


def camera_peer() -> SetPeer:
    return SetPeer(VEHICLE, (POD,), {"QueryCameraStatus": lambda f: ("ReportCameraStatus",
                                                                      STATUS)},
                   name="CameraBot", catalogue=CATALOGUE)


def example_sections() -> dict[str, Any]:
    """The example profile's catalogue and translator tables (links and DDS are the test's)."""
    return {"catalogue": PROFILE["catalogue"], "translators": PROFILE["translators"]}


def test_custom_report_is_a_typed_topic_read_member_by_member(domain_id: int,
                                                              partition: str) -> None:
    cli = shutil.which("cyclonedds", path=str(Path(sys.executable).parent))
    if cli is None:
        pytest.skip("the cyclonedds command-line tool is not installed")
    peer = camera_peer()

    async def body(runtime: Any, operator: Any) -> None:
        # cyclonedds subscribe reads the default partition: the relay publishes there
        child = await asyncio.create_subprocess_exec(
            cli, "subscribe", "CameraStatus", "-i", str(domain_id), "--runtime", "2s",
            "--suppress-progress-bar", "--color", "none",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
        try:
            text = await asyncio.wait_for(_first_sample(child.stdout), 40)
        finally:
            child.kill()
            await child.wait()
        sample = " ".join(text[text.index("CameraStatus("):].split())
        assert f"vehicle_id='{VEHICLE_ID}'" in sample
        assert "pan=0.74" in sample or "pan=0.75" in sample
        assert "mode=2" in sample and "label='bow'" in sample
        assert "lenses=[ CameraStatusLenses(lens_id=1, focal_length=0.03" in sample
        assert "CameraStatusLenses(lens_id=2, focal_length=0.2" in sample

    asyncio.run(relay_with(peer, 90, domain_id, partition, body,
                           extra={**example_sections(), "dds": {"partitions": []}},
                           base_dir=EXAMPLE))


async def _first_sample(stream: Any) -> str:
    """What ``cyclonedds subscribe`` prints up to the end of its first sample."""
    text = ""
    while "CameraStatus(" not in text or not text.endswith("\n)\n"):
        line = await stream.readline()
        if not line:
            break
        text += line.decode()
    return text


def _operator_topics() -> Any:
    from edge_vis.dds.topics import TopicRegistry
    from translators.generic import GenericTranslator

    generic = GenericTranslator()
    generic.configure(PROFILE["translators"]["generic"])
    generic.verify(CATALOGUE)
    registry = TopicRegistry.standard()
    registry.register_all(generic.topic_types, owner="station")
    return registry


def test_custom_command_only_while_controlled_and_throttled(domain_id: int,
                                                           partition: str) -> None:
    peer = camera_peer()
    (command,) = PROFILE["translators"]["generic"]["commands"]
    pointing = {"vehicle_id": VEHICLE_ID, "operator_id": "op1", "pan": 9.0, "tilt": 0.5}

    async def body(runtime: Any, operator: Any) -> None:
        await wait_for(lambda: peer.names("QueryServices"), 8, "discovery")
        for _ in range(10):  # not controlled: nothing may reach the vehicle
            operator.publish("CameraPointing", pointing)
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.5)
        assert peer.names("SetCameraPointing") == []
        await take_control(operator, peer, VEHICLE_ID)
        start = time.monotonic()
        while time.monotonic() - start < 3.0:  # 20 Hz from the operator
            tilt = 0.5 + (time.monotonic() - start) / 10
            operator.publish("CameraPointing", {**pointing, "tilt": tilt})
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.3)
        got = peer.names("SetCameraPointing")
        assert got, "SetCameraPointing never reached the vehicle"
        # pan is clamped to the JSIDL's limit; zoom (optional, not sent) is left out
        assert abs(got[0].fields["pan"] - 3.14159) < 1e-3
        assert "zoom" not in got[0].fields
        times = [r.at for r in got]
        span = times[-1] - times[0]
        assert len(got) <= command["rate"] * span + 2, (len(got), span)
        assert min(b - a for a, b in itertools.pairwise(times)) > \
            0.8 / command["rate"]
        assert got[-1].fields["tilt"] > got[0].fields["tilt"]  # the latest wins

    asyncio.run(relay_with(peer, 92, domain_id, partition, body, extra=example_sections(),
                           base_dir=EXAMPLE, topics=_operator_topics()))


IMAGE = random.Random(19).randbytes(400 * 1024)


def test_large_snapshot_arrives_as_an_image_with_its_hash(domain_id: int,
                                                         partition: str) -> None:
    peer = camera_peer()
    digest = hashlib.sha256(IMAGE).hexdigest()
    snapshot = {"snapshot_id": 42, "format": 1, "size": len(IMAGE), "sha256": digest,
                "image_file": IMAGE}
    bad = {**snapshot, "snapshot_id": 43, "sha256": "0" * 64}

    async def body(runtime: Any, operator: Any) -> None:
        reader = await asyncio.create_subprocess_exec(
            sys.executable, str(Path(__file__).with_name("camera_operator.py")), "images",
            str(domain_id), partition, "1", stdout=asyncio.subprocess.PIPE)
        try:
            assert (await asyncio.wait_for(reader.stdout.readline(), 30)).strip() == b"ready"
            await wait_for(lambda: peer.names("QueryServices"), 8, "discovery")
            await asyncio.sleep(1.0)  # the reader's participant and the relay's have met
            fragments = await _send_large(peer, "ReportSnapshot", bad)
            fragments = await _send_large(peer, "ReportSnapshot", snapshot)
            assert fragments > 200
            line = await asyncio.wait_for(reader.stdout.readline(), 30)
        finally:
            if reader.returncode is None:
                reader.kill()
            await reader.wait()
        image = json.loads(line)
        assert image["image_id"] == "ReportSnapshot-42"  # the forged one was refused
        assert image["format"] == "png" and image["file_name"] == "ReportSnapshot-42.png"
        assert image["size_bytes"] == image["got_size"] == len(IMAGE)
        assert image["sha256"] == image["got_sha256"] == digest
        assert image["chunks"] > 1
        assert runtime.engine.manager.errors["generic"] == 1  # the mismatch, counted

    asyncio.run(relay_with(peer, 94, domain_id, partition, body, extra=example_sections(),
                           base_dir=EXAMPLE))


async def _send_large(peer: SetPeer, name: str, fields: dict[str, Any]) -> int:
    """Send one message as a large data set, paced so loopback buffers never overflow."""
    assert peer.transport is not None and peer.relay is not None
    payload = CATALOGUE.encode(name, fields)
    packets = fragment(Packet(JausAddress(200, 1, 1), VEHICLE, payload, sequence=peer._seq),
                       peer.mtu)
    peer._seq = (peer._seq + len(packets)) % 0x10000
    for i, packet in enumerate(packets):
        peer.transport.sendto(pack_datagram([packet]), peer.relay)
        if i % 16 == 15:
            await asyncio.sleep(0.002)
    return len(packets)
