"""The relay itself receives images when its profile has ``[bulk]``: a real UDT transfer
from a vehicle into ``edge-vis run``'s runtime, announced on the relay's DDS side."""

from __future__ import annotations

import asyncio
import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from edge_vis.config import RelayProfile, from_mapping
from edge_vis.errors import ConfigError
from edge_vis.shell.relay import Runtime

pytestmark = pytest.mark.udt
udt = pytest.importorskip("links.udt")

from udt_helpers import free_udp_port, sha  # noqa: E402


class Recorder:
    """Stands in for the DDS bridge: keeps every sample the runtime publishes."""

    def __init__(self) -> None:
        self.samples: list[tuple[str, dict]] = []

    def publish(self, topic: str, sample: dict) -> None:
        self.samples.append((topic, dict(sample)))

    def close(self) -> None:
        pass


def profile(tmp_path: Path, port: int) -> RelayProfile:
    text = f"""
    [access]
    any_operator = true
    [bulk]
    listen = "127.0.0.1:{port}"
    dir = "{tmp_path / 'images'}"
    quota = 10_000_000
    """
    return from_mapping(tomllib.loads(text), file="relay.toml")


def fetch_announced(tmp_path: Path, server: tuple[str, int], vehicle_id: str,
                    announced: dict) -> dict[tuple[str, str], dict]:
    """Run the relay with ``[bulk]`` and ``server`` as ``vehicle_id``'s image server, put
    ``announced`` through its publish path and wait for the fetched product; return the
    ``ImageProduct`` samples it published, by key."""
    recorder = Recorder()
    text = f"""
    [access]
    any_operator = true
    [bulk]
    listen = "127.0.0.1:{free_udp_port()}"
    dir = "{tmp_path / 'images'}"
    fetch_priority = "oldest"
    [bulk.sources]
    "{vehicle_id}" = "{server[0]}:{server[1]}"
    """
    prof = from_mapping(tomllib.loads(text), file="relay.toml")

    async def main() -> None:
        runtime = Runtime(prof, publisher_factory=lambda _rt: recorder)
        await runtime.start()
        try:
            runtime._publish("ImageProduct", announced)
            for _ in range(200):
                await asyncio.sleep(0.05)
                if any(t == "ImageProduct" and s["transfer_id"] for t, s in recorder.samples):
                    break
            await asyncio.sleep(0.3)
        finally:
            await runtime.stop()

    asyncio.run(main())
    return {(s["vehicle_id"], s["image_id"]): s for t, s in recorder.samples
            if t == "ImageProduct"}


def test_relay_receives_verifies_and_announces_an_image(
    tmp_path: Path, make_file: Callable[..., tuple[Path, bytes]]
) -> None:
    port = free_udp_port()
    path, content = make_file(300_000, "atr-7.png")
    recorder = Recorder()

    async def main() -> udt.TransferResult:
        runtime = Runtime(profile(tmp_path, port), publisher_factory=lambda _rt: recorder)
        await runtime.start()
        try:
            return await asyncio.to_thread(udt.send_image, path, ("127.0.0.1", port),
                                           vehicle_id="uuv-delta", give_up_after=20.0)
        finally:
            await asyncio.sleep(0.3)  # let the announcement reach the loop
            await runtime.stop()

    result = asyncio.run(main())
    assert result.ok
    stored = tmp_path / "images" / "uuv-delta" / "atr-7.png"
    assert stored.read_bytes() == content
    products = [s for t, s in recorder.samples if t == "ImageProduct"]
    assert products and products[-1]["sha256"] == sha(content)
    assert products[-1]["vehicle_id"] == "uuv-delta"
    chunks = sorted((s["chunk_index"], bytes(s["data"])) for t, s in recorder.samples
                    if t == "ImageData")
    assert b"".join(data for _, data in chunks) == content


def test_bulk_profile_errors_name_the_key(tmp_path: Path) -> None:
    text = """
    [bulk]
    listen = "nowhere"
    forward = ["ops:99999"]
    forward_lanes = 40
    """
    with pytest.raises(ConfigError) as info:
        from_mapping(tomllib.loads(text), file="relay.toml")
    message = str(info.value)
    for key in ("bulk.listen", "bulk.dir", "bulk.forward[0]", "bulk.forward_lanes"):
        assert key in message


def test_relay_fetches_an_announced_image_from_the_vehicle(
    tmp_path: Path, make_file: Callable[..., tuple[Path, bytes]]
) -> None:
    """The uuv translator's announcement goes through the relay's publish path: the relay
    fetches the file from the vehicle's image server and the announced product (same
    key) gains the transfer id; no second product appears."""
    path, content = make_file(400_000, "atr-12.png")
    announced = {"vehicle_id": "Nemo-60", "image_id": "atr-12", "file_name": "atr-12.png",
                 "size_bytes": len(content), "sha256": sha(content), "transfer_id": "",
                 "format": "png", "capture_time_ms": 0, "targets": []}
    with udt.UdtBulkChannel.ImageServer(path.parent, vehicle_id="uuv-delta") as server:
        products = fetch_announced(tmp_path, server.address, "Nemo-60", announced)
    assert list(products) == [("Nemo-60", "atr-12")]
    assert products[("Nemo-60", "atr-12")]["transfer_id"]
    (stored,) = (tmp_path / "images").rglob("atr-12.png")
    assert stored.read_bytes() == content


def test_relay_fetches_an_image_announced_by_a_profile_mapping(
    tmp_path: Path, make_file: Callable[..., tuple[Path, bytes]]
) -> None:
    """A custom vehicle declared in a profile, no Python: the generic translator's
    announcement mapping (tests/translators/SurveyImages.xml) yields the product, and the
    relay's publish path fetches the file it names from the vehicle's image server."""
    from edge_vis.catalogue import default_catalogue
    from edge_vis.catalogue.jsidl import load_jsidl
    from edge_vis.jaus.address import JausAddress
    from edge_vis.kit import TranslatorContext, VehicleView
    from translators.generic import GenericTranslator

    catalogue = default_catalogue()
    catalogue.add(load_jsidl([Path(__file__).parents[1] / "translators" / "SurveyImages.xml"]),
                  source="test JSIDL")
    generic = GenericTranslator()
    generic.configure({"mappings": [{"message": "ReportSurveyImage", "image": {
        "id_field": "image_id", "name_field": "file_name", "format": "png",
        "size_field": "size", "sha256_field": "sha256"}}]})
    generic.verify(catalogue)
    path, content = make_file(300_000, "survey-7.png")
    message = catalogue.decode(catalogue.encode("ReportSurveyImage", {
        "image_id": 7, "size": len(content), "sha256": sha(content), "file_name": path.name}))
    vehicle = VehicleView("Survey-1", 151, name="Survey", address=JausAddress(151, 1, 1),
                          online=True)
    ctx = TranslatorContext(now=0.0, timestamp_ms=0, relay_id=JausAddress(42, 1, 1),
                            vehicle=vehicle, catalogue=catalogue)
    (action,) = generic.on_message(message.name, message.fields, ctx)
    assert action.topic == "ImageProduct"
    with udt.UdtBulkChannel.ImageServer(path.parent, vehicle_id="Survey-1") as server:
        products = fetch_announced(tmp_path, server.address, "Survey-1", action.sample)
    assert list(products) == [("Survey-1", "ReportSurveyImage-7")]  # one product, fetched
    assert products[("Survey-1", "ReportSurveyImage-7")]["transfer_id"]
    (stored,) = (tmp_path / "images").rglob("survey-7.png")
    assert stored.read_bytes() == content
