"""What the ``send-image`` and ``receive-images`` commands run. Does file and network I/O.

``send_image`` hashes a file, builds its manifest and sends it with resume. ``ImageService``
is the receiving side of a vehicle → relay → operator chain: a UDT receiver writing into a
journalled spool, an announcer publishing each verified file as ``ImageProduct`` /
``ImageData`` / ``TransferStatus`` dicts, and one forwarder per downstream target.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from links.udt import products
from links.udt.fetch_queue import FetchQueue, Priority, Wanted
from links.udt.image_index import ImageIndex
from links.udt.protocol import (
    AtrMetadata,
    Backoff,
    Manifest,
    check_file_name,
    new_sha256,
    transfer_id_for,
)
from links.udt.puller import Puller
from links.udt.spool import Spool
from links.udt.thumbnail import HEAD, NoThumbnail, check_head, thumbnail
from links.udt.transfer import (
    BulkReceiver,
    BulkSender,
    Forwarder,
    ProgressFn,
    TransferResult,
    parse_address,
)

log = logging.getLogger(__name__)

THUMBNAIL_MAX_FILE = 64 << 20
"""Larger files are not read back for a thumbnail."""

PublishFn = Callable[[str, dict[str, Any]], None]
"""``publish(topic, sample_dict)``, e.g. ``DdsBridge.publish``."""

_FORMATS = {
    ".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg", ".tif": "tiff", ".tiff": "tiff",
    ".bmp": "bmp", ".gif": "gif", ".pgm": "pgm", ".ppm": "ppm", ".xtf": "xtf",
}


def _address(value: str | tuple[str, int]) -> tuple[str, int]:
    return parse_address(value) if isinstance(value, str) else value


def manifest_for_file(
    path: str | os.PathLike[str],
    *,
    vehicle_id: str,
    image_format: str | None = None,
    capture_time: float | None = None,
    atr: AtrMetadata | None = None,
) -> Manifest:
    """Hash ``path`` and describe it; the transfer id is stable so a re-run resumes."""
    p = Path(path)
    digest = new_sha256()
    size = 0
    with open(p, "rb") as fh:
        while chunk := fh.read(1 << 20):
            digest.update(chunk)
            size += len(chunk)
    name = check_file_name(p.name)
    sha = digest.hexdigest()
    fmt = image_format or _FORMATS.get(p.suffix.lower(), "raw")
    ctime = p.stat().st_mtime if capture_time is None else capture_time
    return Manifest.from_mapping({
        **Manifest(transfer_id_for(vehicle_id, name, sha), vehicle_id, name, size, sha, fmt,
                   ctime, atr).to_dict(),
    })


def send_image(
    path: str | os.PathLike[str],
    to: str | tuple[str, int],
    *,
    vehicle_id: str = "vehicle",
    max_rate_bps: int | None = None,
    progress: ProgressFn | None = None,
    give_up_after: float | None = 60.0,
    backoff: Backoff | None = None,
    manifest: Manifest | None = None,
    stop: threading.Event | None = None,
    stall_timeout: float = 10.0,
    lanes: int = 0,
    keys: Mapping[str, bytes] | None = None,
) -> TransferResult:
    """Send one file and wait for the receipt; ``result.ok`` only if the hash was confirmed.

    ``keys`` (vehicle id -> pre-shared key) answer a receiver that requires authentication.
    """
    m = manifest or manifest_for_file(path, vehicle_id=vehicle_id)
    with BulkSender(
        _address(to), max_rate_bps=max_rate_bps, progress=progress,
        give_up_after=give_up_after, backoff=backoff, stop=stop, stall_timeout=stall_timeout,
        lanes=lanes, keys=keys,
    ) as sender:
        return sender.send_file(path, m)


class ImageService:
    """Receive images into ``out_dir``, announce them, and forward them downstream.

    The spool lives in ``spool_dir`` (default ``<out_dir>/.spool``); verified files appear
    as ``<out_dir>/<vehicle_id>/<name>``. ``forward`` lists ``HOST:PORT`` receivers each
    file must reach; ``publish`` gets every ``ImageProduct``/``ImageData``/``TransferStatus``.
    With ``keys`` (vehicle id -> pre-shared key) only those vehicles may deliver, each
    proving it holds its key; the forwarders answer downstream challenges with them.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        listen: str | tuple[str, int] = ("127.0.0.1", 0),
        *,
        spool_dir: str | os.PathLike[str] | None = None,
        forward: Sequence[str | tuple[str, int]] = (),
        quota_bytes: int | None = None,
        publish: PublishFn | None = None,
        publish_data: bool = True,
        max_rate_bps: int | None = None,
        idle_timeout: float = 30.0,
        forward_backoff: Backoff | None = None,
        forward_lanes: int = 0,
        keys: Mapping[str, bytes] | None = None,
        sources: Mapping[str, str | tuple[str, int]] | None = None,
        fetch_priority: Priority = "confidence",
        fetch_budget_bps: int | None = None,
        reserved_bps: Callable[[], float] | None = None,
        fetch_queue: FetchQueue | None = None,
        fetch_lanes: int = 0,
    ) -> None:
        self.out_dir = Path(out_dir)
        #: vehicle id -> its image server, for announced images ("*": any other vehicle)
        self.sources = {v: _address(a) for v, a in (sources or {}).items()}
        self.index = ImageIndex()
        self._progress: dict[str, int] = {}
        targets = [_address(t) for t in forward]
        self.spool = Spool(
            spool_dir or self.out_dir / ".spool", quota_bytes=quota_bytes,
            forward_targets=tuple(f"{h}:{p}" for h, p in targets), deliver_dir=self.out_dir,
        )
        self.publish = publish
        self.publish_data = publish_data
        self.receiver = BulkReceiver(
            self.spool, _address(listen), on_verified=self._verified, on_status=self._status,
            idle_timeout=idle_timeout, keys=keys,
        )
        self.forwarders = [
            Forwarder(self.spool, t, max_rate_bps=max_rate_bps, backoff=forward_backoff,
                      lanes=forward_lanes, keys=keys)
            for t in targets
        ]
        self._rates: dict[str, tuple[float, int]] = {}
        self._publish_lock = threading.Lock()
        self.puller = Puller(
            self.receiver, fetch_queue or FetchQueue(priority=fetch_priority),
            budget_bps=fetch_budget_bps, reserved=reserved_bps, lanes=fetch_lanes,
            on_gave_up=self._gave_up, progress_of=lambda sha: self._progress.get(sha, 0),
        )

    @property
    def address(self) -> tuple[str, int]:
        return self.receiver.address

    def start(self) -> ImageService:
        self.receiver.start()
        for f in self.forwarders:
            f.start()
        self.puller.start()
        return self

    def stop(self) -> None:
        """Stop serving and forwarding; everything received stays in the spool (idempotent)."""
        self.puller.stop()
        self.receiver.stop()
        for f in self.forwarders:
            f.stop()
        self.spool.close()

    def __enter__(self) -> ImageService:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _emit(self, topic: str, sample: dict[str, Any]) -> None:
        if self.publish is not None:
            with self._publish_lock:  # connections run on several threads; publish is not
                self.publish(topic, sample)

    def announce(self, sample: Mapping[str, Any]) -> dict[str, Any]:
        """An image announced over JAUS (an ``ImageProduct`` sample without a transfer id):
        the product to publish for it, and queue its fetch from the vehicle's image server
        unless it is here already or the vehicle has no known server."""
        with self._publish_lock:
            product = self.index.announced(dict(sample))
        sha = str(sample.get("sha256", ""))
        source = self.sources.get(str(sample.get("vehicle_id")), self.sources.get("*"))
        if product.get("transfer_id") or not sha or source is None:
            return product
        targets = sample.get("targets") or []
        confidence = max((float(t.get("confidence", 0.0)) for t in targets), default=0.0)
        self.puller.want(Wanted(
            str(sample["vehicle_id"]), str(sample["image_id"]), str(sample["file_name"]), sha,
            int(sample["size_bytes"]) if sample.get("size_bytes") else None, source,
            0.0 if confidence != confidence else confidence,
            int(sample.get("capture_time_ms", 0)) / 1000.0))
        return product

    def _gave_up(self, wanted: Wanted, reason: str) -> None:
        self._emit(products.TRANSFER_STATUS, {
            "vehicle_id": wanted.vehicle_id, "transfer_id": wanted.image_id,
            "image_id": wanted.image_id, "state": "TRANSFER_FAILED", "bytes_done": 0,
            "bytes_total": wanted.size or 0, "rate_bps": 0.0, "error": reason,
            "timestamp_ms": int(time.time() * 1000)})

    def _status(self, status: dict[str, Any]) -> None:
        now = time.time()
        tid = status["transfer_id"]
        if status.get("sha256"):
            self._progress[status["sha256"]] = max(self._progress.get(status["sha256"], 0),
                                                   status["bytes_received"])
        rate = 0.0
        prev = self._rates.get(tid)
        if prev is not None and now > prev[0]:
            rate = 8.0 * max(0, status["bytes_received"] - prev[1]) / (now - prev[0])
        self._rates[tid] = (now, status["bytes_received"])
        if status["state"] in ("verified", "failed", "refused"):
            self._rates.pop(tid, None)
        sample = products.transfer_status(status, now=now, rate_bps=rate)
        if status.get("sha256"):
            with self._publish_lock:
                sample["vehicle_id"], sample["image_id"] = self.index.key(status["manifest"])
        self._emit(products.TRANSFER_STATUS, sample)

    def _thumbnail(self, manifest: Manifest, path: Path) -> bytes:
        """A PNG thumbnail of the verified file, also written next to the delivered image
        as ``<name>.thumb.png``; empty (and logged) when the format gets none."""
        if manifest.size > THUMBNAIL_MAX_FILE:
            return b""
        try:
            with open(path, "rb") as fh:  # a format without thumbnails is not read whole
                check_head(fh.read(HEAD))
                fh.seek(0)
                thumb = thumbnail(fh.read())
        except NoThumbnail as exc:
            log.info("no thumbnail of %s: %s", manifest.name, exc)
            return b""
        except OSError as exc:
            log.warning("no thumbnail of %s: %s", manifest.name, exc)
            return b""
        entry = self.spool.entry(manifest.transfer_id)
        if entry is not None and entry.delivered:
            target = Path(entry.delivered)
            try:
                tmp = target.with_name(f".{target.name}.thumb.tmp")
                tmp.write_bytes(thumb)
                tmp.replace(target.with_name(f"{target.name}.thumb.png"))
            except OSError as exc:
                log.warning("cannot write the thumbnail of %s: %s", manifest.name, exc)
        return thumb

    def _verified(self, manifest: Manifest, path: Path) -> None:
        self.puller.arrived(manifest.sha256)
        self._progress.pop(manifest.sha256, None)
        for f in self.forwarders:  # the spool holds it verified: the radio need not wait
            f.wake()               # for the thumbnail and the bus
        thumb = self._thumbnail(manifest, path)
        with self._publish_lock:
            product = self.index.transferred(manifest, thumb)
        self._emit(products.IMAGE_PRODUCT, product)
        vehicle_id, image_id = product["vehicle_id"], product["image_id"]
        if self.publish is not None and self.publish_data:
            count = products.chunk_count(manifest.size)
            with open(path, "rb") as fh:
                for index in range(count):
                    data = fh.read(products.BUS_CHUNK)
                    self._emit(products.IMAGE_DATA, {
                        **products.image_data(manifest, index, count, data),
                        "vehicle_id": vehicle_id, "image_id": image_id})
