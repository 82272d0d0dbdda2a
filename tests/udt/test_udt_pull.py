"""Pull over real UDT sockets: a vehicle's image server, the relay fetching what was announced.

The announcement is the ``ImageProduct`` sample the uuv translator makes of
ReportAtrImageAvailable (no transfer id yet); the relay's image service fetches the file
from the vehicle's ``serve-images`` server, verifies it against the announced SHA-256 and
publishes one product per image whatever arrives first.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("udt4py")

from udt_helpers import free_udp_port, sha, wait_for

from links.udt import UdtBulkChannel
from links.udt.fetch_queue import FetchQueue
from links.udt.image_index import ImageIndex
from links.udt.image_service import manifest_for_file

pytestmark = pytest.mark.udt


class Bus:
    """Keeps what the image service publishes, as the DDS bridge would receive it."""

    def __init__(self) -> None:
        self.samples: list[tuple[str, dict]] = []
        self.lock = threading.Lock()

    def publish(self, topic: str, sample: dict) -> None:
        with self.lock:
            self.samples.append((topic, dict(sample)))

    def of(self, topic: str) -> list[dict]:
        with self.lock:
            return [s for t, s in self.samples if t == topic]

    def products(self) -> dict[tuple[str, str], dict]:
        """Latest ImageProduct per DDS key, as a late-joining reader would see them."""
        return {(s["vehicle_id"], s["image_id"]): s for s in self.of("ImageProduct")}


def announcement(content: bytes, number: int, vehicle: str = "Nemo-60",
                 confidence: float = 0.8) -> dict:
    """The ImageProduct the uuv translator publishes for ReportAtrImageAvailable."""
    return {"vehicle_id": vehicle, "image_id": f"atr-{number}", "file_name": f"atr-{number}.png",
            "size_bytes": len(content), "sha256": sha(content), "transfer_id": "",
            "format": "png", "capture_time_ms": 1_700_000_000_000 + number,
            "targets": [{"target_class": "mine-like", "confidence": confidence,
                         "latitude": 1.0, "longitude": 2.0, "depth": float("nan")}]}


def fast_queue() -> FetchQueue:
    return FetchQueue(initial=0.1, maximum=0.5, mismatch_delay=0.1)


def service(tmp_path: Path, bus: Bus, source: tuple[str, int], **kw: object
            ) -> UdtBulkChannel.ImageService:
    return UdtBulkChannel.ImageService(tmp_path / "relay", publish=bus.publish,
                                       sources={"*": source}, fetch_queue=fast_queue(), **kw)


@pytest.mark.parametrize("order", ["announce-first", "push-first", "at-once"])
def test_one_product_per_image_in_every_order(tmp_path: Path, make_file, order: str):
    path, content = make_file(600_000, "atr-5.png")
    bus = Bus()
    with UdtBulkChannel.ImageServer(path.parent, vehicle_id="uuv-delta") as server, \
            service(tmp_path, bus, server.address) as relay:
        if order == "push-first":
            assert UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv-delta").ok
            bus.publish("ImageProduct", relay.announce(announcement(content, 5)))
        elif order == "announce-first":
            bus.publish("ImageProduct", relay.announce(announcement(content, 5)))
        else:
            pusher = threading.Thread(target=UdtBulkChannel.send_image,
                                      args=(path, relay.address), kwargs={"vehicle_id": "x"})
            pusher.start()
            bus.publish("ImageProduct", relay.announce(announcement(content, 5)))
            pusher.join()
        wait_for(lambda: any(p["transfer_id"] for p in bus.products().values()), 20,
                 "the verified product")
        time.sleep(0.5)  # a second product would show up now
        products = bus.products()
    assert len(products) == 1, products
    (product,) = products.values()
    assert product["sha256"] == sha(content)
    assert product["targets"][0]["target_class"] == "mine-like"
    key = (product["vehicle_id"], product["image_id"])
    assert {(s["vehicle_id"], s["image_id"]) for s in bus.of("TransferStatus")} <= {key}
    if order == "announce-first":
        assert key == ("Nemo-60", "atr-5")
        wait_for(lambda: server.counters["served"] == 1, 5, "the server's receipt")


def test_an_announcement_during_a_pushed_files_verification_joins_its_product(
        tmp_path: Path, make_file):
    # the sender may hold its verdict (it comes with the last segment's receipt) before the
    # relay has published the product: an announcement then must not start a second one
    path, content = make_file(1000, "atr-7.png")
    manifest = manifest_for_file(path, vehicle_id="uuv-delta")
    index = ImageIndex()
    status_key = index.key(manifest)  # the push's first TransferStatus names the image
    announced = index.announced(announcement(content, 7))
    assert (announced["vehicle_id"], announced["image_id"]) == status_key
    assert announced["transfer_id"] == ""  # not here yet: the relay may still fetch it
    assert announced["targets"][0]["target_class"] == "mine-like"
    verified = index.transferred(manifest)
    assert (verified["vehicle_id"], verified["image_id"]) == status_key
    assert verified["transfer_id"] == manifest.transfer_id and verified["targets"]


def test_fetch_resumes_after_the_connection_is_cut_several_times(tmp_path: Path, make_file):
    path, content = make_file(6 << 20, "atr-9.png")
    bus = Bus()
    with UdtBulkChannel.ImageServer(path.parent, max_rate_bps=40_000_000) as server, \
            service(tmp_path, bus, server.address, fetch_lanes=1) as relay:
        relay.announce(announcement(content, 9))
        cuts = 0
        deadline = time.monotonic() + 30
        while cuts < 4 and time.monotonic() < deadline:
            if relay.receiver._conns:
                time.sleep(0.2)  # let some data arrive
                cuts += relay.receiver.drop_connections() > 0
                time.sleep(0.3)
            time.sleep(0.02)
        wait_for(lambda: (tmp_path / "relay" / "uuv1" / "atr-9.png").exists()
                 or list((tmp_path / "relay").rglob("atr-9.png")), 30, "the fetched file")
    assert cuts == 4
    (stored,) = (tmp_path / "relay").rglob("atr-9.png")
    assert stored.read_bytes() == content
    assert relay.puller.counters["attempts"] >= 5
    resumed = [s for s in bus.of("TransferStatus") if s["state"] == "TRANSFER_ACTIVE"
               and s["bytes_done"] > 0]
    assert resumed, "no fetch resumed at the offset already held"


def test_a_hash_mismatch_is_refused_with_a_reason_and_fetched_again(tmp_path: Path, make_file):
    path, content = make_file(300_000, "atr-3.png")
    path.write_bytes(b"not the announced picture" * 100)  # the vehicle is still writing it
    bus = Bus()
    with UdtBulkChannel.ImageServer(path.parent) as server, \
            service(tmp_path, bus, server.address) as relay:
        relay.announce(announcement(content, 3))
        refused = wait_for(lambda: [s for s in bus.of("TransferStatus")
                                    if "SHA-256 mismatch" in s["error"]], 10, "a refusal")
        path.write_bytes(content)  # now it is the announced image
        wait_for(lambda: any(p.get("transfer_id") for p in bus.of("ImageProduct")), 20,
                 "the image fetched again")
    assert "announced" in refused[0]["error"]
    assert relay.receiver.counters["verified"] == 1
    wait_for(lambda: server.counters["served"] == 1, 5, "the server's receipt")


def test_a_vehicle_out_of_reach_is_retried_until_it_comes_back(tmp_path: Path, make_file):
    path, content = make_file(200_000, "atr-4.png")
    port = free_udp_port()
    bus = Bus()
    with service(tmp_path, bus, ("127.0.0.1", port)) as relay:
        relay.announce(announcement(content, 4))
        wait_for(lambda: relay.puller.counters["attempts"] >= 3, 20, "retries")
        assert not any(p.get("transfer_id") for p in bus.of("ImageProduct"))
        with UdtBulkChannel.ImageServer(path.parent, ("127.0.0.1", port)):
            wait_for(lambda: any(p.get("transfer_id") for p in bus.of("ImageProduct")), 20,
                     "the image once the vehicle is back")
    assert relay.puller.counters["fetched"] == 1


def test_the_fetch_keeps_to_the_budget_left_by_jaus_traffic(tmp_path: Path, make_file):
    path, content = make_file(1_500_000, "atr-6.png")
    bus = Bus()
    with UdtBulkChannel.ImageServer(path.parent) as server, \
            service(tmp_path, bus, server.address, fetch_budget_bps=10_000_000,
                    reserved_bps=lambda: 2_000_000.0) as relay:
        started = time.monotonic()
        relay.announce(announcement(content, 6))
        wait_for(lambda: any(p.get("transfer_id") for p in bus.of("ImageProduct")), 30,
                 "the fetched image")
        elapsed = time.monotonic() - started
    assert relay.puller.rate() == 8_000_000
    # 12 Mbit in the 8 Mbit/s JAUS leaves cannot take less than 1.5 s (UDT starts in a burst)
    assert elapsed > 0.7 * len(content) * 8 / 8_000_000


def test_queue_fetches_the_most_confident_image_first(tmp_path: Path, make_file):
    low, low_content = make_file(100_000, "atr-1.png", seed=1)
    _, high_content = make_file(100_000, "atr-2.png", seed=2)
    bus = Bus()
    port = free_udp_port()
    relay = service(tmp_path, bus, ("127.0.0.1", port))
    relay.announce(announcement(low_content, 1, confidence=0.3))  # announced while busy
    relay.announce(announcement(high_content, 2, confidence=0.95))
    with relay, UdtBulkChannel.ImageServer(low.parent, ("127.0.0.1", port)):
        wait_for(lambda: len([p for p in bus.of("ImageProduct") if p.get("transfer_id")])
                 == 2, 30, "both images")
    fetched = [p["image_id"] for p in bus.of("ImageProduct") if p.get("transfer_id")]
    assert fetched == ["atr-2", "atr-1"]


def test_a_large_image_is_fetched_on_parallel_lanes(tmp_path: Path, make_file, caplog):
    """Files of several MiB are fetched on parallel lanes, segment after segment on each
    connection, paced by the image server; the segment that completes the file brings
    the verdict, so no whole-file FETCH follows."""
    path, content = make_file(8 << 20, "atr-21.png")
    bus = Bus()
    caplog.set_level(logging.INFO, logger="links.udt.image_server")
    with UdtBulkChannel.ImageServer(path.parent) as server, \
            service(tmp_path, bus, server.address) as relay:
        relay.announce(announcement(content, 21))
        wait_for(lambda: list((tmp_path / "relay").rglob("atr-21.png")), 60, "the fetched file")
        wait_for(lambda: server.counters["served"] >= 1, 5, "the server's receipt")
    (stored,) = (tmp_path / "relay").rglob("atr-21.png")
    assert stored.read_bytes() == content
    # lanes opened one per tick, each asking for several segments; the whole-file
    # verdict on a lane's open connection
    assert 2 <= server.counters["connections"] <= 16
    assert server.counters["served"] > server.counters["connections"]
    assert server.counters["interrupted"] == 0
    assert [s["transfer_id"] for s in bus.of("ImageProduct")][-1]
    served = [r.getMessage() for r in caplog.records
              if r.getMessage().startswith("served atr-21.png")]
    assert [m for m in served if m.endswith("stored; SHA-256 verified")]
    assert not [m for m in served if "segment" not in m]
    # every lane's connection from one port of the relay's (one multiplexer in libudt)
    assert len({m.split(" to ")[1].split(": ")[0] for m in served}) == 1
    # the course of the rate the image server paced the lanes at, for the bench
    assert server.rate_history[0][1:] == (6e6, "startup")


def test_the_image_server_hashes_ahead_and_again_when_a_file_changes(tmp_path: Path,
                                                                       make_file):
    path, old = make_file(2 << 20, "atr-11.png")
    with UdtBulkChannel.ImageServer(path.parent) as server:
        # hashed in the background at start, before anyone asks
        wait_for(lambda: "atr-11.png" in server._manifests, 10, "the file hashed ahead")
        assert server._manifests["atr-11.png"][1].sha256 == sha(old)
        new = old[::-1]
        path.write_bytes(new)  # rewritten after it was hashed: served as it is now
        os.utime(path, ns=(time.time_ns(), time.time_ns() + 1_000_000_000))
        bus = Bus()
        with service(tmp_path, bus, server.address) as relay:
            relay.announce(announcement(new, 11))
            wait_for(lambda: any(p.get("transfer_id") for p in bus.of("ImageProduct")), 30,
                     "the rewritten image")
    (stored,) = (tmp_path / "relay").rglob("atr-11.png")
    assert stored.read_bytes() == new
    assert not [s for s in bus.of("TransferStatus") if "mismatch" in s["error"]]
