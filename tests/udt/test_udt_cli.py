"""``edge-vis send-image`` and ``receive-images`` as a user runs them (real processes, UDT)."""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

pytest.importorskip("udt4py")

from udt_helpers import sha, wait_for

from edge_vis.cli.send_image import Progress, parse_rate
from links.udt import UdtBulkChannel

pytestmark = pytest.mark.udt


def edge_vis(*args: str) -> list[str]:
    return [sys.executable, "-m", "edge_vis", *args]


def test_send_image_exits_0_when_the_hash_is_confirmed(tmp_path: Path, make_file):
    path, content = make_file(3 << 20, "sonar.tif")
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        host, port = ops.address
        proc = subprocess.run(
            edge_vis("send-image", str(path), "--to", f"{host}:{port}", "--vehicle", "uuv3",
                     "--max-rate", "40M", "--lanes", "2", "--target-class", "mine-like",
                     "--confidence", "0.8", "--position", "36.5,-121.9,12"),
            capture_output=True, text=True, timeout=60,
        )
    assert proc.returncode == 0, proc.stderr
    assert "receiver verified the hash" in proc.stdout
    assert sha(content) in proc.stdout
    # Not a terminal: plain progress lines, the last one at 100 %.
    lines = [x for x in proc.stderr.splitlines() if "Mbit/s" in x]
    assert lines and "100.0%" in lines[-1] and "ETA" in lines[-1] and "\r" not in proc.stderr
    assert (tmp_path / "ops" / "uuv3" / "sonar.tif").read_bytes() == content


def test_send_image_sends_a_batch_on_one_connection(tmp_path: Path, make_file):
    files = [make_file(200_000 + i, f"img{i}.png", seed=i) for i in range(3)]
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        host, port = ops.address
        proc = subprocess.run(
            edge_vis("send-image", *(str(p) for p, _ in files), "--to", f"{host}:{port}"),
            capture_output=True, text=True, timeout=60,
        )
        connections = ops.receiver.counters["connections"]
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("receiver verified the hash") == 3
    assert connections == 1
    for i, (_, content) in enumerate(files):
        assert (tmp_path / "ops" / "vehicle" / f"img{i}.png").read_bytes() == content


def test_send_image_exits_1_with_the_receivers_reason(tmp_path: Path, make_file):
    path, _ = make_file(2 << 20)
    with UdtBulkChannel.ImageService(tmp_path / "ops", quota_bytes=1 << 20) as ops:
        host, port = ops.address
        proc = subprocess.run(
            edge_vis("send-image", str(path), "--to", f"{host}:{port}"),
            capture_output=True, text=True, timeout=60,
        )
    assert proc.returncode == 1
    assert "not delivered (QUOTA): spool quota full" in proc.stderr


def test_send_image_rejects_bad_arguments_clearly(tmp_path: Path):
    proc = subprocess.run(edge_vis("send-image", str(tmp_path / "missing.png"), "--to",
                                   "127.0.0.1:9"), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "no such file" in proc.stderr
    proc = subprocess.run(edge_vis("send-image", __file__, "--to", "nowhere"),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "expected HOST:PORT" in proc.stderr


@pytest.mark.parametrize(("lanes", "resumes"), [
    (["--lanes", "1"], r"\b1 resume\(s\)"),   # the one connection resumes at its offset
    ([], r"\b[1-9]\d* resume\(s\)"),           # adaptive lanes: each held segment resumes
])
def test_killed_sender_rerun_resumes_where_it_stopped(tmp_path: Path, make_file, lanes,
                                                      resumes):
    """The sender dies without closing; a re-run takes over the stale connection and resumes."""
    path, content = make_file(6 << 20)
    with UdtBulkChannel.ImageService(tmp_path / "ops") as ops:
        host, port = ops.address
        args = edge_vis("send-image", str(path), "--to", f"{host}:{port}", "--vehicle",
                        "uuv1", "--max-rate", "16M", *lanes)
        first = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        part = ops.spool.root / "partial"
        wait_for(lambda: any(p.stat().st_size > 1_000_000 for p in part.iterdir()), 20, "1 MB")
        first.send_signal(signal.SIGKILL)
        first.communicate(timeout=10)
        second = subprocess.run(args, capture_output=True, text=True, timeout=60)
    assert second.returncode == 0, second.stderr
    assert re.search(resumes, second.stdout), second.stdout
    assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content


def test_progress_bar_on_a_terminal():
    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    out = Tty()
    bar = Progress("img.png", out)
    bar(0, 4 << 20)
    bar._last = 0.0
    bar(2 << 20, 4 << 20)
    bar(4 << 20, 4 << 20)
    text = out.getvalue()
    assert text.count("\r[") == 3
    assert "[############............] img.png: 2.0/4.0 MiB  50.0%" in text
    assert text.endswith("ETA 00:00\x1b[K\n")


def test_rates_accept_suffixes():
    assert parse_rate("10M") == 10_000_000
    assert parse_rate("500k") == 500_000
    assert parse_rate("2500000") == 2_500_000


@pytest.mark.dds
def test_receive_images_publishes_the_image_on_dds(tmp_path: Path, make_file, monkeypatch):
    pytest.importorskip("cyclonedds")
    from edge_vis.dds import DdsBridge, loopback_config

    monkeypatch.setenv("CYCLONEDDS_URI", loopback_config())  # loopback only, here and child
    env = dict(os.environ)
    domain = 230 + os.getpid() % 3
    partition = f"udt-test-{uuid.uuid4().hex[:10]}"
    path, content = make_file(150_000, "sonar.png")
    rx = subprocess.Popen(
        edge_vis("receive-images", "--dir", str(tmp_path / "ops"), "--listen", "127.0.0.1:0",
                 "--domain", str(domain), "--partition", partition),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        assert rx.stdout is not None
        line = rx.stdout.readline()
        assert "receiving images on" in line, rx.stderr.read() if rx.stderr else ""
        address = line.split()[3]
        with DdsBridge(domain, (partition,)) as bridge:
            products = bridge.reader("ImageProduct")
            data = bridge.reader("ImageData")
            # ImageData is volatile: be matched with the receiver's writer before it writes.
            wait_for(data.matched_writers, 10, "DDS discovery")
            result = UdtBulkChannel.send_image(path, address, vehicle_id="uuv9")
            assert result.ok
            (product,) = products.collect(1, 10.0)
            chunks = data.collect(3, 10.0)
    finally:
        rx.send_signal(signal.SIGTERM)
        rx.wait(10)
    assert product["file_name"] == "sonar.png" and product["sha256"] == sha(content)
    assert product["vehicle_id"] == "uuv9"
    assert b"".join(bytes(c["data"]) for c in sorted(chunks, key=lambda c: c["chunk_index"])) \
        == content
