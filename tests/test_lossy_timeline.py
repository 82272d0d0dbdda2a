"""The emulated radio's record of when its link was busy, which ``bench/bulk.py`` reads to
say where a transfer's time went: real UDP datagrams through a real proxy on loopback."""

from __future__ import annotations

import socket
import time

import pytest

from edge_vis.tools.lossy_udp import FULL_BYTES, LossyProxy, separate_process

RATE = 1e6  # 1,200 bytes take 9.6 ms on the link


@pytest.fixture
def sink():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    yield s
    s.close()


def _burst(client: socket.socket, address: tuple[str, int], count: int, size: int) -> None:
    for _ in range(count):
        client.sendto(b"x" * size, address)


def test_the_timeline_says_when_the_link_carried_data_and_when_it_sat_idle(sink):
    with LossyProxy(sink.getsockname(), rate_bps=RATE, queue_bytes=1 << 20,
                    timeline=True) as proxy, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
        started = time.monotonic()
        _burst(client, proxy.address, 10, 1200)   # 96 ms of link time
        _burst(client, proxy.address, 5, 100)     # control: 4 ms
        time.sleep(0.4)
        _burst(client, proxy.address, 10, 1200)
        time.sleep(0.2)
        up = proxy.timelines()["up"]
    assert "down" in proxy.timelines() and proxy.timelines()["down"].first_full is None
    # the busy time is the bytes at the link's rate, whatever the clock did
    assert up.busy_full == pytest.approx(20 * 1200 * 8 / RATE)
    assert up.busy_small == pytest.approx(5 * 100 * 8 / RATE)
    assert up.small_sizes == {100: 5}  # which control packets the control time went to
    assert started <= up.first_full < up.last_full
    # the pause between the bursts (0.4 s less the first burst's 0.1 s on the link) is
    # the idle time while data flowed; loose bounds: the test's own sleeps are not exact
    idle = up.idle(up.first_full, up.last_full)
    assert 0.2 < idle < 0.4
    assert up.last_full - up.first_full == pytest.approx(up.busy_full + up.busy_small + idle)
    assert up.idle(up.first_full, up.first_full + 0.05) == 0.0


def test_without_the_option_nothing_is_kept_and_a_separate_process_hands_it_back(sink):
    with LossyProxy(sink.getsockname(), rate_bps=RATE) as proxy:
        assert proxy.timelines() == {}
    with separate_process(sink.getsockname(), rate_bps=RATE, timeline=True) as (address, seen), \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
        _burst(client, address, 3, FULL_BYTES)
        time.sleep(0.2)
    assert seen["up_timeline"].busy_full == pytest.approx(3 * FULL_BYTES * 8 / RATE)
    assert seen["delivered"] == 3
