"""Store-and-forward spool for bulk image transfers. Does file I/O (no networking).

Layout under the spool root::

    journal.log          one JSON record per line, fsync'd on append
    partial/<id>.part    bytes received so far for transfer <id>
    ready/<id>           verified files still to be forwarded

Life of a transfer::

    begin (journal: manifest) -> write* -> sync (journal: bytes durable) -> ...
        -> complete: SHA-256 checked from disk -> verified (moved to ready/)
        -> delivered to the output directory and/or forwarded -> removed from the spool

Why a journal: a relay may lose power mid-transfer. On restart the journal says which
manifest each partial file belongs to and how many of its bytes were fsync'd; the file is
cut back to that length (anything after may be torn) and the sender resumes from there.

Quota policy: the spool reserves a transfer's full declared size when it begins. A new
transfer that does not fit is refused with ``Reason.QUOTA`` and a message saying how much
is needed and free. Nothing the spool holds is ever deleted to make room: partial data
stays until it completes or fails verification, verified data until every forward target
confirmed it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import IO, Any

from links.udt.protocol import Manifest, ManifestError, Reason, segment_bounds

log = logging.getLogger(__name__)

SYNC_BYTES = 4 << 20
SYNC_INTERVAL = 1.0
"""A transfer's received bytes are fsync'd and journalled every ``SYNC_BYTES`` or
``SYNC_INTERVAL`` seconds, whichever comes first: the most a crash can lose."""


class SpoolRefusal(Exception):
    """The spool will not take (or keep) a transfer; ``code`` and ``reason`` go to the sender."""

    def __init__(self, code: Reason, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason


class EntryState(Enum):
    PARTIAL = "partial"
    VERIFIED = "verified"
    DONE = "done"


@dataclass
class Claim:
    """One connection's hold on a transfer (the whole file, or one lane's segment)."""

    segment: int | None
    handle: IO[bytes]
    position: int
    touched: set[int] = field(default_factory=set)
    unsynced: int = 0
    synced_at: float = 0.0


@dataclass
class Entry:
    """One transfer the spool knows about.

    ``durable[i]`` counts the bytes of segment ``i`` (from its start) that are fsync'd and
    journalled; ``written[i]`` those written so far. A transfer sent on one connection has
    one segment, the whole file.
    """

    manifest: Manifest
    segments: int = 1
    state: EntryState = EntryState.PARTIAL
    durable: list[int] = field(default_factory=lambda: [0])
    written: list[int] = field(default_factory=lambda: [0])
    forwarded: set[str] = field(default_factory=set)
    delivered: str | None = None
    claims: dict[int | None, Claim] = field(default_factory=dict)
    #: SHA-256 of the first ``hashed`` durable bytes, kept up as the prefix grows, so the
    #: verdict at the end reads only what came last (not kept across a restart)
    digest: Any = field(default=None, compare=False, repr=False)
    hashed: int = 0

    def bounds(self, index: int) -> tuple[int, int]:
        return segment_bounds(self.manifest.size, index, self.segments)

    def prefix(self) -> int:
        """Durable bytes held contiguously from the start of the file."""
        total = 0
        for i in range(self.segments):
            start, end = self.bounds(i)
            total = start + self.durable[i]
            if start + self.durable[i] < end:
                break
        return total if self.segments > 1 else self.durable[0]

    @property
    def held(self) -> int:
        """Durable bytes held (sum over segments)."""
        return sum(self.durable)


def _human(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"


class Spool:
    """Journalled store of incoming files; thread-safe (one writer per transfer at a time).

    ``forward_targets`` lists the names of downstream receivers every verified file must
    reach before the spool lets go of it. ``deliver_dir``, when set, receives a copy of
    each verified file at ``<deliver_dir>/<vehicle_id>/<name>``.
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        quota_bytes: int | None = None,
        forward_targets: tuple[str, ...] = (),
        deliver_dir: str | os.PathLike[str] | None = None,
        sync_bytes: int = SYNC_BYTES,
        sync_interval: float = SYNC_INTERVAL,
    ) -> None:
        self.root = Path(root)
        self.quota_bytes = quota_bytes
        self.forward_targets = tuple(forward_targets)
        self.deliver_dir = None if deliver_dir is None else Path(deliver_dir)
        self.sync_bytes = sync_bytes
        self.sync_interval = sync_interval
        self._lock = threading.RLock()
        self._entries: dict[str, Entry] = {}
        self.counters = {"torn_journal_lines": 0, "refused": 0, "verified": 0, "failed": 0}
        (self.root / "partial").mkdir(parents=True, exist_ok=True)
        (self.root / "ready").mkdir(parents=True, exist_ok=True)
        self._journal_path = self.root / "journal.log"
        self._replay()
        self._compact()
        self._journal = open(self._journal_path, "a", encoding="utf-8")  # noqa: SIM115

    # ------------------------------------------------------------------ journal

    def _append(self, record: dict[str, Any]) -> None:
        self._journal.write(json.dumps(record, separators=(",", ":")) + "\n")
        self._journal.flush()
        os.fsync(self._journal.fileno())

    def _replay(self) -> None:
        if not self._journal_path.exists():
            return
        with open(self._journal_path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                try:
                    rec = json.loads(line)
                    self._apply(rec)
                except (ValueError, KeyError, TypeError, IndexError, ManifestError):
                    self.counters["torn_journal_lines"] += 1
                    log.warning("spool %s: skipped an unreadable journal line", self.root)
        for tid, entry in list(self._entries.items()):
            if entry.state is EntryState.PARTIAL:
                part = self._part(tid)
                have = part.stat().st_size if part.exists() else 0
                if entry.segments == 1:
                    # Bytes past the journalled length may be torn: cut them off.
                    keep = min(have, entry.durable[0])
                    if have != keep or not part.exists():
                        with open(part, "ab") as fh:
                            fh.truncate(keep)
                    entry.durable[0] = keep
                elif not part.exists():
                    part.write_bytes(b"")
                    entry.durable = [0] * entry.segments
                entry.written = list(entry.durable)
                log.info(
                    "spool %s: resuming %s (%s) with %d of %d bytes", self.root, tid,
                    entry.manifest.name, entry.held, entry.manifest.size,
                )
            elif entry.state is EntryState.VERIFIED and not self._ready(tid).exists():
                log.error("spool %s: verified file for %s is missing", self.root, tid)
                del self._entries[tid]

    def _apply(self, rec: dict[str, Any]) -> None:
        op = rec["op"]
        if op == "begin":
            m = Manifest.from_mapping(rec["m"])
            k = int(rec.get("segments", 1))
            self._entries[m.transfer_id] = Entry(m, k, durable=[0] * k, written=[0] * k)
            return
        entry = self._entries.get(rec["id"])
        if entry is None:
            return
        if op == "durable":
            entry.durable[int(rec.get("seg", 0))] = int(rec["n"])
        elif op == "verified":
            entry.state = EntryState.VERIFIED
        elif op == "forwarded":
            entry.forwarded.add(str(rec["to"]))
        elif op == "delivered":
            entry.delivered = str(rec["path"])
        elif op == "done":
            entry.state = EntryState.DONE
        elif op == "failed":
            del self._entries[rec["id"]]

    def _compact(self) -> None:
        """Rewrite the journal as the current state, so it does not grow without bound."""
        tmp = self._journal_path.with_suffix(".tmp")
        done = [e for e in self._entries.values() if e.state is EntryState.DONE]
        for old in done[:-10000]:  # remember the last 10 000 finished ids for idempotence
            del self._entries[old.manifest.transfer_id]
        with open(tmp, "w", encoding="utf-8") as fh:
            for tid, e in self._entries.items():
                recs: list[dict[str, Any]] = [
                    {"op": "begin", "m": e.manifest.to_dict(), "segments": e.segments}
                ]
                if e.state is EntryState.PARTIAL:
                    recs += [{"op": "durable", "id": tid, "seg": i, "n": n}
                             for i, n in enumerate(e.durable)]
                else:
                    recs.append({"op": "verified", "id": tid})
                recs += [{"op": "forwarded", "id": tid, "to": t} for t in sorted(e.forwarded)]
                if e.delivered:
                    recs.append({"op": "delivered", "id": tid, "path": e.delivered})
                if e.state is EntryState.DONE:
                    recs.append({"op": "done", "id": tid})
                for r in recs:
                    fh.write(json.dumps(r, separators=(",", ":")) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self._journal_path)

    # ------------------------------------------------------------------ paths, accounting

    def _part(self, tid: str) -> Path:
        return self.root / "partial" / f"{tid}.part"

    def _ready(self, tid: str) -> Path:
        return self.root / "ready" / tid

    def reserved_bytes(self) -> int:
        """Bytes the spool holds or has promised to hold (declared sizes of live transfers)."""
        with self._lock:
            return sum(
                e.manifest.size for e in self._entries.values() if e.state is not EntryState.DONE
            )

    def is_active(self, tid: str) -> bool:
        """Whether a connection currently holds a claim on ``tid``."""
        with self._lock:
            entry = self._entries.get(tid)
            return entry is not None and bool(entry.claims)

    def entry(self, tid: str) -> Entry | None:
        with self._lock:
            return self._entries.get(tid)

    # ------------------------------------------------------------------ receiving

    def begin(self, manifest: Manifest) -> int:
        """Claim ``manifest`` (a whole file or one lane's segment) for one connection.

        Returns the offset already held, relative to the manifest's span. Raises
        :class:`SpoolRefusal` when the claim is taken by another connection (BUSY),
        conflicts with what the spool knows of that transfer id (BAD_MANIFEST) or does not
        fit the quota or the disk (QUOTA / STORAGE).
        """
        tid = manifest.transfer_id
        base = manifest.whole()
        seg = manifest.segment
        with self._lock:
            entry = self._entries.get(tid)
            if entry is not None and entry.manifest != base:
                raise self._refuse(
                    Reason.BAD_MANIFEST,
                    f"transfer id {tid} is already in use with a different manifest",
                )
            if entry is not None and seg is not None and seg[1] != entry.segments:
                raise self._refuse(
                    Reason.BAD_MANIFEST,
                    f"transfer {tid} is being received in {entry.segments} lane(s), "
                    f"not {seg[1]}",
                )
            if entry is None:
                self._check_space(base)
                k = 1 if seg is None else seg[1]
                entry = Entry(base, k, durable=[0] * k, written=[0] * k)
                self._part(tid).write_bytes(b"")
                self._entries[tid] = entry
                self._append({"op": "begin", "m": base.to_dict(), "segments": k})
            key = None if seg is None else seg[0]
            if key in entry.claims or (entry.claims and (key is None or None in entry.claims)):
                raise self._refuse(Reason.BUSY, f"transfer {tid} is in progress on another link")
            if entry.state is not EntryState.PARTIAL:
                return manifest.length
            start, _ = manifest.span()
            if seg is None:
                held = entry.prefix()
            else:
                held = entry.durable[seg[0]]
            handle = open(self._part(tid), "r+b")  # noqa: SIM115
            handle.seek(start + held)
            if entry.segments == 1:
                handle.truncate(held)
            # Bytes written but never made durable are not trusted; only this claim's
            # segments are reset, other lanes may be writing theirs right now.
            for i in range(entry.segments) if key is None else (key,):
                entry.written[i] = entry.durable[i]
            entry.claims[key] = Claim(key, handle, start + held, synced_at=time.monotonic())
            return held

    def _check_space(self, manifest: Manifest) -> None:
        reserved = self.reserved_bytes()
        if self.quota_bytes is not None and reserved + manifest.size > self.quota_bytes:
            free = max(0, self.quota_bytes - reserved)
            raise self._refuse(
                Reason.QUOTA,
                f"spool quota full: {manifest.name} needs {_human(manifest.size)}, "
                f"{_human(free)} free of {_human(self.quota_bytes)} (unsent data is kept "
                "until forwarded; retry later)",
            )
        disk_free = shutil.disk_usage(self.root).free
        if manifest.size > disk_free:
            raise self._refuse(
                Reason.STORAGE,
                f"disk full: {manifest.name} needs {_human(manifest.size)}, "
                f"{_human(disk_free)} free on the spool's disk",
            )

    def _refuse(self, code: Reason, reason: str) -> SpoolRefusal:
        self.counters["refused"] += 1
        return SpoolRefusal(code, reason)

    @staticmethod
    def _key(m: Manifest | str) -> tuple[str, int | None]:
        if isinstance(m, str):
            return m, None
        return m.transfer_id, None if m.segment is None else m.segment[0]

    def _claim(self, m: Manifest | str) -> tuple[Entry, Claim]:
        tid, key = self._key(m)
        entry = self._entries.get(tid)
        claim = None if entry is None else entry.claims.get(key)
        if entry is None or claim is None:
            raise SpoolRefusal(Reason.STORAGE, f"no claim on transfer {tid}")
        return entry, claim

    def write(self, m: Manifest | str, offset: int, data: bytes) -> None:
        """Store ``data`` at ``offset`` of the claim's span (where the last write ended).

        ``m`` is the manifest the connection announced, or a transfer id for a whole file.
        """
        with self._lock:
            entry, claim = self._claim(m)
        start = 0 if isinstance(m, str) else m.span()[0]
        at = start + offset
        if at != claim.position:
            raise SpoolRefusal(Reason.STORAGE, f"write at {at}, expected {claim.position}")
        try:
            claim.handle.write(data)
        except OSError as exc:
            raise SpoolRefusal(Reason.STORAGE, f"cannot write spool file: {exc}") from exc
        end = at + len(data)
        claim.position = end
        with self._lock:
            for i in range(entry.segments):
                s0, s1 = entry.bounds(i)
                # Extend segment i if this write overlaps it and joins what it holds.
                if at < s1 and end > s0 and at <= s0 + entry.written[i] < end:
                    entry.written[i] = min(s1, end) - s0
                    claim.touched.add(i)
        claim.unsynced += len(data)
        if (claim.unsynced >= self.sync_bytes
                or time.monotonic() - claim.synced_at >= self.sync_interval):
            self.sync(m)

    def sync(self, m: Manifest | str) -> None:
        """Make the claim's received bytes durable and record how many in the journal."""
        with self._lock:
            try:
                entry, claim = self._claim(m)
            except SpoolRefusal:
                return
            claim.handle.flush()
            os.fsync(claim.handle.fileno())
            claim.unsynced = 0
            claim.synced_at = time.monotonic()
            tid = entry.manifest.transfer_id
            for i in sorted(claim.touched):
                if entry.written[i] != entry.durable[i]:
                    entry.durable[i] = entry.written[i]
                    self._append({"op": "durable", "id": tid, "seg": i, "n": entry.durable[i]})
            self._hash_ahead(entry)

    def _hash_ahead(self, entry: Entry) -> None:
        """Hash the durable bytes held from the start of the file that are not hashed yet.
        Durable bytes are never written again (a resumed claim writes after them)."""
        upto = entry.prefix()
        if upto <= entry.hashed or entry.state is not EntryState.PARTIAL:
            return
        if entry.digest is None:
            entry.digest, entry.hashed = hashlib.sha256(), 0
        with open(self._part(entry.manifest.transfer_id), "rb") as fh:
            fh.seek(entry.hashed)
            while entry.hashed < upto and (
                    chunk := fh.read(min(1 << 20, upto - entry.hashed))):
                entry.digest.update(chunk)
                entry.hashed += len(chunk)

    def release(self, m: Manifest | str) -> None:
        """The connection carrying ``m`` ended: keep what arrived, free the claim."""
        with self._lock:
            tid, key = self._key(m)
            entry = self._entries.get(tid)
            claim = None if entry is None else entry.claims.get(key)
            if entry is None or claim is None:
                return
            try:
                self.sync(m)
            finally:
                claim.handle.close()
                del entry.claims[key]

    def complete(self, m: Manifest | str) -> Path:
        """Verify the full file against the manifest hash; return its path in the spool.

        On a mismatch the data is discarded (the sender must start again) and
        :class:`SpoolRefusal` with ``HASH_MISMATCH`` or ``SIZE_MISMATCH`` is raised.
        """
        tid, _ = self._key(m)
        with self._lock:
            entry = self._entries[tid]
            if entry.state is not EntryState.PARTIAL:
                return self._ready(tid) if entry.state is EntryState.VERIFIED else Path(
                    entry.delivered or self._ready(tid))
            self.sync(m)
            part = self._part(tid)
            hashed = entry.hashed if entry.digest is not None else 0
            digest = entry.digest.copy() if hashed else hashlib.sha256()
        size = hashed
        with open(part, "rb") as fh:
            fh.seek(hashed)
            while chunk := fh.read(1 << 20):
                digest.update(chunk)
                size += len(chunk)
        man = entry.manifest
        problem: SpoolRefusal | None = None
        if size != man.size:
            problem = SpoolRefusal(
                Reason.SIZE_MISMATCH, f"size mismatch: manifest says {man.size}, stored {size}"
            )
        elif digest.hexdigest() != man.sha256:
            problem = SpoolRefusal(
                Reason.HASH_MISMATCH,
                f"SHA-256 mismatch: manifest says {man.sha256[:16]}..., "
                f"received data hashes to {digest.hexdigest()[:16]}...",
            )
        with self._lock:
            for claim in entry.claims.values():
                claim.handle.close()
            entry.claims.clear()
            if problem is not None:
                part.unlink(missing_ok=True)
                del self._entries[tid]
                self._append({"op": "failed", "id": tid, "reason": problem.reason})
                self.counters["failed"] += 1
                raise problem
            os.replace(part, self._ready(tid))
            entry.state = EntryState.VERIFIED
            entry.durable = [e - s for s, e in map(entry.bounds, range(entry.segments))]
            entry.written = list(entry.durable)
            self._append({"op": "verified", "id": tid})
            self.counters["verified"] += 1
            self._deliver(entry)
            self._maybe_done(entry)
            return self._ready(tid) if entry.state is EntryState.VERIFIED else Path(
                entry.delivered or ""
            )

    def all_held(self, tid: str) -> bool:
        """Whether every byte of ``tid`` is stored (ready for verification)."""
        with self._lock:
            entry = self._entries.get(tid)
            if entry is None:
                return False
            if entry.state is not EntryState.PARTIAL:
                return True
            return all(entry.durable[i] == e - s
                       for i, (s, e) in enumerate(map(entry.bounds, range(entry.segments))))

    def _deliver(self, entry: Entry) -> None:
        if self.deliver_dir is None or entry.delivered:
            return
        m = entry.manifest
        folder = self.deliver_dir / m.vehicle_id
        folder.mkdir(parents=True, exist_ok=True)
        target = folder / m.name
        if target.exists():
            target = folder / f"{m.transfer_id[:12]}-{m.name}"
        tmp = folder / f".{m.transfer_id}.tmp"
        src = self._ready(m.transfer_id)
        try:
            os.link(src, tmp)
        except OSError:
            shutil.copyfile(src, tmp)
        os.replace(tmp, target)
        entry.delivered = str(target)
        self._append({"op": "delivered", "id": m.transfer_id, "path": entry.delivered})

    def _maybe_done(self, entry: Entry) -> None:
        """Let go of a verified file once it is safe elsewhere: delivered and/or forwarded."""
        elsewhere = entry.delivered is not None or bool(self.forward_targets)
        if (entry.state is EntryState.VERIFIED and elsewhere
                and set(self.forward_targets) <= entry.forwarded):
            self._ready(entry.manifest.transfer_id).unlink(missing_ok=True)
            entry.state = EntryState.DONE
            self._append({"op": "done", "id": entry.manifest.transfer_id})

    # ------------------------------------------------------------------ forwarding

    def outbox(self, target: str) -> Iterator[tuple[Manifest, Path]]:
        """Verified files not yet confirmed by ``target``, oldest first."""
        with self._lock:
            items = [
                (e.manifest, self._ready(tid)) for tid, e in self._entries.items()
                if e.state is EntryState.VERIFIED and target not in e.forwarded
            ]
        yield from items

    def mark_forwarded(self, tid: str, target: str) -> None:
        """``target`` confirmed the file's hash; drop it once every target has."""
        with self._lock:
            entry = self._entries.get(tid)
            if entry is None or target in entry.forwarded:
                return
            entry.forwarded.add(target)
            self._append({"op": "forwarded", "id": tid, "to": target})
            self._maybe_done(entry)

    def close(self) -> None:
        """Sync every open transfer and close the journal (idempotent)."""
        with self._lock:
            for tid, entry in list(self._entries.items()):
                for key in list(entry.claims):
                    self.release(tid if key is None else replace(
                        entry.manifest, segment=(key, entry.segments)))
            if not self._journal.closed:
                self._journal.close()
