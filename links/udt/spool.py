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
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import IO, Any

from links.udt.protocol import Manifest, ManifestError, Reason

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
class Entry:
    """One transfer the spool knows about."""

    manifest: Manifest
    state: EntryState = EntryState.PARTIAL
    durable: int = 0
    written: int = 0
    forwarded: set[str] = field(default_factory=set)
    delivered: str | None = None
    handle: IO[bytes] | None = None
    unsynced: int = 0
    synced_at: float = 0.0


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
        self._active: set[str] = set()
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
                except (ValueError, KeyError, TypeError, ManifestError):
                    self.counters["torn_journal_lines"] += 1
                    log.warning("spool %s: skipped an unreadable journal line", self.root)
        for tid, entry in list(self._entries.items()):
            if entry.state is EntryState.PARTIAL:
                part = self._part(tid)
                have = part.stat().st_size if part.exists() else 0
                keep = min(have, entry.durable)
                if have != keep or not part.exists():
                    with open(part, "ab") as fh:
                        fh.truncate(keep)
                entry.durable = entry.written = keep
                log.info(
                    "spool %s: resuming %s (%s) at %d of %d bytes", self.root, tid,
                    entry.manifest.name, keep, entry.manifest.size,
                )
            elif entry.state is EntryState.VERIFIED and not self._ready(tid).exists():
                log.error("spool %s: verified file for %s is missing", self.root, tid)
                del self._entries[tid]

    def _apply(self, rec: dict[str, Any]) -> None:
        op = rec["op"]
        if op == "begin":
            m = Manifest.from_mapping(rec["m"])
            self._entries[m.transfer_id] = Entry(m)
            return
        entry = self._entries.get(rec["id"])
        if entry is None:
            return
        if op == "durable":
            entry.durable = int(rec["n"])
        elif op == "verified":
            entry.state = EntryState.VERIFIED
            entry.durable = entry.manifest.size
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
                recs: list[dict[str, Any]] = [{"op": "begin", "m": e.manifest.to_dict()}]
                if e.state is EntryState.PARTIAL:
                    recs.append({"op": "durable", "id": tid, "n": e.durable})
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
        """Whether a connection currently holds the claim on ``tid``."""
        with self._lock:
            return tid in self._active

    def entry(self, tid: str) -> Entry | None:
        with self._lock:
            return self._entries.get(tid)

    # ------------------------------------------------------------------ receiving

    def begin(self, manifest: Manifest) -> int:
        """Claim ``manifest`` for one connection; return the byte offset already held.

        Raises :class:`SpoolRefusal` when the transfer is already being received on another
        connection (BUSY), conflicts with a known transfer id (BAD_MANIFEST) or does not fit
        the quota or the disk (QUOTA / STORAGE).
        """
        tid = manifest.transfer_id
        with self._lock:
            if tid in self._active:
                raise self._refuse(Reason.BUSY, f"transfer {tid} is in progress on another link")
            entry = self._entries.get(tid)
            if entry is not None and entry.manifest != manifest:
                raise self._refuse(
                    Reason.BAD_MANIFEST,
                    f"transfer id {tid} is already in use with a different manifest",
                )
            if entry is None:
                self._check_space(manifest)
                entry = Entry(manifest)
                self._part(tid).write_bytes(b"")
                self._entries[tid] = entry
                self._append({"op": "begin", "m": manifest.to_dict()})
            self._active.add(tid)
            if entry.state is EntryState.PARTIAL:
                entry.handle = open(self._part(tid), "r+b")  # noqa: SIM115
                entry.handle.seek(entry.durable)
                entry.handle.truncate(entry.durable)
                entry.synced_at = time.monotonic()
                entry.written = entry.durable
                return entry.durable
            return manifest.size

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

    def write(self, tid: str, offset: int, data: bytes) -> None:
        """Store ``data`` at ``offset`` (which must be where the previous write ended)."""
        entry = self._entries[tid]
        if entry.handle is None or offset != entry.written:
            raise SpoolRefusal(Reason.STORAGE, f"write at {offset}, expected {entry.written}")
        try:
            entry.handle.write(data)
        except OSError as exc:
            raise SpoolRefusal(Reason.STORAGE, f"cannot write spool file: {exc}") from exc
        entry.written += len(data)
        entry.unsynced += len(data)
        if (entry.unsynced >= self.sync_bytes
                or time.monotonic() - entry.synced_at >= self.sync_interval):
            self.sync(tid)

    def sync(self, tid: str) -> None:
        """Make the received bytes durable and record how many in the journal."""
        with self._lock:
            entry = self._entries.get(tid)
            if entry is None or entry.handle is None:
                return
            entry.handle.flush()
            os.fsync(entry.handle.fileno())
            entry.unsynced = 0
            entry.synced_at = time.monotonic()
            if entry.written != entry.durable:
                entry.durable = entry.written
                self._append({"op": "durable", "id": tid, "n": entry.durable})

    def release(self, tid: str) -> None:
        """The connection carrying ``tid`` ended: keep what arrived, free the claim."""
        with self._lock:
            entry = self._entries.get(tid)
            if entry is not None and entry.handle is not None:
                try:
                    self.sync(tid)
                finally:
                    entry.handle.close()
                    entry.handle = None
            self._active.discard(tid)

    def complete(self, tid: str) -> Path:
        """Verify the full file against the manifest hash; return its path in the spool.

        On a mismatch the partial data is discarded (the sender must start again) and
        :class:`SpoolRefusal` with ``HASH_MISMATCH`` or ``SIZE_MISMATCH`` is raised.
        """
        with self._lock:
            entry = self._entries[tid]
            if entry.state is not EntryState.PARTIAL:
                return self._ready(tid)
            self.sync(tid)
            part = self._part(tid)
        digest = hashlib.sha256()
        size = 0
        with open(part, "rb") as fh:
            while chunk := fh.read(1 << 20):
                digest.update(chunk)
                size += len(chunk)
        m = entry.manifest
        problem: SpoolRefusal | None = None
        if size != m.size:
            problem = SpoolRefusal(
                Reason.SIZE_MISMATCH, f"size mismatch: manifest says {m.size}, stored {size}"
            )
        elif digest.hexdigest() != m.sha256:
            problem = SpoolRefusal(
                Reason.HASH_MISMATCH,
                f"SHA-256 mismatch: manifest says {m.sha256[:16]}..., "
                f"received data hashes to {digest.hexdigest()[:16]}...",
            )
        with self._lock:
            if entry.handle is not None:
                entry.handle.close()
                entry.handle = None
            if problem is not None:
                part.unlink(missing_ok=True)
                del self._entries[tid]
                self._append({"op": "failed", "id": tid, "reason": problem.reason})
                self.counters["failed"] += 1
                raise problem
            os.replace(part, self._ready(tid))
            entry.state = EntryState.VERIFIED
            entry.durable = entry.written = m.size
            self._append({"op": "verified", "id": tid})
            self.counters["verified"] += 1
            self._deliver(entry)
            self._maybe_done(entry)
            return self._ready(tid) if entry.state is EntryState.VERIFIED else Path(
                entry.delivered or ""
            )

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
            for tid in list(self._active):
                self.release(tid)
            if not self._journal.closed:
                self._journal.close()
