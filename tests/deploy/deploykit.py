"""Shared pieces for the deployment tests (imported as ``deploykit``): a stand-in for
systemd's notification socket and the relay as a child process, as a service manager runs it."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Notification:
    at: float
    fields: dict[str, str]
    raw: str


class NotifyListener:
    """The receiving end of ``$NOTIFY_SOCKET``: a real AF_UNIX datagram socket."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.setblocking(False)
        self.messages: list[Notification] = []

    def drain(self) -> list[Notification]:
        """Collect what has arrived so far."""
        while True:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                return self.messages
            text = data.decode()
            fields = dict(line.split("=", 1) for line in text.split("\n") if "=" in line)
            self.messages.append(Notification(time.monotonic(), fields, text))

    def wait_for(self, key: str, value: str | None = None, timeout: float = 10.0,
                 after: int = 0) -> Notification:
        """The first notification (from index ``after``) carrying ``key`` (= ``value``)."""
        deadline = time.monotonic() + timeout
        while True:
            for note in self.drain()[after:]:
                if key in note.fields and (value is None or value in note.fields[key]):
                    return note
            if time.monotonic() > deadline:
                raise AssertionError(f"no {key}={value or '*'} within {timeout} s; got "
                                     f"{[n.raw for n in self.messages]}")
            time.sleep(0.02)

    def close(self) -> None:
        self.sock.close()


def relay_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID")}
    env.update(extra)
    return env


class Relay:
    """``python -m edge_vis ARGS`` as a child process with its stderr in a file."""

    def __init__(self, args: Sequence[str], log_path: Path, env: dict[str, str]) -> None:
        self.log_path = log_path
        self._log = open(log_path, "wb")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen([sys.executable, "-m", "edge_vis", *args], env=env,
                                     stdout=self._log, stderr=subprocess.STDOUT, cwd=REPO)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def signal(self, sig: signal.Signals) -> None:
        self.proc.send_signal(sig)

    def wait(self, timeout: float = 15.0) -> int:
        """Until it exits by itself (``--duration``); killed if it does not."""
        return self.stop(timeout, terminate=False)

    def stop(self, timeout: float = 10.0, *, terminate: bool = True) -> int:
        if terminate and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        self._log.close()
        return code
