"""Public test fakes: an in-memory ``loop://`` link, a settable clock, a router shell.

No real I/O: :class:`MemoryLink` moves bytes between objects in one process, and
:class:`RouterNode` only drives links it is given on the running asyncio loop.

``MemoryLink`` joins links in one process through a named bus, like python-can's
virtual bus: ``loop://bench?addr=a`` and ``loop://bench?addr=b`` hear each other.
Packets really go through the JUDP encoder and decoder on the way (so a packet that
cannot be encoded fails here as it would on a socket), and delivery is deferred to the
asyncio loop with ``call_soon``, as a socket read would be.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

from edge_vis.errors import DecodeError
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.routing.link import Link, LinkOptions, LinkUrl, Peer
from edge_vis.routing.router import (
    Action,
    Deliver,
    DeliveryFailed,
    ForwardWires,
    Router,
    SendPackets,
)
from edge_vis.shell.memory import release_memory
from edge_vis.shell.sharedloop import on_loop_thread

_BUSES: dict[str, dict[str, MemoryLink]] = {}
_anonymous = itertools.count(1)


@dataclass(frozen=True, slots=True)
class MemoryOptions(LinkOptions):
    """``loop://BUS?addr=NAME``: the member's name on the bus (default: a unique one)."""

    addr: str = ""


class MemoryLink(Link):
    """A link to the other ``MemoryLink`` objects open on the same bus name.

    URL: ``loop://BUS?addr=NAME`` (``addr`` defaults to a unique name). The peer address
    of a packet is the sender's ``addr``; ``send(packets, None)`` reaches every other
    member of the bus.
    """

    scheme: ClassVar[str] = "loop"
    options_type: ClassVar[type[LinkOptions]] = MemoryOptions

    def __init__(self, url: str | LinkUrl, *, name: str | None = None) -> None:
        super().__init__(url, name=name)
        self.bus = self.url.host or "default"
        self.addr = self.config.addr or f"anon{next(_anonymous)}"
        self._loop: asyncio.AbstractEventLoop | None = None

    async def _open(self) -> None:
        members = _BUSES.setdefault(self.bus, {})
        if self.addr in members:
            from edge_vis.errors import LinkError

            raise LinkError(f"loop://{self.bus}: address {self.addr!r} already in use")
        members[self.addr] = self
        self._loop = asyncio.get_running_loop()

    def _send(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        data = pack_datagram(packets)
        members = _BUSES.get(self.bus, {})
        if peer is None:
            targets = [m for a, m in members.items() if a != self.addr]
        else:
            target = members.get(str(peer))
            if target is None:
                self.counters.dropped("no such peer", len(packets))
                return
            targets = [target]
        self.counters.sent(peer if peer is not None else "*", len(data), len(packets))
        for target in targets:
            target.inject(data, self.addr)

    def inject(self, data: bytes, peer: Peer) -> None:
        """Make ``data`` (a JUDP datagram, valid or not) arrive from ``peer``."""
        if self._loop is None or self.state == "closed":
            return
        self._loop.call_soon(self._arrive, bytes(data), peer)

    def _arrive(self, data: bytes, peer: Peer) -> None:
        if self.state == "closed":
            return
        try:
            packets = unpack_datagram(data)
        except DecodeError as exc:
            self._malformed(peer, str(exc), data)
            return
        self._received(peer, packets, len(data))

    async def _close(self) -> None:
        members = _BUSES.get(self.bus, {})
        if members.get(self.addr) is self:
            del members[self.addr]
        if not members:
            _BUSES.pop(self.bus, None)


class FakeClock:
    """A clock the test advances by hand (``now`` for sans-I/O code)."""

    def __init__(self, start: float = 1000.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> float:
        """Move time forward; return the new ``now``."""
        self.now += seconds
        return self.now


class RouterNode:
    """A minimal asyncio shell joining links and a :class:`~edge_vis.routing.router.Router`.

    It does what the relay runtime does for routing, and nothing more: it feeds packets
    from the links into the router with the loop's clock as ``now``, carries out the
    actions, and keeps the router's timer armed. Delivered messages are put on
    :attr:`delivered` (an :class:`asyncio.Queue` of :class:`~edge_vis.routing.router.Deliver`),
    failures on :attr:`failures`. Used by tests, benches and demos. ``pass_through=False``
    leaves the router's pass-through path unused (every packet decoded and routed by
    :meth:`~edge_vis.routing.router.Router.receive`), to compare the two.
    """

    def __init__(self, router: Router, links: Sequence[Link], *, pass_through: bool = True
                 ) -> None:
        self.router = router
        self.pass_through = pass_through
        self.links = {link.name: link for link in links}
        self.delivered: asyncio.Queue[Deliver] = asyncio.Queue()
        self.failures: list[DeliveryFailed] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None

    async def start(self) -> None:
        """Register and open every link."""
        self._loop = asyncio.get_running_loop()
        for link in self.links.values():
            self.router.add_link(link.name, mtu=link.mtu, bandwidth_bps=link.bandwidth_bps,
                                 overhead=link.overhead)
            await link.open(self._received,
                            pass_through=self._pass_through if self.pass_through else None)

    async def stop(self) -> None:
        """Close every link and stop the timer."""
        if self._timer is not None:
            self._timer.cancel()
        for link in self.links.values():
            await link.close()

    def now(self) -> float:
        """The clock given to the router."""
        assert self._loop is not None
        return self._loop.time()

    def send(self, packet: Packet, *, ack: bool = False, urgent: bool = False) -> None:
        """Send from a local component through the router (``urgent``: the urgent path)."""
        self._execute(self.router.send(packet, self.now(), ack=ack, urgent=urgent))

    def _received(self, link: str, peer: Peer, packets: list[Packet]) -> None:
        self._carry(self.router.receive(link, peer, packets, self.now()))

    def _pass_through(self, link: str, peer: Peer, wires: list[bytes]) -> int:
        taken, actions, queued = self.router.forward(link, peer, wires, self.now())
        if queued:
            self._carry(actions)
        else:
            for action in actions:  # only ForwardWires: no deadline moved
                self._send(action)  # type: ignore[arg-type]
        return taken

    def _carry(self, actions: list[Action]) -> None:
        if on_loop_thread(self._loop):
            self._execute(actions)
            return
        # a link thread (its lock held): send now, leave the rest to the loop
        rest: list[Action] = []
        for action in actions:
            if isinstance(action, SendPackets | ForwardWires):
                self._send(action)
            else:
                rest.append(action)
        deadline = self.router.next_deadline()
        if rest or (deadline is not None
                    and (self._timer_at is None or deadline < self._timer_at)):
            assert self._loop is not None
            self._loop.call_soon_threadsafe(self._execute, rest)

    def _send(self, action: SendPackets | ForwardWires) -> None:
        link = self.links.get(action.link)
        if link is None:
            return
        if isinstance(action, ForwardWires):
            link.send_wires(action.wires, action.peer)
        elif action.urgent:
            link.send_urgent(action.packets, action.peer)
        else:
            link.send(action.packets, action.peer)

    def _execute(self, actions: list[Action]) -> None:
        for action in actions:
            if isinstance(action, SendPackets | ForwardWires):
                self._send(action)
            elif isinstance(action, Deliver):
                self.delivered.put_nowait(action)
            else:
                self.failures.append(action)
        self._arm()

    def _arm(self) -> None:
        deadline = self.router.next_deadline()
        if deadline is None or (self._timer_at is not None and self._timer_at <= deadline):
            return
        if self._timer is not None:
            self._timer.cancel()
        assert self._loop is not None
        self._timer_at = deadline
        self._timer = self._loop.call_at(deadline, self._fire)

    def _fire(self) -> None:
        self._timer = None
        self._timer_at = None
        compactions = self.router.compactions
        self._execute(self.router.on_timer(self.now()))
        if self.router.compactions != compactions:  # a burst is over: give its memory back
            release_memory()
