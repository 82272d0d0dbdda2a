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
