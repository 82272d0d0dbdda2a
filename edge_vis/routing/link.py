"""The link contract: how a transport plugin carries JAUS packets. No I/O here.

A link is chosen by a URL whose scheme is the name of its entry point in the group
``edge_vis.links`` (``udp://0.0.0.0:3794?multicast=239.255.0.1``,
``serial:///dev/ttyUSB0?baud=57600``, ``loop://bench``). Query options configure the
plugin; every link understands ``mtu`` (largest payload per packet, bytes) and
``bandwidth`` (bits per second the medium carries, for pacing). A plugin declares its
options once, as a dataclass (:class:`LinkOptions` or a subclass, see
:mod:`edge_vis.schema`): :meth:`Link.parse_options` validates a URL against it without
opening anything, and the constructor uses the same method, so ``edge-vis check``
refuses exactly what ``edge-vis run`` would. :func:`check_link_url` does it by URL.

Life cycle (the runtime is one asyncio loop; every call is made from it)::

    Link(url, name=...)            constructed: options validated, nothing opened
        │
        ▼
    await open(deliver, on_state)  resources acquired; state "open"
        │
        ├──► send(packets, peer)           any number of times, never blocks; peer None = broadcast
        ├──► send_wires(wires, peer)       the same for messages given as their bytes
        ├──► send_urgent(packets, peer)    the same, ahead of whatever the link still holds
        ├──◄ deliver(name, peer, packets)  called by the link for every good datagram / frame
        └──◄ on_state(name, state, reason) "down" / "open" when the medium goes and comes back
        │
        ▼
    await close()                  idempotent; afterwards send() counts a drop

Framing and protocol logic live in sans-I/O modules (:mod:`edge_vis.jaus.transport`,
:mod:`edge_vis.jaus.serial_framing`); a link is the thin adapter that moves their bytes. A link
never raises out of ``send`` or its receive path: bad input is counted (``malformed``),
I/O trouble becomes state ``down`` plus a counted drop, and :meth:`Link.stats` returns
a :class:`LinkStats` snapshot for health reporting.
"""

from __future__ import annotations

import logging
import re
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar
from urllib.parse import parse_qsl, urlsplit

from edge_vis.errors import ConfigError, DecodeError, PluginNotFoundError
from edge_vis.jaus.transport import JTS_MAX_PAYLOAD, Packet, packet_from_wire, unpack_message
from edge_vis.schema import Reader, setting

log = logging.getLogger(__name__)

Peer = Hashable
"""A link-level address: ``(ip, port)`` for UDP, the device path for serial, a name for loop."""

DeliverCallback = Callable[[str, Peer, list[Packet]], None]
StateCallback = Callable[[str, str, str], None]
TapCallback = Callable[[str, str, Peer, Sequence[Packet]], None]
"""``tap(link_name, direction, peer, packets)`` with direction ``"in"`` or ``"out"``."""
PassThroughCallback = Callable[[str, Peer, list[bytes]], int]
"""``pass_through(link_name, peer, wires)``: the runtime forwards the leading messages
that only pass through (see :meth:`Link.open`) and returns how many it took."""

#: peers tracked per link before the least recently seen is forgotten (bounds memory
#: when a noisy network sends from many source addresses)
MAX_TRACKED_PEERS = 256


@dataclass(frozen=True, slots=True)
class LinkUrl:
    """A parsed link URL. ``options`` holds the query string, last value wins."""

    scheme: str
    host: str
    port: int | None
    path: str
    options: Mapping[str, str]
    text: str

    @classmethod
    def parse(cls, text: str) -> LinkUrl:
        """Split ``scheme://host:port/path?k=v&...``; raise :class:`ConfigError` if malformed."""
        parts = urlsplit(text)
        if not parts.scheme or "://" not in text:
            raise ConfigError([("", "url", f"{text!r} is not a link URL: no scheme "
                                           "(e.g. udp://0.0.0.0:3794)")])
        try:
            port = parts.port
        except ValueError as exc:
            raise ConfigError([("", "url", f"{text!r}: {exc}")]) from None
        host = parts.hostname or ""
        if parts.scheme == "loop":  # loop://Name keeps the case the user wrote
            host = parts.netloc
        return cls(
            scheme=parts.scheme.lower(),
            host=host,
            port=port,
            path=parts.path,
            options=dict(parse_qsl(parts.query, keep_blank_values=True)),
            text=text,
        )

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True, slots=True)
class LinkOptions:
    """The query options every link understands; a plugin's options subclass this."""

    #: largest JAUS payload per packet, bytes
    mtu: int = setting(JTS_MAX_PAYLOAD, ge=16, le=0xFFFF - 16, unit="bytes")
    #: bits per second the medium carries, for pacing (None: unknown)
    bandwidth: int | None = setting(None, ge=1, le=10**12, unit="bit/s")
    #: the link's name in logs and status (default: the URL)
    name: str = ""


@dataclass(frozen=True, slots=True)
class PeerStats:
    """Traffic with one peer of a link."""

    bytes_in: int = 0
    bytes_out: int = 0
    messages_in: int = 0
    messages_out: int = 0
    malformed: int = 0

    def as_dict(self) -> dict[str, int]:
        """Plain values (for JSON output)."""
        return {
            "bytes_in": self.bytes_in, "bytes_out": self.bytes_out,
            "messages_in": self.messages_in, "messages_out": self.messages_out,
            "malformed": self.malformed,
        }


@dataclass(frozen=True, slots=True)
class LinkStats:
    """A snapshot of one link's health counters (all totals since open)."""

    name: str
    url: str
    state: str
    mtu: int
    bandwidth_bps: float | None
    bytes_in: int = 0
    bytes_out: int = 0
    messages_in: int = 0
    messages_out: int = 0
    malformed: int = 0
    drops: Mapping[str, int] = field(default_factory=dict)
    queue_depth: int = 0  # bytes accepted but not yet written
    peers: Mapping[str, PeerStats] = field(default_factory=dict)
    last_error: str = ""

    def as_dict(self) -> dict[str, object]:
        """Plain values (for JSON output)."""
        return {
            "name": self.name, "url": self.url, "state": self.state, "mtu": self.mtu,
            "bandwidth_bps": self.bandwidth_bps, "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out, "messages_in": self.messages_in,
            "messages_out": self.messages_out, "malformed": self.malformed,
            "drops": dict(self.drops), "queue_depth": self.queue_depth,
            "peers": {k: v.as_dict() for k, v in self.peers.items()},
            "last_error": self.last_error,
        }


class _PeerCounters:
    __slots__ = ("bytes_in", "bytes_out", "malformed", "messages_in", "messages_out")

    def __init__(self) -> None:
        self.bytes_in = self.bytes_out = self.messages_in = self.messages_out = 0
        self.malformed = 0


class LinkCounters:
    """Mutable counters a link updates on its hot path; :meth:`Link.stats` snapshots them."""

    def __init__(self) -> None:
        self.bytes_in = self.bytes_out = 0
        self.messages_in = self.messages_out = 0
        self.malformed = 0
        self.drops: Counter[str] = Counter()
        self.last_error = ""
        self._peers: dict[Peer, _PeerCounters] = {}

    def peer(self, peer: Peer) -> _PeerCounters:
        """The counters of ``peer`` (created on first use, bounded in number)."""
        counters = self._peers.get(peer)
        if counters is None:
            if len(self._peers) >= MAX_TRACKED_PEERS:
                del self._peers[next(iter(self._peers))]
                self.drops["peer counters forgotten: table full"] += 1
            counters = self._peers[peer] = _PeerCounters()
        return counters

    def received(self, peer: Peer, nbytes: int, nmessages: int) -> None:
        self.bytes_in += nbytes
        self.messages_in += nmessages
        p = self.peer(peer)
        p.bytes_in += nbytes
        p.messages_in += nmessages

    def sent(self, peer: Peer, nbytes: int, nmessages: int) -> None:
        self.bytes_out += nbytes
        self.messages_out += nmessages
        p = self.peer(peer)
        p.bytes_out += nbytes
        p.messages_out += nmessages

    def bad_input(self, peer: Peer | None) -> None:
        self.malformed += 1
        if peer is not None:
            self.peer(peer).malformed += 1

    def dropped(self, reason: str, count: int = 1) -> None:
        self.drops[reason] += count

    def peers(self) -> dict[str, PeerStats]:
        return {
            format_peer(k): PeerStats(v.bytes_in, v.bytes_out, v.messages_in, v.messages_out,
                                      v.malformed)
            for k, v in self._peers.items()
        }


_NUMBERS = re.compile(r"0x[0-9A-Fa-f]+|\d+")


def drop_reason(reason: str) -> str:
    """The kind of a decode error, without its values: ``data size N exceeds the N bytes
    left``. Counters are keyed by it, so they stay few however varied the bad input."""
    return _NUMBERS.sub("N", reason.split(" (")[0])[:80]


def format_peer(peer: Peer | None) -> str:
    """``127.0.0.2:3794`` for an (ip, port) tuple; ``str()`` otherwise; ``*`` for broadcast."""
    if peer is None:
        return "*"
    if isinstance(peer, tuple) and len(peer) >= 2:
        return f"{peer[0]}:{peer[1]}"
    return str(peer)


class Link(ABC):
    """Base class of every link plugin (see the module docstring for the life cycle).

    Subclasses set ``scheme``, list their extra query options in ``options`` and
    implement :meth:`_open`, :meth:`_send` and :meth:`_close`. They report received
    traffic through :meth:`_received` and bad input through :meth:`_malformed`.
    """

    scheme: ClassVar[str] = ""
    #: the dataclass of the query options this plugin understands
    options_type: ClassVar[type[LinkOptions]] = LinkOptions
    #: bytes the medium adds to each packet's data size (for pacing and budgets)
    overhead: ClassVar[int] = 0

    def __init__(self, url: str | LinkUrl, *, name: str | None = None) -> None:
        self.url = url if isinstance(url, LinkUrl) else LinkUrl.parse(url)
        #: the validated query options (an instance of :attr:`options_type`)
        self.config: Any = self.parse_options(self.url)
        self.name = name or self.config.name or str(self.url)
        self.mtu: int = self.config.mtu
        bandwidth = self.config.bandwidth
        self.bandwidth_bps: float | None = float(bandwidth) if bandwidth else None
        self.counters = LinkCounters()
        self.state = "new"
        self._deliver: DeliverCallback | None = None
        self._on_state: StateCallback | None = None
        self._taps: list[TapCallback] = []
        self._pass_through: PassThroughCallback | None = None

    # -- options -----------------------------------------------------------------------
    @classmethod
    def parse_options(cls, url: str | LinkUrl) -> LinkOptions:
        """Validate ``url`` for this plugin without opening anything; return its options.

        The query is read against :attr:`options_type` (unknown options, types, ranges),
        then :meth:`url_problems` checks the rest of the URL. Raises
        :class:`~edge_vis.errors.ConfigError` naming every problem as ``url.OPTION``.
        """
        parsed = url if isinstance(url, LinkUrl) else LinkUrl.parse(url)
        reader = Reader(text=True, unknown="unknown option", list_known=True)
        options = reader.read(cls.options_type, parsed.options, "url")
        if options is not None and not reader.problems:
            for key, reason in cls.url_problems(parsed, options):
                reader.problem(key, reason)
        if reader.problems:
            raise ConfigError([(f, key, f"{parsed}: {reason}")
                               for f, key, reason in reader.problems])
        assert options is not None
        return options

    @classmethod
    def url_problems(cls, url: LinkUrl, options: Any) -> list[tuple[str, str]]:
        """Problems of the URL beyond its query options, as ``(key, reason)``; the key
        is ``url`` or ``url.OPTION``. The default finds none."""
        return []

    # -- life cycle --------------------------------------------------------------------
    async def open(self, deliver: DeliverCallback, on_state: StateCallback | None = None, *,
                   pass_through: PassThroughCallback | None = None) -> None:
        """Acquire the medium; from now on received packets go to ``deliver``.

        ``pass_through`` (optional): a link that receives one general transport message
        per datagram may first offer a run of them from one peer as their bytes; the
        runtime forwards the leading ones that only pass through (the router's
        :meth:`~edge_vis.routing.router.Router.forward`) and returns how many it took;
        the rest go to ``deliver`` decoded, in order, as always. No link has to use it.

        Raises :class:`~edge_vis.errors.LinkError` when the medium cannot be opened.
        """
        if self.state != "new":
            raise RuntimeError(f"link {self.name} already opened (state {self.state})")
        self._deliver = deliver
        self._on_state = on_state
        self._pass_through = pass_through
        await self._open()
        if self.state == "new":
            self.state = "open"

    def send(self, packets: Sequence[Packet], peer: Peer | None = None) -> None:
        """Queue ``packets`` for ``peer`` (``None``: broadcast). Never blocks or raises."""
        if self.state not in ("open", "down"):
            self.counters.dropped("link closed", len(packets))
            return
        for tap in self._taps:
            tap(self.name, "out", peer, packets)
        self._send(packets, peer)

    def send_wires(self, wires: Sequence[bytes], peer: Peer | None = None) -> None:
        """:meth:`send` for general transport messages given as their bytes (forwarded as
        they were received: :class:`~edge_vis.routing.router.ForwardWires`)."""
        if self.state not in ("open", "down"):
            self.counters.dropped("link closed", len(wires))
            return
        if self._taps:  # the taps see packets
            self.send([packet_from_wire(w) for w in wires], peer)
            return
        self._send_wires(wires, peer)

    def send_urgent(self, packets: Sequence[Packet], peer: Peer | None = None) -> None:
        """Like :meth:`send`, but ahead of everything the link still holds to write, and
        never dropped for a full write buffer (an emergency stop). A plugin that buffers
        overrides :meth:`_send_urgent`; the default is :meth:`_send`."""
        if self.state not in ("open", "down"):
            self.counters.dropped("link closed", len(packets))
            return
        for tap in self._taps:
            tap(self.name, "out", peer, packets)
        self._send_urgent(packets, peer)

    async def close(self) -> None:
        """Release the medium; safe to call more than once."""
        if self.state in ("closed", "new"):
            self.state = "closed"
            return
        self.state = "closed"
        await self._close()

    def add_tap(self, tap: TapCallback) -> None:
        """Also call ``tap`` with every packet received or sent (for a traffic mirror)."""
        self._taps.append(tap)

    @property
    def queue_depth(self) -> int:
        """Bytes accepted by :meth:`send` but not yet written to the medium."""
        return 0

    def stats(self) -> LinkStats:
        """A snapshot of the counters."""
        c = self.counters
        return LinkStats(
            name=self.name, url=str(self.url), state=self.state, mtu=self.mtu,
            bandwidth_bps=self.bandwidth_bps, bytes_in=c.bytes_in, bytes_out=c.bytes_out,
            messages_in=c.messages_in, messages_out=c.messages_out, malformed=c.malformed,
            drops=dict(c.drops), queue_depth=self.queue_depth, peers=c.peers(),
            last_error=c.last_error,
        )

    # -- for subclasses ----------------------------------------------------------------
    @abstractmethod
    async def _open(self) -> None:
        """Acquire the medium."""

    @abstractmethod
    def _send(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        """Write or queue packets; count what could not be sent."""

    @abstractmethod
    async def _close(self) -> None:
        """Release the medium."""

    def _send_urgent(self, packets: Sequence[Packet], peer: Peer | None) -> None:
        """Write packets ahead of anything buffered (default: as :meth:`_send`)."""
        self._send(packets, peer)

    def _send_wires(self, wires: Sequence[bytes], peer: Peer | None) -> None:
        """Write messages given as their bytes (default: decoded, then :meth:`_send`)."""
        self._send([packet_from_wire(w) for w in wires], peer)

    def _received_wires(self, peer: Peer, wires: list[bytes], extra: int = 0) -> None:
        """Hand a run of messages received from ``peer`` (each one whole datagram or
        frame, as bytes without the medium's framing) to the runtime: the leading ones
        that only pass through to the pass-through path, the rest decoded and delivered
        as by :meth:`_received` (or counted as malformed). ``extra``: bytes the medium
        carried per message besides them (counted as received, as on the full path)."""
        pass_through = self._pass_through
        taken = pass_through(self.name, peer, wires) \
            if pass_through is not None and not self._taps else 0
        if taken:
            done = wires if taken == len(wires) else wires[:taken]
            self.counters.received(peer, sum(map(len, done)) + extra * taken, taken)
            if done is wires:
                return
        packets: list[Packet] = []
        nbytes = 0
        for wire in wires[taken:]:
            try:
                packets += unpack_message(wire)
            except DecodeError as exc:
                self._malformed(peer, str(exc), wire)
                continue
            nbytes += len(wire) + extra
        if packets:
            self._received(peer, packets, nbytes)

    def _received(self, peer: Peer, packets: list[Packet], nbytes: int, *,
                  tapped: bool = False) -> None:
        """Count and hand good packets to the runtime.

        ``tapped``: the subclass already showed each datagram to the taps (see
        :meth:`_tap_in`), because it delivers several datagrams in one call.
        """
        self.counters.received(peer, nbytes, len(packets))
        if not tapped:
            self._tap_in(peer, packets)
        if self._deliver is not None:
            self._deliver(self.name, peer, packets)

    def _tap_in(self, peer: Peer, packets: list[Packet]) -> None:
        """Show one received datagram's packets to the taps."""
        for tap in self._taps:
            tap(self.name, "in", peer, packets)

    def _malformed(self, peer: Peer | None, reason: str, data: bytes) -> None:
        """Count and log bad input (the log is DEBUG: a noisy radio must not flood it)."""
        self.counters.bad_input(peer)
        self.counters.dropped(f"malformed: {drop_reason(reason)}")
        log.debug("%s: dropped %d bytes from %s: %s", self.name, len(data), format_peer(peer),
                  reason)

    def _set_state(self, state: str, reason: str = "") -> None:
        """Record an up/down change and tell the runtime."""
        if state == self.state or self.state == "closed":
            return
        self.state = state
        if reason:
            self.counters.last_error = reason
        log.info("link %s is %s%s", self.name, state, f": {reason}" if reason else "")
        if self._on_state is not None:
            self._on_state(self.name, state, reason)


def link_class(scheme: str) -> type[Link]:
    """The :class:`Link` subclass registered under ``scheme`` in ``edge_vis.links``.

    Raises :class:`~edge_vis.errors.PluginNotFoundError` naming the installed schemes, or
    :class:`~edge_vis.errors.PluginLoadError` (import failed, e.g. a missing optional
    dependency such as pyserial, or the entry point is not a packet link).
    """
    from edge_vis import plugins

    installed = sorted(plugins.available(plugins.LINKS))
    if scheme not in installed:
        if scheme in plugins.available(plugins.BULK):
            raise PluginNotFoundError(
                f"{scheme}:// is a bulk channel for image files, not a JAUS link: give it in "
                f"the profile's [bulk] table (or use send-image / receive-images), not as a "
                f"link")
        raise PluginNotFoundError(f"unknown link scheme {scheme!r} (installed: "
                                  f"{', '.join(installed) or 'none'})")
    cls: type[Link] = plugins.load(plugins.LINKS, scheme, Link)
    return cls


def check_link_url(url: str) -> LinkOptions:
    """Validate ``url`` and its options exactly as :func:`create_link` does, opening
    nothing: the same plugin lookup and :meth:`Link.parse_options`.

    Raises :class:`~edge_vis.errors.ConfigError` (a bad URL or option) or
    :class:`~edge_vis.errors.PluginError` (no plugin of that scheme, or it cannot load).
    """
    parsed = LinkUrl.parse(url)
    return link_class(parsed.scheme).parse_options(parsed)


def create_link(url: str, *, name: str | None = None) -> Link:
    """Construct (not open) the link for ``url``; the scheme selects the plugin."""
    parsed = LinkUrl.parse(url)
    return link_class(parsed.scheme)(parsed, name=name)


def parse_peers(text: str, default_port: int) -> list[tuple[str, int]]:
    """``"10.0.0.5:3794,10.0.0.6"`` → ``[("10.0.0.5", 3794), ("10.0.0.6", default_port)]``.

    Raises ValueError naming a peer that is not ``host[:port]``.
    """
    peers = []
    for item in filter(None, (part.strip() for part in text.split(","))):
        host, sep, port = item.rpartition(":")
        if not sep:
            host, port = item, str(default_port)
        if not host or not port.isdigit() or int(port) > 0xFFFF:
            raise ValueError(f"peer {item!r} is not host:port")
        peers.append((host.strip("[]"), int(port)))
    return peers


def total_stats(stats: Iterable[LinkStats]) -> dict[str, int]:
    """Sum of the traffic counters over several links (for a one-line summary)."""
    out = Counter[str]()
    for s in stats:
        out.update(bytes_in=s.bytes_in, bytes_out=s.bytes_out, messages_in=s.messages_in,
                   messages_out=s.messages_out, malformed=s.malformed)
    return dict(out)
