"""systemd notifications: what a service manager sees from ``edge-vis run``."""

from __future__ import annotations

import asyncio
import os
import socket
import time

from deploykit import NotifyListener, Relay, relay_env

from edge_vis.shell.service import Heartbeat, Notifier


def test_run_reports_ready_then_watchdog_then_stopping(
    notify_socket: NotifyListener, tmp_path
) -> None:
    env = relay_env(NOTIFY_SOCKET=notify_socket.path, WATCHDOG_USEC="1000000")
    started = time.monotonic()
    relay = Relay(["--log-format", "json", "run", "--no-dds", "--duration", "2",
                   "--link", "udp://127.0.61.1:0?multicast=off"], tmp_path / "relay.log", env)
    while relay.proc.poll() is None and time.monotonic() < started + 15:
        notify_socket.drain()  # as they come: arrival times matter
        time.sleep(0.02)
    code = relay.wait()
    assert code == 0, relay.log()
    notes = notify_socket.drain()
    kinds = [next(k for k in ("READY", "WATCHDOG", "STOPPING", "STATUS") if k in n.fields)
             for n in notes]
    assert kinds[0] == "READY", kinds
    assert notes[0].fields["STATUS"] == "0 vehicle(s), 0 online; links 1/1 up"
    stopping = kinds.index("STOPPING")
    pings = [n for n in notes[1:stopping] if "WATCHDOG" in n.fields]
    # 2 s at one ping every 0.5 s: about four, never a watchdog interval (1 s) apart
    assert len(pings) >= 3, kinds
    gaps = [b.at - a.at for a, b in zip([notes[0], *pings], pings, strict=False)]
    assert max(gaps) < 1.0, gaps
    assert kinds.count("READY") == 1 and kinds.count("STOPPING") == 1
    # --log-format json: every stderr line is one JSON object
    import json

    lines = relay.log().splitlines()
    assert lines and all(json.loads(line)["message"] for line in lines)


def test_without_notify_socket_nothing_is_sent(tmp_path) -> None:
    relay = Relay(["run", "--no-dds", "--duration", "0.5",
                   "--link", "udp://127.0.61.1:0?multicast=off"], tmp_path / "relay.log",
                  relay_env())
    assert relay.wait() == 0, relay.log()
    assert "watchdog" not in relay.log()


def test_abstract_socket_address() -> None:
    name = f"edge-vis-test-{os.getpid()}"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind("\0" + name)
        notifier = Notifier("@" + name)
        assert notifier.ready("starting")
        assert sock.recv(100) == b"READY=1\nSTATUS=starting"
        notifier.close()


def test_watchdog_pid_of_another_process_is_ignored() -> None:
    env = {"NOTIFY_SOCKET": "/run/x", "WATCHDOG_USEC": "4000000", "WATCHDOG_PID": "1"}
    assert Notifier.from_environ(env, pid=1234).watchdog_interval is None
    assert Notifier.from_environ(env, pid=1).watchdog_interval == 4.0
    assert Notifier.from_environ({"WATCHDOG_USEC": "4000000"}).watchdog_interval is None


def test_vanished_manager_does_not_raise(tmp_path) -> None:
    notifier = Notifier(str(tmp_path / "gone"))
    assert notifier.watchdog() is False
    assert notifier.stopping() is False


def test_stuck_event_loop_stops_pinging(notify_socket: NotifyListener) -> None:
    """The pings come from the loop itself: a blocked loop is a silent one."""

    async def main() -> None:
        notifier = Notifier(notify_socket.path, watchdog_usec=200_000)
        heartbeat = Heartbeat(notifier)
        heartbeat.start()
        await asyncio.sleep(0.5)
        notify_socket.drain()
        before = len(notify_socket.messages)
        time.sleep(0.8)  # a callback that hangs the loop
        notify_socket.drain()
        assert len(notify_socket.messages) == before, "pinged while the loop was stuck"
        await asyncio.sleep(0.3)
        heartbeat.stop()
        notifier.close()
        after = [n for n in notify_socket.drain()[before:] if "WATCHDOG" in n.fields]
        assert after, "pings did not resume with the loop"

    asyncio.run(main())
