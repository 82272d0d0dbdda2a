"""ATR images end to end: a UUV announces over JAUS (real UDP), the relay fetches each
image from the vehicle's image server over real UDT, and an operator station in its own
process (real Cyclone DDS) sees exactly one ``ImageProduct`` per image, thumbnail included.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime
from edge_vis.tools.sim.images import frame_pixels, png_grey

from .peer_sets import SetPeer
from .test_translators_e2e import RELAY, relay_with

pytestmark = [pytest.mark.dds, pytest.mark.udt]
dds = pytest.importorskip("edge_vis.dds")
udt = pytest.importorskip("links.udt")

HELLO = {"vehicle_name": "Remus", "vehicle_type": 1,
         "jaus_id": {"subsystem": 86, "node": 1, "component": 2}, "firmware_version": "7.1",
         "services": [{"uri": "urn:edge-vis:uuv:AtrImageNotifier", "major_version": 1,
                       "minor_version": 0}], "bulk_image_port": 9100}


def test_announced_images_are_fetched_once_each(domain_id: int, partition: str,
                                                tmp_path: Path) -> None:
    atr = tmp_path / "vehicle"
    atr.mkdir()
    images = {}
    for n, (w, h) in {1: (320, 240), 2: (1200, 900)}.items():  # the second one ~1 MiB
        data = png_grey(w, h, frame_pixels(w, h, 7, n))
        (atr / f"atr-{n}.png").write_bytes(data)
        images[n] = data
    peer = SetPeer(JausAddress(86, 1, 2), (), {}, discoverable=False)
    uuv = Path(__file__).resolve().parents[2] / "profiles" / "vehicles" / "uuv.toml"
    seen: list[dict[str, Any]] = []

    async def body(runtime: Runtime, _operator: Any) -> None:
        watcher = await asyncio.create_subprocess_exec(
            sys.executable, str(Path(__file__).with_name("image_watcher.py")),
            str(domain_id), partition, str(len(images)), stdout=asyncio.subprocess.PIPE)
        assert watcher.stdout is not None
        assert (await asyncio.wait_for(watcher.stdout.readline(), 30)).strip() == b"ready"
        peer.start_hello(("127.0.0.61", 3794), RELAY, HELLO)
        await asyncio.sleep(1.5)  # found by its hello
        for n, data in images.items():
            peer.send(RELAY, "ReportAtrImageAvailable", {
                "image_id": n, "size_bytes": len(data), "format": 1,
                "sha256": hashlib.sha256(data).digest(), "capture_time": 1_700_000_000_000 + n,
                "target_class": "cylinder", "confidence": 0.5 + n / 10})
        line = await asyncio.wait_for(watcher.stdout.readline(), 90)
        await watcher.wait()
        seen.extend(json.loads(line))

    with udt.UdtBulkChannel.ImageServer(atr, vehicle_id="Remus-86") as server:
        host, port = server.address
        asyncio.run(relay_with(peer, 61, domain_id, partition, body, extra={
            "vehicles": [{"file": str(uuv)}],
            "bulk": {"listen": "127.0.0.1:0", "dir": str(tmp_path / "relay"),
                     "sources": {"Remus-86": f"{host}:{port}"}}}))
    keys = {(s["vehicle_id"], s["image_id"]) for s in seen}
    assert keys == {("Remus-86", "atr-1"), ("Remus-86", "atr-2")}  # one product per image
    for n, data in images.items():
        samples = [s for s in seen if s["image_id"] == f"atr-{n}"]
        assert {s["sha256"] for s in samples} == {hashlib.sha256(data).hexdigest()}
        last = samples[-1]
        assert last["transfer_id"] and last["thumbnail"] > 0   # fetched, verified, pictured
        stored = tmp_path / "relay" / "Remus-86" / f"atr-{n}.png"
        assert stored.read_bytes() == data
        assert stored.with_name(f"atr-{n}.png.thumb.png").exists()
