"""Running under a service manager: the systemd notification protocol. Performs I/O.

systemd starts a ``Type=notify`` service with ``$NOTIFY_SOCKET`` (an ``AF_UNIX`` datagram
socket; a leading ``@`` means the abstract namespace) and, with ``WatchdogSec=``,
``$WATCHDOG_USEC`` (and ``$WATCHDOG_PID``). The service reports newline-separated
``KEY=value`` lines: ``READY=1`` when it works, ``WATCHDOG=1`` while it is alive,
``STATUS=...`` for ``systemctl status``, ``RELOADING=1``/``READY=1`` around a reload and
``STOPPING=1`` when it shuts down. This module speaks that protocol with the standard
library only (no libsystemd binding to install on a relay).

:class:`Heartbeat` pings the watchdog from the asyncio event loop itself, at half the
watchdog interval: if the loop is stuck (a blocking call, an endless callback), the pings
stop and systemd restarts the relay. Without ``$NOTIFY_SOCKET`` every call is a no-op, so
``edge-vis run`` behaves the same from a terminal.
"""

from __future__ import annotations

import asyncio
import logging
import os
import signal
import socket
from collections.abc import Callable, Mapping, Sequence
from typing import Any

log = logging.getLogger(__name__)

#: how often STATUS is refreshed when no watchdog is configured (seconds)
STATUS_PERIOD = 5.0


class Notifier:
    """Sends sd_notify messages to ``socket_path``; does nothing when it is None.

    ``watchdog_usec`` is the watchdog interval systemd expects pings within (0 = none).
    Send failures (the manager went away) are logged once and never raised: losing the
    service manager must not take the relay down.
    """

    def __init__(self, socket_path: str | None = None, watchdog_usec: int = 0) -> None:
        self.socket_path = socket_path or None
        self.watchdog_usec = max(int(watchdog_usec), 0)
        self._sock: socket.socket | None = None
        self._warned = False
        self._stopping = False
        self.sent = 0

    @classmethod
    def from_environ(cls, environ: Mapping[str, str] | None = None,
                     pid: int | None = None) -> Notifier:
        """The notifier systemd asked for, from ``$NOTIFY_SOCKET`` and ``$WATCHDOG_USEC``.

        The watchdog applies only when ``$WATCHDOG_PID`` is unset or names this process
        (systemd sets it so a child process does not ping on its parent's behalf).
        """
        env = os.environ if environ is None else environ
        pid = os.getpid() if pid is None else pid
        usec = 0
        raw = env.get("WATCHDOG_USEC", "")
        watchdog_pid = env.get("WATCHDOG_PID", "")
        if raw.isdigit() and (not watchdog_pid or watchdog_pid == str(pid)):
            usec = int(raw)
        elif raw:
            log.debug("watchdog not for this process (WATCHDOG_USEC=%r, WATCHDOG_PID=%r)",
                      raw, watchdog_pid)
        return cls(env.get("NOTIFY_SOCKET") or None, usec)

    @property
    def enabled(self) -> bool:
        """True when a service manager listens."""
        return self.socket_path is not None

    @property
    def watchdog_interval(self) -> float | None:
        """Seconds within which systemd expects a ping, or None without a watchdog."""
        return self.watchdog_usec / 1e6 if self.enabled and self.watchdog_usec else None

    def notify(self, *lines: str) -> bool:
        """Send ``KEY=value`` lines as one datagram; True when it was sent."""
        if self.socket_path is None or not lines:
            return False
        address = self.socket_path
        if address.startswith("@"):
            address = "\0" + address[1:]
        try:
            if self._sock is None:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            self._sock.sendto("\n".join(lines).encode("utf-8", "replace"), address)
        except OSError as exc:
            if not self._warned:
                log.warning("cannot notify the service manager at %s: %s", self.socket_path, exc)
                self._warned = True
            return False
        self.sent += 1
        return True

    def ready(self, status: str = "") -> bool:
        """Start-up done (links and DDS open)."""
        return self.notify("READY=1", *([f"STATUS={_one_line(status)}"] if status else []))

    def status(self, text: str) -> bool:
        """Free-form status shown by ``systemctl status``."""
        return self.notify(f"STATUS={_one_line(text)}")

    def watchdog(self) -> bool:
        """The relay is alive."""
        return self.notify("WATCHDOG=1")

    def reloading(self) -> bool:
        """A reload began; :meth:`ready` ends it."""
        return self.notify("RELOADING=1")

    def stopping(self) -> bool:
        """Shutdown began (sent once, however often it is asked)."""
        if self._stopping:
            return False
        self._stopping = True
        return self.notify("STOPPING=1", "STATUS=stopping: cancelling events, releasing control")

    def close(self) -> None:
        """Release the socket."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def _one_line(text: str) -> str:
    return " ".join(text.split())


class Heartbeat:
    """Watchdog pings and status refreshes scheduled on the running event loop.

    Every tick sends ``WATCHDOG=1`` (when systemd configured a watchdog) and ``STATUS=``
    if ``status()`` changed. Ticks come at half the watchdog interval, or every
    :data:`STATUS_PERIOD` seconds without one; nothing is scheduled without a manager,
    so an idle relay does not wake up for nothing.
    """

    def __init__(self, notifier: Notifier, status: Callable[[], str] | None = None) -> None:
        self.notifier = notifier
        self._status = status
        self._last_status: str | None = None
        self._handle: asyncio.TimerHandle | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        interval = notifier.watchdog_interval
        self.period = interval / 2.0 if interval else STATUS_PERIOD
        self.pings = 0

    def start(self) -> None:
        """Send READY=1 with the first status, then tick from the running loop."""
        self._loop = asyncio.get_running_loop()
        self._last_status = self._current_status()
        self.notifier.ready(self._last_status or "")
        if self.notifier.watchdog_interval:
            log.info("watchdog: %.1f s, pinging every %.2f s",
                     self.notifier.watchdog_interval, self.period)
        if self.notifier.enabled:
            self._handle = self._loop.call_later(self.period, self._tick)

    def refresh(self) -> None:
        """Send the status now if it changed (e.g. after a reload)."""
        text = self._current_status()
        if text and text != self._last_status:
            self._last_status = text
            self.notifier.status(text)

    def stop(self) -> None:
        """No more ticks."""
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None

    def _tick(self) -> None:
        assert self._loop is not None
        if self.notifier.watchdog_interval and self.notifier.watchdog():
            self.pings += 1
        self.refresh()
        self._handle = self._loop.call_later(self.period, self._tick)

    def _current_status(self) -> str:
        if self._status is None:
            return ""
        try:
            return self._status()
        except Exception as exc:  # a status line must never stop the watchdog
            log.debug("status line failed: %s", exc)
            return ""


class Supervisor:
    """Wires a running relay to its service manager and to SIGHUP.

    ``started()`` after the runtime opened its links and DDS sends READY=1 and starts the
    :class:`Heartbeat`; ``stop()`` (signal handlers, ``--duration``) sends STOPPING=1 and
    asks the runtime to stop; SIGHUP re-reads the profile with ``reload_profile`` and
    applies it (:mod:`edge_vis.shell.reload`) between RELOADING=1 and READY=1.
    """

    def __init__(self, runtime: Any, reload_profile: Callable[[], Any] | None = None,
                 notifier: Notifier | None = None) -> None:
        from edge_vis.shell.reload import Reloader  # the reload machinery only when supervised

        self.runtime = runtime
        self.notifier = notifier or Notifier.from_environ()
        self.reloader = (Reloader(runtime, reload_profile) if reload_profile is not None
                         else None)
        self.heartbeat = Heartbeat(self.notifier, self.status)
        self._loop: asyncio.AbstractEventLoop | None = None

    def status(self) -> str:
        """The current status line."""
        pending = self.reloader.restart_needed if self.reloader is not None else ()
        return status_line(self.runtime, pending)

    def started(self) -> None:
        """The relay is up: READY=1, watchdog pings, SIGHUP reloads."""
        self._loop = asyncio.get_running_loop()
        self.heartbeat.start()
        if self.reloader is not None:
            self._loop.add_signal_handler(signal.SIGHUP, self.reload)

    def failed(self, exc: BaseException) -> None:
        """Start-up failed: say why in ``systemctl status``."""
        self.notifier.status(f"failed to start: {exc}")

    def reload(self) -> None:
        """SIGHUP: apply the profile file again."""
        if self.reloader is None:
            return
        self.notifier.reloading()
        self.reloader.reload()
        self.heartbeat.refresh()
        self.notifier.ready(self.status())

    def stop(self) -> None:
        """STOPPING=1, then ask the runtime to stop (idempotent)."""
        self.notifier.stopping()
        self.runtime.request_stop()

    def close(self) -> None:
        """After the runtime stopped."""
        self.heartbeat.stop()
        if self._loop is not None and self.reloader is not None:
            self._loop.remove_signal_handler(signal.SIGHUP)
        self.notifier.close()


def status_line(runtime: Any, restart_needed: Sequence[str] = ()) -> str:
    """``"2 vehicle(s), 1 online; links 2/2 up"`` from a running :class:`Runtime`.

    ``restart_needed`` names profile settings a reload could not apply.
    """
    engine = getattr(runtime, "engine", None)
    vehicles = list(getattr(engine, "vehicles", {}).values()) if engine is not None else []
    online = sum(1 for v in vehicles if getattr(v, "online", False))
    links = getattr(runtime, "links", {})
    up = sum(1 for link in links.values() if link.stats().state == "open")
    text = f"{len(vehicles)} vehicle(s), {online} online; links {up}/{len(links)} up"
    if restart_needed:
        text += f"; restart needed for {', '.join(restart_needed)}"
    return text


__all__ = ["STATUS_PERIOD", "Heartbeat", "Notifier", "Supervisor", "status_line"]
