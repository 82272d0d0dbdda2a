"""One ``ImageProduct`` per image, however it reaches the relay. Pure: dicts in, dicts out.

An image can be announced over JAUS (``image_id`` ``atr-N``, no transfer id yet) and arrive
over UDT (pulled after the announcement, or pushed by ``send-image`` before it). Both
describe the same bytes, so the SHA-256 is the image's identity: whichever comes first
names the product (vehicle id and image id, the DDS key), and the other only fills in
what it knows - the transfer id and thumbnail from the transfer, the ATR targets, file
name and capture time from the announcement. Every later sample of that image (progress,
chunks, the verified product) carries the same key.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

from links.udt import products
from links.udt.protocol import Manifest


@dataclass
class ImageIndex:
    """Products by SHA-256, oldest forgotten past ``max_images``."""

    max_images: int = 4096
    _by_sha: OrderedDict[str, dict[str, Any]] = field(default_factory=OrderedDict)

    def _keep(self, sha: str, sample: dict[str, Any]) -> dict[str, Any]:
        self._by_sha[sha] = sample
        self._by_sha.move_to_end(sha)
        while len(self._by_sha) > self.max_images:
            self._by_sha.popitem(last=False)
        return dict(sample)

    def get(self, sha256: str) -> dict[str, Any] | None:
        found = self._by_sha.get(sha256)
        return None if found is None else dict(found)

    def key(self, manifest: Manifest) -> tuple[str, str]:
        """``(vehicle_id, image_id)`` samples about this transfer's image are published under.

        The first sample published names the image: a transfer heard of before any
        announcement claims its key here, so an announcement that arrives while the file is
        still being verified (a pushing sender may already have its answer) joins it rather
        than starting a second product. The claim carries no transfer id, so the image
        still counts as not here until :meth:`transferred`.
        """
        found = self._by_sha.get(manifest.sha256)
        if found is None:
            found = {**products.image_product(manifest), "transfer_id": ""}
            self._keep(manifest.sha256, found)
        return found["vehicle_id"], found["image_id"]

    def announced(self, sample: dict[str, Any]) -> dict[str, Any]:
        """The product to publish for an announcement (``sample`` with a hex ``sha256``)."""
        sha = str(sample.get("sha256", ""))
        known = self._by_sha.get(sha) if sha else None
        if known is None:
            return self._keep(sha, dict(sample)) if sha else dict(sample)
        merged = dict(known)
        for name in ("targets", "capture_time_ms", "format"):
            if sample.get(name) and not known.get(name):
                merged[name] = sample[name]
        if sample.get("targets"):
            merged["targets"] = sample["targets"]
        return self._keep(sha, merged)

    def transferred(self, manifest: Manifest, thumbnail: bytes = b"") -> dict[str, Any]:
        """The product to publish once the transfer of ``manifest`` is verified."""
        fresh = products.image_product(manifest)
        known = self._by_sha.get(manifest.sha256)
        merged = fresh if known is None else {
            **known, "transfer_id": manifest.transfer_id,
            "size_bytes": manifest.size,
            "targets": known.get("targets") or fresh["targets"],
        }
        if thumbnail:
            merged["thumbnail_png"] = thumbnail
        return self._keep(manifest.sha256, merged)
