"""The lanes' congestion control (links/udt/udt_cc.cpp, built by scripts/setup.sh): a
paced connection keeps to its cap through a lossy radio where libudt's own control holds
it below; unpaced it follows UDT's rules; where it is missing, everything runs as before."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("udt4py")

from lossy_proxy import LossyProxy
from udt_helpers import paces_until, wait_for

from links.udt import UdtBulkChannel, udt_cc
from links.udt.image_server import ImageServer

pytestmark = pytest.mark.udt

SIZE = 1 << 20
CAP = 500_000  # UDT_MAXBW, bytes/s on the wire: 4 Mbit/s, a fifth of the radio


def _sink(install: bool) -> tuple[Any, list[Any], list[int], threading.Thread]:
    """A UDT listener (with our control when ``install``) that takes one connection and
    reads ``SIZE`` bytes: (the listener, the accepted socket once there, the counts read,
    its thread)."""
    udt4py = pytest.importorskip("udt4py")
    server = udt4py.UDTSocket()
    if install:
        assert udt_cc.install(server)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    accepted: list[Any] = []
    received: list[int] = []

    def sink() -> None:
        conn, _ = server.accept()
        accepted.append(conn)
        buf = bytearray(65536)
        while sum(received) < SIZE:
            received.append(conn.recv(buf))

    thread = threading.Thread(target=sink, daemon=True)
    thread.start()
    return server, accepted, received, thread


def _push(paced: bool) -> tuple[list[float], float]:
    """``SIZE`` bytes on one connection capped at ``CAP`` through a radio losing 3 % of
    its datagrams each way: (the paces kept, the cap's pace)."""
    udt4py = pytest.importorskip("udt4py")
    server, _, received, thread = _sink(install=False)
    with LossyProxy(server.address, loss=0.03, delay=0.010, rate_bps=20e6, seed=3,
                    lifetime=60) as proxy:
        client = udt4py.UDTSocket()
        if paced:
            assert udt_cc.install(client)
        client.connect(proxy.address)
        client.UDT_MAXBW = CAP
        if paced:
            assert udt_cc.pace(client)
        cap_pace = int(client.UDT_MSS) / CAP
        client.send(bytes(SIZE))
        paces = paces_until(client, received, SIZE, 0.01)
        thread.join(10)
        assert proxy.counters["up_lost"] > 10  # the radio did lose data
        client.close()
    server.close()
    return paces, cap_pace


def test_setup_built_the_control_and_it_loads():
    assert udt_cc.available(), (
        f"{udt_cc.library_path()} missing or not loadable: run scripts/setup.sh")


def test_a_paced_connection_keeps_its_cap_through_losses_that_hold_udts_own_back():
    """The reason for the control: UDT's own reads each loss as congestion and sends
    slower than the cap for seconds after; paced, the cap is the pace throughout."""
    own, cap_pace = _push(paced=False)
    assert max(own) > 1.5 * cap_pace, "libudt's own control held the connection back"
    paced, cap_pace = _push(paced=True)
    settled = paced[len(paced) // 10:]  # (before its first ACK: UDT's opening 1 µs)
    assert max(settled) <= 1.1 * cap_pace
    assert sorted(settled)[len(settled) // 2] == pytest.approx(cap_pace, rel=0.1)


def test_a_listener_with_the_control_follows_udts_rules_until_told_to_pace():
    """An image server's connections inherit the control from its listener: one serving a
    whole file keeps UDT's loss reaction; one serving a lane's segment is paced."""
    udt4py = pytest.importorskip("udt4py")
    server, accepted, _, thread = _sink(install=True)
    client = udt4py.UDTSocket()
    client.connect(server.address)
    (conn,) = wait_for(lambda: accepted, 10, "the connection accepted")
    assert udt_cc.paced(conn) is False  # inherited, UDT's rules
    assert udt_cc.paced(client) is None  # libudt's own control: not ours to switch
    assert not udt_cc.pace(client)
    assert udt_cc.pace(conn) and udt_cc.paced(conn) is True
    assert udt_cc.pace(conn, False) and udt_cc.paced(conn) is False
    client.send(bytes(SIZE))
    thread.join(10)
    client.close()
    conn.close()
    server.close()
    assert udt_cc.paced(conn) is None and not udt_cc.pace(conn)  # closed


def test_an_image_server_paces_segment_answers_and_not_whole_files(
        tmp_path: Path, make_file, monkeypatch):
    """A small file goes whole on one connection, on UDT's rules; a file of several
    segments goes on lanes, every segment's answer paced by its share."""
    small, small_content = make_file(200_000, name="atr-1.png")
    large, large_content = make_file(2 << 20, name="atr-2.png", seed=8)
    told: list[bool] = []
    real = udt_cc.pace

    def spy(sock: Any, on: bool = True) -> bool:
        told.append(on)
        return real(sock, on)

    monkeypatch.setattr(udt_cc, "pace", spy)
    verified: list[str] = []

    def publish(topic: str, sample: dict) -> None:
        if topic == "ImageProduct" and sample.get("transfer_id"):
            verified.append(sample["file_name"])

    with ImageServer(small.parent, vehicle_id="uuv1") as server, \
            UdtBulkChannel.ImageService(tmp_path / "relay", publish=publish,
                                        publish_data=False,
                                        sources={"*": f"127.0.0.1:{server.address[1]}"}
                                        ) as relay:
        for n, path in enumerate((small, large), 1):
            m = UdtBulkChannel.manifest_for_file(path, vehicle_id="uuv1")
            relay.announce({"vehicle_id": "uuv1", "image_id": f"atr-{n}",
                            "file_name": path.name, "size_bytes": m.size,
                            "sha256": m.sha256, "transfer_id": "", "format": "png",
                            "capture_time_ms": 1_700_000_000_000, "targets": []})
            wait_for(lambda name=path.name: name in verified, 30, f"{path.name} fetched")
            if path is small:
                assert told == [False]
                told.clear()
    assert (tmp_path / "relay" / "uuv1" / "atr-1.png").read_bytes() == small_content
    assert (tmp_path / "relay" / "uuv1" / "atr-2.png").read_bytes() == large_content
    # 32 segments of 64 KiB, each answered paced (and the whole-file verdict, if the
    # last segment's receipt did not bring it, on UDT's rules)
    assert told.count(True) >= 32 and all(told[:-1])


def test_without_the_control_adaptive_lanes_keep_udts_own(tmp_path: Path, make_file,
                                                           monkeypatch):
    """``EDGE_VIS_UDT_CC=off`` (or no library): nothing is installed and an adaptive push
    still arrives whole."""
    monkeypatch.setenv(udt_cc.ENV, "off")
    udt_cc._library.cache_clear()
    try:
        assert not udt_cc.available()
        udt4py = pytest.importorskip("udt4py")
        sock = udt4py.UDTSocket()
        assert not udt_cc.install(sock) and udt_cc.paced(sock) is None
        sock.close()
        path, content = make_file(2 << 20)
        with UdtBulkChannel.ImageService(tmp_path / "ops") as ops, LossyProxy(
                ops.address, loss=0.01, delay=0.005, rate_bps=40e6, seed=2,
                lifetime=60) as proxy:
            result = UdtBulkChannel.send_image(path, proxy.address, vehicle_id="uuv1",
                                               lanes=0, give_up_after=30)
        assert result.ok, result.reason
        assert (tmp_path / "ops" / "uuv1" / "img.png").read_bytes() == content
    finally:
        udt_cc._library.cache_clear()
