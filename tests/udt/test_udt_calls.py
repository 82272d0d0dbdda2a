"""libudt's state and options through ctypes (links.udt.udt_calls): the same values as
udt4py reads, and a call that waits inside libudt stops only its own thread."""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

import pytest

pytest.importorskip("udt4py")

from udt_helpers import wait_for

from links.udt import udt_calls
from links.udt.transfer import _connect, listen

pytestmark = pytest.mark.udt

READ = ("UDT_MSS", "UDT_SNDSYN", "UDT_RCVSYN", "UDT_SNDBUF", "UDT_RCVBUF", "UDT_LINGER",
        "UDP_SNDBUF", "UDP_RCVBUF", "UDT_SNDTIMEO", "UDT_RCVTIMEO", "UDT_REUSEADDR",
        "UDT_MAXBW", "UDT_STATE", "UDT_EVENT", "UDT_SNDDATA", "UDT_RCVDATA", "UDT_FC")


def _pair() -> tuple[Any, Any, Any]:
    """(listener, the client's socket, the accepted socket) of a connection on loopback."""
    server = listen(("127.0.0.1", 0), linger=0)
    accepted: list[Any] = []
    threading.Thread(target=lambda: accepted.append(server.accept()[0]), daemon=True).start()
    client = _connect(server.address, 5.0, 5_000_000)
    wait_for(lambda: accepted, 5, "the connection accepted")
    return server, client, accepted[0]


def test_state_and_options_read_and_set_as_udt4py_does():
    udt4py = pytest.importorskip("udt4py")
    if udt_calls.library() is None:
        pytest.skip("libudt cannot be loaded through ctypes here (udt4py is used instead)")
    server, client, conn = _pair()
    try:
        assert udt_calls.state(client) == udt4py.UDTSocket.Status.CONNECTED
        for name in READ:
            assert udt_calls.get_option(client, name) == int(getattr(client, name)), name
        # what _connect set through ctypes, udt4py reads back
        assert client.UDT_MAXBW == 5_000_000 // 8
        assert client.UDT_LINGER == 0 and client.UDT_RCVSYN
        assert udt_calls.set_option(client, "UDT_MAXBW", 123_456)
        assert client.UDT_MAXBW == 123_456
        assert udt_calls.set_option(client, "UDT_MAXBW", -1)
        assert udt_calls.get_option(client, "UDT_MAXBW") == -1  # no cap (udt4py overflows)
    finally:
        client.close()
    # a closed socket: refused, not raised (the lanes' coordinator reads closing lanes)
    assert udt_calls.get_option(client, "UDT_SNDDATA") is None
    assert not udt_calls.set_option(client, "UDT_MAXBW", 1000)
    assert udt_calls.state(client) != udt4py.UDTSocket.Status.CONNECTED
    conn.close()
    server.close()


def test_an_option_set_while_a_recv_waits_stops_only_its_own_thread():
    """libudt's setsockopt waits for the socket's receive lock, which a blocked recv
    holds until its timeout: through udt4py that wait held the GIL, and every thread of
    the relay stood still for as long."""
    if udt_calls.library() is None:
        pytest.skip("libudt cannot be loaded through ctypes here (udt4py is used instead)")
    server, client, conn = _pair()
    recv_timeout = 1.5
    try:
        conn.UDT_RCVTIMEO = int(recv_timeout * 1000)
        blocked = threading.Event()

        def receive() -> None:
            blocked.set()
            with contextlib.suppress(Exception):  # nothing comes: it times out
                conn.recv(bytearray(1024))

        receiver = threading.Thread(target=receive, daemon=True)
        receiver.start()
        blocked.wait(5)
        time.sleep(0.1)  # the receiver is inside libudt's recv, holding its lock
        took: list[float] = []

        def set_cap() -> None:
            started = time.monotonic()
            udt_calls.set_option(conn, "UDT_MAXBW", 500_000)
            took.append(time.monotonic() - started)

        gaps: list[float] = []
        ticking = threading.Event()

        def tick() -> None:  # another thread of the relay, meanwhile
            last = time.monotonic()
            while not ticking.is_set():
                time.sleep(0.01)
                now = time.monotonic()
                gaps.append(now - last)
                last = now

        ticker = threading.Thread(target=tick, daemon=True)
        ticker.start()
        time.sleep(0.1)
        setter = threading.Thread(target=set_cap, daemon=True)
        setter.start()
        setter.join(5)
        ticking.set()
        ticker.join(5)
        receiver.join(5)
        longest = max(gaps)
        # the setter did wait for the receive lock (else this test shows nothing) ...
        assert took and took[0] > 0.5, f"setsockopt did not wait ({took})"
        # ... and the other threads ran meanwhile
        assert longest < 0.3, f"the process stood still for {longest:.2f} s"
        assert conn.UDT_MAXBW == 500_000
    finally:
        client.close()
        conn.close()
        server.close()
