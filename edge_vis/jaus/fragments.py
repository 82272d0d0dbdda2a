"""Large JAUS messages: splitting into a large data set and bounded reassembly. No I/O.

Theory of operation
-------------------
A payload (message code + body) longer than a link's MTU travels as a *large data set*:
consecutive packets whose data flags say FIRST, MIDDLE ... MIDDLE, LAST and whose sequence
numbers count up by one (AS5669A; the JAUS Toolset does the same). Only the first fragment
carries the message code.

The reassembler keeps, per source component, the fragments it holds keyed by sequence
number. A *run* is a stretch of consecutive sequence numbers that does not cross a LAST →
FIRST boundary; a run that starts with FIRST and ends with LAST is a complete set and is
handed back as one single packet (data flags SINGLE, the first fragment's sequence
number). Arrival order does not matter.

Memory is bounded three ways, all counted in :class:`ReassemblyStats` and never raised:

* ``max_sets_per_source`` incomplete runs per source; past it the oldest run is dropped;
* ``max_bytes`` held in total; past it the oldest runs (of any source) are dropped;
* ``timeout`` seconds without a new fragment for a run; :meth:`Reassembler.expire`
  drops it. Time is the ``now`` the caller passes: this module never reads a clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from edge_vis.errors import EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import DataFlags, Packet

_MOD = 0x10000


def fragment(packet: Packet, mtu: int) -> list[Packet]:
    """Split ``packet`` into a large data set whose payloads are at most ``mtu`` bytes.

    A payload that fits is returned unchanged. Fragments take consecutive sequence numbers
    starting at ``packet.sequence``, so a sender must advance its counter by the number of
    packets returned. Broadcast destinations may not be fragmented (receivers could not
    reassemble from many sources reliably; the JAUS Toolset refuses it too).
    """
    if mtu < 3:
        raise EncodeError(f"MTU {mtu} is too small to carry a message code and data")
    payload = packet.payload
    if len(payload) <= mtu:
        return [packet]
    if packet.destination.is_broadcast:
        raise EncodeError(
            f"a broadcast message of {len(payload)} bytes exceeds the MTU of {mtu}; "
            "broadcasts cannot be fragmented",
            code=packet.message_code,
        )
    chunks = [payload[i : i + mtu] for i in range(0, len(payload), mtu)]
    last = len(chunks) - 1
    out = []
    for index, chunk in enumerate(chunks):
        if index == 0:
            flags = DataFlags.FIRST
        else:
            flags = DataFlags.LAST if index == last else DataFlags.MIDDLE
        out.append(
            replace(
                packet,
                payload=chunk,
                data_flags=flags,
                sequence=(packet.sequence + index) % _MOD,
            )
        )
    return out


@dataclass(slots=True)
class ReassemblyStats:
    """Counters of what the reassembler did; drops are counted here, never raised."""

    completed: int = 0
    fragments: int = 0
    duplicates: int = 0
    dropped_timeout: int = 0
    dropped_set_cap: int = 0
    dropped_byte_cap: int = 0
    dropped_fragments: int = 0

    @property
    def dropped_sets(self) -> int:
        """Sets dropped for any reason."""
        return self.dropped_timeout + self.dropped_set_cap + self.dropped_byte_cap


@dataclass(slots=True)
class _Fragment:
    packet: Packet
    arrived: float


@dataclass(slots=True)
class _SourceStore:
    fragments: dict[int, _Fragment] = field(default_factory=dict)


class Reassembler:
    """Reassemble large data sets from any number of sources, within fixed bounds."""

    def __init__(
        self,
        *,
        max_sets_per_source: int = 8,
        max_bytes: int = 8 * 1024 * 1024,
        timeout: float = 5.0,
    ) -> None:
        self.max_sets_per_source = max_sets_per_source
        self.max_bytes = max_bytes
        self.timeout = timeout
        self.stats = ReassemblyStats()
        self._sources: dict[JausAddress, _SourceStore] = {}
        self._held = 0

    @property
    def bytes_held(self) -> int:
        """Payload bytes currently held in incomplete sets."""
        return self._held

    def pending_sets(self, source: JausAddress | None = None) -> int:
        """Number of incomplete runs held (for one source, or all)."""
        stores = [self._sources[source]] if source is not None else list(self._sources.values())
        return sum(len(self._run_starts(s)) for s in stores if s is not None)

    def feed(self, packet: Packet, now: float) -> Packet | None:
        """Take one packet; return a whole message when one is complete, else ``None``.

        A SINGLE packet is returned as is.
        """
        if packet.data_flags == DataFlags.SINGLE:
            return packet
        self.stats.fragments += 1
        store = self._sources.setdefault(packet.source, _SourceStore())
        seq = packet.sequence
        old = store.fragments.get(seq)
        if old is not None:
            self.stats.duplicates += 1
            self._held -= len(old.packet.payload)
        store.fragments[seq] = _Fragment(packet, now)
        self._held += len(packet.payload)
        start, end = self._run_around(store, seq)
        frags = store.fragments
        if frags[start].packet.data_flags == DataFlags.FIRST and (
            frags[end].packet.data_flags == DataFlags.LAST
        ):
            return self._complete(packet.source, store, start, end)
        self._enforce_caps(packet.source, store, keep=start)
        return None

    def expire(self, now: float) -> int:
        """Drop runs idle for longer than the timeout; return how many were dropped."""
        dropped = 0
        for source in list(self._sources):
            store = self._sources[source]
            for start in self._run_starts(store):
                seqs = self._run_seqs(store, start)
                newest = max(store.fragments[s].arrived for s in seqs)
                if now - newest > self.timeout:
                    self._drop(store, seqs)
                    self.stats.dropped_timeout += 1
                    dropped += 1
            if not store.fragments:
                del self._sources[source]
        return dropped

    def next_deadline(self) -> float | None:
        """When :meth:`expire` next has work, or ``None`` when nothing is held."""
        newest_per_run = [
            max(store.fragments[s].arrived for s in self._run_seqs(store, start))
            for store in self._sources.values()
            for start in self._run_starts(store)
        ]
        return min(newest_per_run) + self.timeout if newest_per_run else None

    # -- internals ------------------------------------------------------------------------

    @staticmethod
    def _run_around(store: _SourceStore, seq: int) -> tuple[int, int]:
        frags = store.fragments
        start = seq
        limit = len(frags)
        for _ in range(limit):
            prev = (start - 1) % _MOD
            if (
                frags[start].packet.data_flags == DataFlags.FIRST
                or prev not in frags
                or frags[prev].packet.data_flags == DataFlags.LAST
            ):
                break
            start = prev
        end = seq
        for _ in range(limit):
            nxt = (end + 1) % _MOD
            if (
                frags[end].packet.data_flags == DataFlags.LAST
                or nxt not in frags
                or frags[nxt].packet.data_flags == DataFlags.FIRST
            ):
                break
            end = nxt
        return start, end

    @staticmethod
    def _run_starts(store: _SourceStore) -> list[int]:
        frags = store.fragments
        starts = []
        for seq, frag in frags.items():
            prev = (seq - 1) % _MOD
            if (
                frag.packet.data_flags == DataFlags.FIRST
                or prev not in frags
                or frags[prev].packet.data_flags == DataFlags.LAST
            ):
                starts.append(seq)
        return starts

    def _run_seqs(self, store: _SourceStore, start: int) -> list[int]:
        _, end = self._run_around(store, start)
        count = (end - start) % _MOD + 1
        return [(start + i) % _MOD for i in range(count)]

    def _drop(self, store: _SourceStore, seqs: list[int]) -> None:
        for s in seqs:
            frag = store.fragments.pop(s)
            self._held -= len(frag.packet.payload)
            self.stats.dropped_fragments += 1

    def _complete(
        self, source: JausAddress, store: _SourceStore, start: int, end: int
    ) -> Packet:
        count = (end - start) % _MOD + 1
        frags = [store.fragments.pop((start + i) % _MOD) for i in range(count)]
        for frag in frags:
            self._held -= len(frag.packet.payload)
        if not store.fragments:
            del self._sources[source]
        self.stats.completed += 1
        first = frags[0].packet
        payload = b"".join(frag.packet.payload for frag in frags)
        return replace(first, payload=payload, data_flags=DataFlags.SINGLE)

    def _oldest_run(self, store: _SourceStore, exclude: int | None) -> list[int] | None:
        best: tuple[float, list[int]] | None = None
        for start in self._run_starts(store):
            if start == exclude:
                continue
            seqs = self._run_seqs(store, start)
            oldest = min(store.fragments[s].arrived for s in seqs)
            if best is None or oldest < best[0]:
                best = (oldest, seqs)
        return best[1] if best else None

    def _enforce_caps(self, source: JausAddress, store: _SourceStore, keep: int) -> None:
        while len(self._run_starts(store)) > self.max_sets_per_source:
            seqs = self._oldest_run(store, exclude=keep)
            if seqs is None:
                break
            self._drop(store, seqs)
            self.stats.dropped_set_cap += 1
        while self._held > self.max_bytes:
            victim: tuple[float, _SourceStore, list[int]] | None = None
            for other in self._sources.values():
                seqs = self._oldest_run(other, exclude=keep if other is store else None)
                if seqs is None:
                    continue
                oldest = min(other.fragments[s].arrived for s in seqs)
                if victim is None or oldest < victim[0]:
                    victim = (oldest, other, seqs)
            if victim is None:
                # the run being built is alone and too large by itself: drop it
                seqs = self._run_seqs(store, keep)
                self._drop(store, seqs)
                self.stats.dropped_byte_cap += 1
                break
            self._drop(victim[1], victim[2])
            self.stats.dropped_byte_cap += 1
        for src in [s for s, st in self._sources.items() if not st.fragments]:
            del self._sources[src]
