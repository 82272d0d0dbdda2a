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

Ties in age go to the source heard first, then to the run whose first fragment number was
held first. Runs are records indexed by both ends, and lazily pruned heaps give the oldest
run (per source and overall) and the next timeout, so a flood costs O(log n) per fragment
and per eviction however many runs it leaves held (``bench/reassembly.py``). A duplicate
rebuilds the runs beside it, at a cost of their length.
"""

from __future__ import annotations

import heapq
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
    #: when its sequence number was first held (not renewed by a duplicate): ties in age
    #: between runs go to the run whose first fragment number was held first
    order: int


@dataclass(eq=False, slots=True)
class _Run:
    """A stretch of held fragments: its ends, ages and eviction-order key.

    ``version`` changes whenever the key or ages change; heap entries carrying another
    version (or a dead run) are stale and skipped.
    """

    store: _SourceStore
    start: int
    end: int
    oldest: float
    newest: float
    version: int = 0
    alive: bool = True

    def age_key(self) -> tuple[float, int, int]:
        """Eviction order: oldest arrival, then source, then when the start was held."""
        return (self.oldest, self.store.order, self.store.fragments[self.start].order)


@dataclass(slots=True)
class _SourceStore:
    source: JausAddress
    order: int
    fragments: dict[int, _Fragment] = field(default_factory=dict)
    by_start: dict[int, _Run] = field(default_factory=dict)
    by_end: dict[int, _Run] = field(default_factory=dict)
    #: (oldest, source order, start order, version, run) for this source's set cap
    ages: list[tuple[float, int, int, int, _Run]] = field(default_factory=list)


def _joins(before: Packet, after: Packet) -> bool:
    """Whether two fragments with consecutive numbers belong to the same run."""
    return before.data_flags != DataFlags.LAST and after.data_flags != DataFlags.FIRST


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
        self._runs = 0
        self._counter = 0
        self._ages: list[tuple[float, int, int, int, _Run]] = []
        self._deadlines: list[tuple[float, int, _Run]] = []
        self._emptied: list[_SourceStore] = []

    @property
    def bytes_held(self) -> int:
        """Payload bytes currently held in incomplete sets."""
        return self._held

    def pending_sets(self, source: JausAddress | None = None) -> int:
        """Number of incomplete runs held (for one source, or all)."""
        if source is None:
            return self._runs
        return len(self._sources[source].by_start)

    def feed(self, packet: Packet, now: float) -> Packet | None:
        """Take one packet; return a whole message when one is complete, else ``None``.

        A SINGLE packet is returned as is.
        """
        if packet.data_flags == DataFlags.SINGLE:
            return packet
        self.stats.fragments += 1
        store = self._sources.get(packet.source)
        if store is None:
            store = self._sources[packet.source] = _SourceStore(packet.source, self._next())
        seq = packet.sequence
        old = store.fragments.get(seq)
        if old is not None:
            self.stats.duplicates += 1
            self._held -= len(old.packet.payload)
            old.packet, old.arrived = packet, now
            self._held += len(packet.payload)
            run = self._rebuild_around(store, seq)
        else:
            store.fragments[seq] = _Fragment(packet, now, self._next())
            self._held += len(packet.payload)
            run = self._insert(store, seq, now)
        frags = store.fragments
        if frags[run.start].packet.data_flags == DataFlags.FIRST and (
            frags[run.end].packet.data_flags == DataFlags.LAST
        ):
            return self._complete(packet.source, store, run)
        self._enforce_caps(store, run)
        return None

    def expire(self, now: float) -> int:
        """Drop runs idle for longer than the timeout; return how many were dropped."""
        dropped = 0
        heap = self._deadlines
        while heap:
            newest, version, run = heap[0]
            if not run.alive or version != run.version:
                heapq.heappop(heap)
                continue
            if not now - newest > self.timeout:
                break
            heapq.heappop(heap)
            self._drop(run)
            self.stats.dropped_timeout += 1
            dropped += 1
        self._forget_empty()
        return dropped

    def next_deadline(self) -> float | None:
        """When :meth:`expire` next has work, or ``None`` when nothing is held."""
        heap = self._deadlines
        while heap and (not heap[0][2].alive or heap[0][1] != heap[0][2].version):
            heapq.heappop(heap)
        return heap[0][0] + self.timeout if heap else None

    # -- internals ------------------------------------------------------------------------

    def _next(self) -> int:
        self._counter += 1
        return self._counter

    def _insert(self, store: _SourceStore, seq: int, now: float) -> _Run:
        """Place a new fragment: extend or join the runs beside it, or start a run."""
        frags = store.fragments
        packet = frags[seq].packet
        left = store.by_end.get((seq - 1) % _MOD)
        if left is not None and not _joins(frags[left.end].packet, packet):
            left = None
        right = store.by_start.get((seq + 1) % _MOD)
        if right is not None and (right is left or not _joins(packet, frags[right.start].packet)):
            right = None  # (right is left: the run would close into a ring of 65,536)
        if left is None and right is None:
            run = _Run(store, seq, seq, now, now)
            self._add_run(run)
            return run
        if left is not None and right is not None:
            self._remove_run(right)
            del store.by_end[left.end]
            left.end = right.end
            store.by_end[left.end] = left
            left.oldest = min(left.oldest, right.oldest, now)
            left.newest = max(left.newest, right.newest, now)
            self._push(left)
            return left
        if left is not None:
            del store.by_end[left.end]
            left.end = seq
            store.by_end[seq] = left
            run = left
        else:
            assert right is not None
            del store.by_start[right.start]
            right.start = seq
            store.by_start[seq] = right
            run = right
        run.oldest = min(run.oldest, now)
        run.newest = max(run.newest, now)
        self._push(run)
        return run

    def _rebuild_around(self, store: _SourceStore, seq: int) -> _Run:
        """A held fragment was replaced: rebuild its run and its neighbours from scratch."""
        frags = store.fragments
        start = seq
        while start not in store.by_start:
            start = (start - 1) % _MOD
        run = store.by_start[start]
        affected = [run]
        before = store.by_end.get((run.start - 1) % _MOD)
        if before is not None and before is not run:
            affected.insert(0, before)
        after = store.by_start.get((run.end + 1) % _MOD)
        if after is not None and after is not run and after is not before:
            affected.append(after)
        first = affected[0].start
        count = sum((r.end - r.start) % _MOD + 1 for r in affected)
        for r in affected:
            self._remove_run(r)
        found: _Run | None = None
        current: _Run | None = None
        for i in range(count):
            s = (first + i) % _MOD
            frag = frags[s]
            if current is not None and _joins(frags[current.end].packet, frag.packet):
                current.end = s
                current.oldest = min(current.oldest, frag.arrived)
                current.newest = max(current.newest, frag.arrived)
            else:
                if current is not None:
                    self._add_run(current)
                current = _Run(store, s, s, frag.arrived, frag.arrived)
            if s == seq:
                found = current
        assert current is not None and found is not None
        self._add_run(current)
        return found

    def _add_run(self, run: _Run) -> None:
        store = run.store
        store.by_start[run.start] = run
        store.by_end[run.end] = run
        self._runs += 1
        self._push(run)

    def _remove_run(self, run: _Run) -> None:
        store = run.store
        del store.by_start[run.start]
        del store.by_end[run.end]
        run.alive = False
        self._runs -= 1

    def _push(self, run: _Run) -> None:
        """(Re)file a run whose key or ages changed; compact heaps gone mostly stale."""
        run.version = version = self._next()
        oldest, source_order, start_order = run.age_key()
        entry = (oldest, source_order, start_order, version, run)
        heapq.heappush(self._ages, entry)
        heapq.heappush(run.store.ages, entry)
        heapq.heappush(self._deadlines, (run.newest, version, run))
        if len(self._deadlines) > 4 * self._runs + 64:
            self._deadlines = [e for e in self._deadlines if e[2].alive and e[1] == e[2].version]
            heapq.heapify(self._deadlines)
        if len(self._ages) > 4 * self._runs + 64:
            self._ages = [e for e in self._ages if e[4].alive and e[3] == e[4].version]
            heapq.heapify(self._ages)
        store = run.store
        if len(store.ages) > 4 * len(store.by_start) + 64:
            store.ages = [e for e in store.ages if e[4].alive and e[3] == e[4].version]
            heapq.heapify(store.ages)

    @staticmethod
    def _oldest(
        heap: list[tuple[float, int, int, int, _Run]], exclude: _Run
    ) -> _Run | None:
        """The oldest live run in ``heap`` other than ``exclude`` (stale entries pruned)."""
        while heap and (not heap[0][4].alive or heap[0][3] != heap[0][4].version):
            heapq.heappop(heap)
        if not heap:
            return None
        if heap[0][4] is not exclude:
            return heap[0][4]
        kept = heapq.heappop(heap)
        while heap and (not heap[0][4].alive or heap[0][3] != heap[0][4].version):
            heapq.heappop(heap)
        found = heap[0][4] if heap else None
        heapq.heappush(heap, kept)
        return found

    def _drop(self, run: _Run) -> None:
        store = run.store
        self._remove_run(run)
        count = (run.end - run.start) % _MOD + 1
        for i in range(count):
            frag = store.fragments.pop((run.start + i) % _MOD)
            self._held -= len(frag.packet.payload)
        self.stats.dropped_fragments += count
        if not store.fragments:
            self._emptied.append(store)

    def _complete(self, source: JausAddress, store: _SourceStore, run: _Run) -> Packet:
        self._remove_run(run)
        count = (run.end - run.start) % _MOD + 1
        frags = [store.fragments.pop((run.start + i) % _MOD) for i in range(count)]
        for frag in frags:
            self._held -= len(frag.packet.payload)
        if not store.fragments:
            del self._sources[source]
        self.stats.completed += 1
        first = frags[0].packet
        payload = b"".join(frag.packet.payload for frag in frags)
        return replace(first, payload=payload, data_flags=DataFlags.SINGLE)

    def _enforce_caps(self, store: _SourceStore, keep: _Run) -> None:
        while len(store.by_start) > self.max_sets_per_source:
            victim = self._oldest(store.ages, exclude=keep)
            if victim is None:
                break
            self._drop(victim)
            self.stats.dropped_set_cap += 1
        while self._held > self.max_bytes:
            victim = self._oldest(self._ages, exclude=keep)
            if victim is None:
                # the run being built is alone and too large by itself: drop it
                self._drop(keep)
                self.stats.dropped_byte_cap += 1
                break
            self._drop(victim)
            self.stats.dropped_byte_cap += 1
        self._forget_empty()

    def _forget_empty(self) -> None:
        """Forget the sources whose last runs were just dropped."""
        for store in self._emptied:
            if not store.fragments and self._sources.get(store.source) is store:
                del self._sources[store.source]
        self._emptied.clear()
