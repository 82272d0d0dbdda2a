"""Command throttling, lifespan and dead-man stop for one vehicle and command kind.

No I/O, explicit ``now``.

Theory of operation
-------------------
Operators may publish commands faster than a radio link carries them. Per vehicle and
command kind the relay keeps one *slot*:

* at most ``rate`` sends per second; between sends, a newer command replaces the waiting
  one (latest wins, the replaced one is counted as coalesced);
* a command older than ``lifespan`` is never sent (counted as expired), so a backlog
  after a radio outage cannot drive the vehicle with stale intent;
* commands wait (within their lifespan) until control is confirmed: :meth:`take` is only
  called by the engine when the component is controlled and ready;
* dead-man: for motion commands (those with ``stop`` fields), if the operator's commands
  stop arriving for ``deadman_timeout`` while the last one sent was not a stop, the slot
  produces the stop command itself, once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from edge_vis.config import CommandProfile
from edge_vis.kit.actions import Command


@dataclass(frozen=True, slots=True)
class Pending:
    """A command waiting in its slot, stamped with its arrival time."""

    command: Command
    received: float
    is_stop: bool = False


class CommandSlot:
    """Latest-wins, rate-limited, lifespan-bounded queue of length one."""

    def __init__(self, profile: CommandProfile) -> None:
        self.profile = profile
        self.pending: Pending | None = None
        self.last_sent: float | None = None
        self.last_received: float | None = None
        self.last_command: Command | None = None
        self.stop_sent = True
        self.sent = 0
        self.coalesced = 0
        self.expired = 0
        self.stops = 0

    @property
    def interval(self) -> float:
        """Minimum seconds between two sends."""
        return 1.0 / self.profile.rate

    def offer(self, command: Command, now: float) -> None:
        """A new command from the operator holding control."""
        if self.pending is not None:
            self.coalesced += 1
        self.pending = Pending(command, now)
        self.last_received = now
        self.last_command = command

    def clear(self) -> int:
        """Drop the waiting command (control lost, vehicle lost); returns how many."""
        dropped = 1 if self.pending is not None else 0
        self.pending = None
        return dropped

    def expire(self, now: float) -> None:
        """Drop a waiting command that has outlived its lifespan."""
        if (
            self.pending is not None
            and not self.pending.is_stop
            and now - self.pending.received > self.profile.lifespan
        ):
            self.pending = None
            self.expired += 1

    def arm_deadman(self, now: float) -> bool:
        """Queue the stop command if the operator went quiet; True when it did."""
        last = self.last_command
        if (
            last is None
            or last.stop is None
            or self.stop_sent
            or self.pending is not None
            or self.last_received is None
            or now - self.last_received < self.profile.deadman_timeout
        ):
            return False
        stop = replace(last, fields=dict(last.stop))
        self.pending = Pending(stop, now, is_stop=True)
        self.stops += 1
        return True

    def take(self, now: float) -> Command | None:
        """The command to send now, if the rate allows; None otherwise."""
        self.expire(now)
        if self.pending is None:
            return None
        if self.last_sent is not None and now < self.last_sent + self.interval:
            return None
        pending, self.pending = self.pending, None
        self.last_sent = now
        self.sent += 1
        self.stop_sent = pending.is_stop or _is_stop(pending.command)
        return pending.command

    def next_deadline(self, can_send: bool) -> float | None:
        """When this slot next needs attention (send, expiry or dead-man)."""
        times: list[float] = []
        if self.pending is not None:
            if not self.pending.is_stop:
                times.append(self.pending.received + self.profile.lifespan + 1e-6)
            if can_send:
                ready = self.last_sent + self.interval if self.last_sent is not None else 0.0
                times.append(ready)
        last = self.last_command
        if (last is not None and last.stop is not None and not self.stop_sent
                and self.pending is None and self.last_received is not None):
            times.append(self.last_received + self.profile.deadman_timeout)
        return min(times) if times else None


def _is_stop(command: Command) -> bool:
    stop: Mapping[str, Any] | None = command.stop
    if stop is None:
        return False
    return all(command.fields.get(k, 0) == v for k, v in stop.items())
