"""Bulk image transfer over real UDT sockets on loopback: relay chain, resume, bad input."""

from __future__ import annotations

import itertools
import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("udt4py")

from lossy_proxy import LossyProxy
from udt_helpers import RawClient, free_udp_port, sha, wait_for

from links.udt import UdtBulkChannel
from links.udt.protocol import (
    HEADER,
    MAGIC,
    VERSION,
    FrameType,
    Manifest,
    Reason,
    SenderConnection,
    encode_frame,
    transfer_id_for,
)

pytestmark = pytest.mark.udt

FAST = UdtBulkChannel.Backoff(initial=0.02, maximum=0.2, jitter=0.0)


def spool_entries(spool: UdtBulkChannel.Spool) -> list:
    """A consistent copy of the spool's entries while its threads change them."""
    with spool._lock:
        return list(spool._entries.values())


def manifest(content: bytes, name: str = "img.png", **over: object) -> Manifest:
    digest = sha(content)
    fields: dict[str, object] = {
        "transfer_id": transfer_id_for("uuv1", name, digest), "vehicle_id": "uuv1",
        "name": name, "size": len(content), "sha256": digest, "image_format": "png",
        "capture_time": 1.7e9,
    }
    fields.update(over)
    return Manifest(**fields)  # type: ignore[arg-type]


def test_20mb_vehicle_to_relay_to_operator(tmp_path: Path, make_file):
    path, content = make_file(20 << 20, "sonar_0001.png")
    published: list[tuple[str, dict]] = []
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, UdtBulkChannel.ImageService(
        tmp_path / "relay", forward=[ops.address],
        publish=lambda topic, sample: published.append((topic, sample)),
    ) as relay:
        atr = UdtBulkChannel.AtrMetadata(
            "mine-like", 0.91, UdtBulkChannel.Position(36.6, -121.9, 18.5))
        m = UdtBulkChannel.manifest_for_file(path, vehicle_id="uuv1", atr=atr, capture_time=1.7e9)
        result = UdtBulkChannel.send_image(path, relay.address, manifest=m)
        assert result.ok, result.reason
        final = tmp_path / "ops" / "uuv1" / "sonar_0001.png"
        wait_for(lambda: relay.spool.reserved_bytes() == 0, 20, "the relay to forward")
        assert sha(final.read_bytes()) == sha(content)
        assert list((tmp_path / "relay" / ".spool" / "ready").iterdir()) == []
    # the forwarder's lanes were paced: the course of their rate, for the bench
    assert relay.forwarders[0].rate_history[0][1:] == (6e6, "startup")
    topics = [t for t, _ in published]
    (product,) = [s for t, s in published if t == "ImageProduct"]
    assert product["file_name"] == "sonar_0001.png" and product["sha256"] == sha(content)
    assert product["size_bytes"] == len(content) and product["capture_time_ms"] == 1_700_000_000_000
    assert product["targets"] == [{"target_class": "mine-like", "confidence": 0.91,
                                   "latitude": 36.6, "longitude": -121.9, "depth": 18.5}]
    chunks = [s for t, s in published if t == "ImageData"]
    assert b"".join(c["data"] for c in chunks) == content
    assert {c["chunk_count"] for c in chunks} == {len(chunks)}
    assert max(len(c["data"]) for c in chunks) <= 64 * 1024
    states = [s["state"] for t, s in published if t == "TransferStatus"]
    assert states[0] == "TRANSFER_ACTIVE" and states[-1] == "TRANSFER_COMPLETE"
    # Announced only after verification: the product comes after the last status change.
    assert topics.index("ImageProduct") > topics.index("TransferStatus")


def test_transfer_interrupted_ten_times_completes(tmp_path: Path, make_file):
    path, content = make_file(6 << 20)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        drops = 0
        done = threading.Event()

        def cut_the_link() -> None:
            nonlocal drops
            last = 0
            while drops < 10 and not done.is_set():
                entries = [e for e in spool_entries(ops.spool) if e.claims]
                if entries and entries[0].written[0] - last >= 300_000:
                    last = entries[0].written[0]
                    drops += ops.receiver.drop_connections() > 0
                time.sleep(0.005)

        cutter = threading.Thread(target=cut_the_link)
        cutter.start()
        result = UdtBulkChannel.send_image(path, ops.address, vehicle_id="uuv1", lanes=1,
                                    max_rate_bps=24_000_000, backoff=FAST, give_up_after=20)
        done.set()
        cutter.join()
    assert result.ok, result.reason
    assert drops == 10
    assert result.attempts >= 11
    resumed = [o for o in result.resumed_from if o]
    assert len(resumed) >= 10 and resumed == sorted(resumed)
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def _receiver_process(out: Path, port: int) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "edge_vis", "receive-images", "--dir", str(out),
         "--listen", f"127.0.0.1:{port}"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert "receiving images on" in line, line + proc.stderr.read() if proc.stderr else ""
    return proc


def test_receiver_killed_mid_transfer_resumes_from_its_journal(tmp_path: Path, make_file):
    path, content = make_file(8 << 20)
    port = free_udp_port()
    out = tmp_path / "ops"
    proc = _receiver_process(out, port)
    results = []
    sender = threading.Thread(target=lambda: results.append(UdtBulkChannel.send_image(
        path, ("127.0.0.1", port), vehicle_id="uuv1", max_rate_bps=16_000_000, lanes=1,
        backoff=UdtBulkChannel.Backoff(initial=0.1, maximum=0.3), give_up_after=20,
        stall_timeout=1.5)))
    sender.start()
    part = out / ".spool" / "partial" / f"{transfer_id_for('uuv1', 'img.png', sha(content))}.part"
    journal = out / ".spool" / "journal.log"

    def durable() -> int:
        records = [json.loads(x) for x in journal.read_text().split()] if journal.exists() else []
        return max([r["n"] for r in records if r["op"] == "durable"], default=0)

    try:
        wait_for(lambda: durable() > 1_000_000, 15, "a megabyte made durable")
        proc.send_signal(signal.SIGKILL)  # power cut: no clean shutdown
        proc.wait(5)
        held = durable()
        assert part.stat().st_size >= held
        assert held < len(content)
        proc = _receiver_process(out, port)
        sender.join(30)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
    (result,) = results
    assert result.ok, result.reason
    assert any(0 < o <= held for o in result.resumed_from), result.resumed_from
    assert (out / "uuv1" / "img.png").read_bytes() == content


def test_forwarding_waits_for_a_target_that_is_down(tmp_path: Path, make_file):
    path, content = make_file(300_000)
    port = free_udp_port()
    with UdtBulkChannel.ImageService(
        tmp_path / "relay", forward=[("127.0.0.1", port)],
        forward_backoff=UdtBulkChannel.Backoff(initial=0.1, maximum=0.3),
    ) as relay:
        assert UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv1").ok
        time.sleep(1.0)  # the operator station is down: the file waits in the relay's spool
        queued = list(relay.spool.outbox(f"127.0.0.1:{port}"))
        assert [m.name for m, _ in queued] == ["img.png"]
        assert queued[0][1].read_bytes() == content
        with UdtBulkChannel.ImageService(tmp_path / "ops", ("127.0.0.1", port)):
            final = tmp_path / "ops" / "uuv1" / "img.png"
            wait_for(final.exists, 10, "the forwarded file")
            wait_for(lambda: relay.spool.reserved_bytes() == 0, 5, "the relay to let go")
        assert final.read_bytes() == content


def test_rate_budget_is_respected(tmp_path: Path, make_file):
    path, content = make_file(1_500_000)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        started = time.monotonic()
        result = UdtBulkChannel.send_image(path, ops.address, max_rate_bps=8_000_000)
        elapsed = time.monotonic() - started
    assert result.ok
    # 12 Mbit at 8 Mbit/s cannot take less than 1.5 s; allow for UDT's startup burst.
    assert elapsed > 0.7 * len(content) * 8 / 8_000_000


class _LosesChosen(LossyProxy):
    """The emulated radio losing the first copy of chosen datagrams, one after another
    (which packet is lost matters here, not how many), and counting UDT's NAKs each way
    after the last of them: a test's own proxy."""

    def __init__(self, upstream: tuple[str, int], picks: list[Callable[[str, bytes], bool]],
                 **options: Any) -> None:
        super().__init__(upstream, **options)
        self.picks = picks  # (direction, datagram) -> lose it?
        self.naks: Counter[str] = Counter()

    def _admit(self, direction: Any, data: bytes, now: float) -> float | None:
        if not self.picks and data[0] & 0x80 and int.from_bytes(data[:2], "big") & 0x7FFF == 3:
            self.naks[direction.name] += 1  # UDT's NAK
        if self.picks and self.picks[0](direction.name, data):
            self.picks.pop(0)
            return None
        return super()._admit(direction, data, now)


UDT_HEADER = 16
"""Bytes of UDT's header on every packet; a data packet's first bit is 0."""


def _data(direction: str, data: bytes, size: int) -> bool:
    return direction == "up" and not data[0] & 0x80 and len(data) - UDT_HEADER == size


def _tenth_data_packet() -> Callable[[str, bytes], bool]:
    seen = itertools.count(1)
    return lambda direction, data: _data(direction, data, 1456) and next(seen) == 10


def _last_data(direction: str, data: bytes) -> bool:
    # 100,000 bytes go as one DATA frame of 100,008 bytes: 68 packets of 1,456 and 1,000
    return _data(direction, data, 1000)


def _receipt(direction: str, data: bytes) -> bool:
    return direction == "down" and not data[0] & 0x80 and data[UDT_HEADER:UDT_HEADER + 4] == (
        HEADER.pack(MAGIC, VERSION, FrameType.RECEIPT, 0)[:4])


@pytest.mark.parametrize(("pick", "reporter"), [(_last_data, "down"), (_receipt, "up")],
                         ids=["last data packet", "receipt"])
def test_a_lost_last_packet_is_reported_at_once_not_waited_for(
        tmp_path: Path, make_file, pick: Callable[[str, bytes], bool], reporter: str):
    """The last packet before a pause has nothing behind it that shows it missing: UDT
    would wait for its retransmission timer (at least 300 ms, each time, on every lossy
    segment and receipt). The trailer behind it makes the other end report the loss (a
    NAK) as soon as the trailer arrives, on a connection's first transfer and on later
    ones (a batch, the relay's forwarder)."""
    first, _ = make_file(200_000, name="first.png")  # its 10th packet lost too
    second, content = make_file(100_000, name="second.png")
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, _LosesChosen(
            ops.address, [_tenth_data_packet(), pick], delay=0.02, lifetime=40) as proxy, \
            UdtBulkChannel.BulkSender(proxy.address, lanes=1, give_up_after=30) as sender:
        for path in (first, second):  # one connection, as a batch
            result = sender.send_file(path, UdtBulkChannel.manifest_for_file(
                path, vehicle_id="uuv1"))
            assert result.ok, result.reason
    assert not proxy.picks, "the chosen packets never crossed the radio"
    assert proxy.naks[reporter] >= 1, "the loss waited for UDT's retransmission timer"
    assert (tmp_path / "ops" / "uuv1" / "second.png").read_bytes() == content


def test_a_lane_whose_shared_port_was_taken_leaves_from_a_new_one():
    """A transfer's lanes connect from one port; once every lane on it had closed and
    libudt had let the port go, something else may hold it: the next lane binds a new
    port and connects, and the lanes after it share that one."""
    import socket

    from links.udt.transfer import LocalPort, _close, _connect, listen

    server = listen(("127.0.0.1", 0), linger=0)
    accepted: list[Any] = []
    threading.Thread(target=lambda: [accepted.append(server.accept()) for _ in range(2)],
                     daemon=True).start()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
        squatter.bind(("0.0.0.0", 0))
        taken = squatter.getsockname()[1]
        local = LocalPort()
        local.port = taken
        first = _connect(server.address, 2.0, None, local)
        second = _connect(server.address, 2.0, None, local)
    try:
        assert local.port not in (0, taken)
        assert first.address[1] == second.address[1] == local.port
        wait_for(lambda: len(accepted) == 2, 5, "both connections accepted")
        assert {peer[1] for _, peer in accepted} == {local.port}
    finally:
        for sock in (first, second, *(s for s, _ in accepted), server):
            _close(sock)


def test_a_lane_closed_under_the_coordinators_look_reads_as_nothing_pending():
    """The lanes' coordinator reads each lane's socket while the lane's own thread may be
    closing it after a drop; udt4py then raises TypeError, which ended the whole
    transfer's thread (seen once in a cut-twice run)."""
    import udt4py

    sock = udt4py.UDTSocket()
    sock.close()
    conn = SenderConnection()
    m = manifest(b"x" * 5000)
    conn.send_manifest(m, 0.0)
    conn.receive_data(encode_frame(FrameType.ACCEPT, struct.pack(">Q", 1000)), 0.0)
    sender = UdtBulkChannel.BulkSender(("127.0.0.1", free_udp_port()))
    sender._live, sender._live_conn = sock, conn  # the lane mid-transfer, as it closes
    assert sender.acknowledged() == (None, 1000, True)


def test_transfer_through_a_lossy_delaying_rate_limited_link(tmp_path: Path, make_file):
    path, content = make_file(400_000)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, LossyProxy(
        ops.address, loss=0.02, delay=0.01, jitter=0.002, rate_bps=20e6, seed=11, lifetime=40,
    ) as proxy:
        result = UdtBulkChannel.send_image(path, proxy.address, vehicle_id="uuv1", give_up_after=30)
    assert result.ok, result.reason
    assert proxy.counters["up_lost"] + proxy.counters["down_lost"] > 0
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def test_lanes_over_a_lossy_link_survive_a_drop_and_verify(tmp_path: Path, make_file):
    path, content = make_file(4 << 20)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, LossyProxy(
        ops.address, loss=0.01, delay=0.005, rate_bps=16e6, queue_bytes=256 * 1024, seed=5,
        lifetime=40,
    ) as proxy:
        results = []
        sender = threading.Thread(target=lambda: results.append(UdtBulkChannel.send_image(
            path, proxy.address, vehicle_id="uuv1", lanes=4, backoff=FAST, give_up_after=20)))
        sender.start()
        wait_for(lambda: [e for e in spool_entries(ops.spool) if len(e.claims) == 4
                          and sum(e.written) > 300_000], 20, "four lanes under way")
        assert ops.receiver.drop_connections() == 4
        sender.join(40)
    (result,) = results
    assert result.ok, result.reason
    # every lane came back on a new connection (a lane between two segments at the cut
    # reconnects on its next one, which its attempts do not count)
    assert ops.receiver.counters["connections"] >= 8
    # ... all from one port, as the lanes began: libudt tears down one multiplexer for
    # the transfer, not one per connection (LocalPort)
    assert proxy.counters["clients"] == 1
    assert sum(1 for o in result.resumed_from if o) >= 2
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def test_paced_lanes_through_a_radio_cut_twice_resume_and_verify(tmp_path: Path, make_file):
    """No flags: the lanes are paced from their connections' round trips and what the
    receiver acknowledges; cut twice, every lane resumes at what the spool holds."""
    path, content = make_file(3 << 20)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, LossyProxy(
        ops.address, delay=0.010, rate_bps=20e6, queue_bytes=64 * 1024, lifetime=60,
    ) as proxy:
        results = []
        sender = UdtBulkChannel.BulkSender(proxy.address, lanes=0, backoff=FAST,
                                           give_up_after=20)
        m = UdtBulkChannel.manifest_for_file(path, vehicle_id="uuv1")
        thread = threading.Thread(target=lambda: results.append(sender.send_file(path, m)))
        thread.start()
        for held in (600_000, 1_500_000):
            wait_for(lambda h=held: [e for e in spool_entries(ops.spool)
                                     if sum(e.durable) > h], 20, f"{held} bytes held")
            assert ops.receiver.drop_connections() >= 1
        thread.join(40)
        sender.close()
    (result,) = results
    assert result.ok, result.reason
    assert sum(1 for o in result.resumed_from if o) >= 1
    assert sender.rate_history, "the rate probe paced the lanes"
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def test_the_last_segment_of_a_push_brings_the_verdict_once(tmp_path: Path, make_file):
    """The receipt of the segment that completes the file carries its verified SHA-256,
    so the sender does not ask again with the whole-file manifest (a round trip less);
    a sender that does ask (an older one) is answered without a second announcement."""
    path, content = make_file(3 << 20)
    published: list[str] = []
    with UdtBulkChannel.ImageService(
            tmp_path / "ops", publish=lambda topic, sample: published.append(topic)) as ops:
        m = UdtBulkChannel.manifest_for_file(path, vehicle_id="uuv1")
        result = UdtBulkChannel.send_image(path, ops.address, manifest=m, lanes=4)
        assert result.ok, result.reason
        assert len(content) not in result.resumed_from  # no whole-file manifest was sent
        assert ops.receiver.counters["verified"] == 1
        with UdtBulkChannel.BulkSender(ops.address) as older:
            again = older.send_file(path, m)
        assert again.ok and again.resumed_from == (len(content),)
        wait_for(lambda: "ImageProduct" in published, 5, "the announcement")
        time.sleep(0.2)
    assert published.count("ImageProduct") == 1
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def test_lanes_whose_data_fails_the_hash_are_refused_then_sent_again(tmp_path: Path,
                                                                     make_file):
    """The receiver hashes each lane's segments as they are stored; data that is not the
    announced file is still refused at the verdict, and the right data then verifies."""
    path, content = make_file(2 << 20)
    lie = manifest(content[:-1] + bytes([content[-1] ^ 1]))  # one bit off at the very end
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        result = UdtBulkChannel.send_image(path, ops.address, manifest=lie, lanes=0)
        assert not result.ok
        assert result.code is Reason.HASH_MISMATCH
        assert "SHA-256 mismatch" in result.reason
        assert UdtBulkChannel.send_image(path, ops.address, manifest=manifest(content),
                                         lanes=0).ok
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


# --------------------------------------------------------------------------- bad input


@pytest.fixture
def receiver(tmp_path: Path):
    with UdtBulkChannel.ImageService(tmp_path / "out", quota_bytes=1 << 20) as svc:
        yield svc
        # Whatever happened before, the receiver still serves a good transfer ...
        good = tmp_path / "good.png"
        good.write_bytes(b"still serving" * 100)
        assert UdtBulkChannel.send_image(good, svc.address, vehicle_id="uuv1").ok
        assert (tmp_path / "out" / "uuv1" / "good.png").exists()
    # ... and nothing was written outside the output directory.
    outside = {p.name for p in tmp_path.iterdir()} - {"out", "good.png", "vehicle"}
    assert outside == set()
    assert not (tmp_path / "x").exists()


def test_data_beyond_the_manifest_size_is_refused(receiver, tmp_path: Path):
    m = manifest(b"0123456789")
    client = RawClient(receiver.address)
    client.send(encode_frame(FrameType.MANIFEST, m.to_json()))
    assert client.frame() == (FrameType.ACCEPT, struct.pack(">Q", 0))
    client.send(encode_frame(FrameType.DATA, b"x" * 25))
    ftype, payload = client.frame()
    assert ftype is FrameType.ERROR
    assert struct.unpack(">H", payload[:2])[0] == Reason.SIZE_MISMATCH
    assert "manifest says 10 bytes" in payload[2:].decode()
    client.close()
    assert not (tmp_path / "out" / "uuv1").exists()


def test_content_not_matching_the_manifest_hash_fails_the_receipt(receiver, make_file):
    path, content = make_file(200_000)
    lie = manifest(b"\x00" * len(content))  # right size, other content
    result = UdtBulkChannel.send_image(path, receiver.address, manifest=lie)
    assert not result.ok
    assert result.code is Reason.HASH_MISMATCH
    assert "SHA-256 mismatch" in result.reason


def test_garbage_connection_gets_a_reason_and_the_receiver_carries_on(receiver):
    client = RawClient(receiver.address)
    client.send(b"GET /images HTTP/1.1\r\nHost: relay\r\n\r\n")
    ftype, payload = client.frame()
    assert ftype is FrameType.ERROR
    assert "bad frame magic" in payload[2:].decode()
    client.close()
    assert receiver.receiver.counters["protocol_errors"] == 1


@pytest.mark.parametrize("name", ["../x", "/tmp/x", "a\x00b.png", "..", "sub/x.png"])
def test_file_names_escaping_the_spool_are_refused(receiver, name: str):
    raw = json.loads(manifest(b"payload").to_json())
    raw["name"] = name
    client = RawClient(receiver.address)
    client.send(encode_frame(FrameType.MANIFEST, json.dumps(raw).encode()))
    ftype, payload = client.frame()
    assert ftype is FrameType.REFUSE
    assert struct.unpack(">H", payload[:2])[0] == Reason.BAD_NAME
    assert "manifest.name" in payload[2:].decode()
    # The same connection may go on with a proper manifest.
    client.send(encode_frame(FrameType.MANIFEST, manifest(b"payload").to_json()))
    assert client.frame()[0] is FrameType.ACCEPT
    client.close()


def test_transfer_bigger_than_the_quota_is_refused(receiver, make_file):
    path, _ = make_file(2 << 20)
    result = UdtBulkChannel.send_image(path, receiver.address, vehicle_id="uuv1")
    assert not result.ok and result.code is Reason.QUOTA
    assert "spool quota full: img.png needs 2.0 MiB" in result.reason
    assert list((receiver.spool.root / "partial").iterdir()) == []


def test_oversized_frame_header_is_refused_without_buffering(receiver):
    client = RawClient(receiver.address)
    client.send(HEADER.pack(b"EB", 1, FrameType.MANIFEST, 1 << 31))
    ftype, payload = client.frame()
    assert ftype is FrameType.ERROR and "outside 2..16384" in payload[2:].decode()
    client.close()


def test_sender_reports_a_receiver_that_never_answers(make_file):
    path, _ = make_file(1000)
    started = time.monotonic()
    result = UdtBulkChannel.send_image(path, ("127.0.0.1", free_udp_port()), backoff=FAST,
                                give_up_after=1.0)
    assert not result.ok and result.code is Reason.TIMEOUT
    assert "no progress" in result.reason
    assert time.monotonic() - started < 10
    assert os.path.exists(path)


def _slow_png(side: int = 2000) -> bytes:
    """A PNG whose every row uses the Paeth filter: a few KiB that take the standard
    library's decoder about a second or two to thumbnail."""
    raw = b"".join(b"\x04" + bytes([y & 0xFF]) * side for y in range(side))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", __import__("zlib").crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", __import__("zlib").compress(raw)) + chunk(b"IEND", b""))


def test_forwarding_starts_on_verification_not_after_the_thumbnail(tmp_path: Path):
    # the relay's thumbnail of this picture takes a second or more: the operator side must
    # not wait for it (nor for the relay's own announcement)
    src = tmp_path / "src"
    src.mkdir()
    (src / "slow.png").write_bytes(_slow_png())
    seen: dict[str, float] = {}

    def mark(where: str, topic_seen: str, state: str | None = None):
        def publish(topic: str, sample: dict) -> None:
            if topic == topic_seen and (state is None or sample["state"] == state):
                seen.setdefault(where, time.monotonic())
        return publish

    with UdtBulkChannel.ImageService(tmp_path / "ops", publish_data=False, publish=mark(
            "operator verified", "TransferStatus", "TRANSFER_COMPLETE")) as ops, \
            UdtBulkChannel.ImageService(tmp_path / "relay", forward=[ops.address],
                                        publish_data=False,
                                        publish=mark("relay product", "ImageProduct")) as relay:
        assert UdtBulkChannel.send_image(src / "slow.png", relay.address, vehicle_id="uuv1").ok
        wait_for(lambda: len(seen) == 2, 30, "the relay's product and the operator's copy")
    assert seen["operator verified"] < seen["relay product"], seen
    assert (tmp_path / "ops" / "uuv1" / "slow.png.thumb.png").exists()
