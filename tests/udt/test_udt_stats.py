"""What libudt says of a real connection that udt4py does not: its smoothed round trip
and the packets in flight, read for the rate probe."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

pytest.importorskip("udt4py")

from lossy_proxy import LossyProxy
from udt_helpers import paces_until, wait_for

from links.udt import udt_stats

pytestmark = pytest.mark.udt


def _sink(size: int) -> tuple[Any, list[int], threading.Thread]:
    """A UDT server that takes one connection and reads ``size`` bytes from it: (the
    listening socket, the byte counts read so far, its thread)."""
    udt4py = pytest.importorskip("udt4py")
    server = udt4py.UDTSocket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    received: list[int] = []

    def sink() -> None:
        conn, _ = server.accept()
        buf = bytearray(65536)
        while sum(received) < size:
            received.append(conn.recv(buf))

    thread = threading.Thread(target=sink, daemon=True)
    thread.start()
    return server, received, thread


def test_a_connection_through_a_delaying_radio_reports_its_round_trip_and_flight():
    udt4py = pytest.importorskip("udt4py")
    server, received, thread = _sink(4 << 20)
    with LossyProxy(server.address, delay=0.020, rate_bps=20e6, lifetime=30) as proxy:
        client = udt4py.UDTSocket()
        client.connect(proxy.address)
        assert udt_stats.read(client).round_trip is None  # UDT's first guess, not yet
        flights = []
        client.send(bytes(4 << 20))  # into UDT's buffer; 20 Mbit/s take 1.7 s
        while sum(received) < 4 << 20:
            flights.append(udt_stats.read(client).in_flight)
            time.sleep(0.02)
        stats = wait_for(lambda: (s := udt_stats.read(client)) and s.round_trip and s, 10,
                         "a settled round trip")
        # 2 x 20 ms of radio delay, and a little for serialising and acknowledging
        assert 0.038 <= stats.round_trip <= 0.080
        assert max(flights) > 0
        thread.join(10)
        client.close()
    server.close()
    assert udt_stats.read(client) is None  # closed: nothing to read


def test_a_capped_connection_reports_the_pace_of_its_cap():
    """The pace is what tells a lane held back by UDT's loss reaction (slower than its
    cap) from one its cap holds: with no loss it is the cap's, MSS bytes per packet."""
    udt4py = pytest.importorskip("udt4py")
    size = 2 << 20
    server, received, thread = _sink(size)
    with LossyProxy(server.address, delay=0.010, rate_bps=20e6, lifetime=30) as proxy:
        client = udt4py.UDTSocket()
        client.connect(proxy.address)
        client.UDT_MAXBW = 1_000_000  # bytes/s on the wire: a packet every MSS µs
        expected = int(client.UDT_MSS) / 1e6
        client.send(bytes(size))
        paces = paces_until(client, received, size, 0.02)
        thread.join(10)
        client.close()
    server.close()
    # without loss, the cap's (before UDT's first look at its congestion control, 1 µs:
    # no lane reads as held back then)
    assert sorted(paces)[len(paces) // 2] == pytest.approx(expected, rel=0.1)
    assert max(paces) <= 1.1 * expected
