"""Shapes of what a verified image becomes on the data bus. Pure: dicts in, dicts out; no I/O.

The DDS bridge turns these dicts into the ``ImageProduct``, ``ImageData`` and
``TransferStatus`` topic types of ``edge_vis/data/edge_vis.idl``; keeping the mapping
here means the UDT side never imports DDS, and tests can compare plain dicts.
"""

from __future__ import annotations

import math
from typing import Any

from links.udt.protocol import Manifest

IMAGE_PRODUCT = "ImageProduct"
IMAGE_DATA = "ImageData"
TRANSFER_STATUS = "TransferStatus"

BUS_CHUNK = 60 * 1024
"""Bytes of image per ``ImageData`` sample: under 64 KiB so one sample fits a UDP datagram
train without huge fragments on the DDS side."""

_STATES = {
    "started": "TRANSFER_ACTIVE",
    "resumed": "TRANSFER_ACTIVE",
    "active": "TRANSFER_ACTIVE",
    "interrupted": "TRANSFER_PAUSED",
    "verified": "TRANSFER_COMPLETE",
    "failed": "TRANSFER_FAILED",
    "refused": "TRANSFER_FAILED",
}


def image_product(manifest: Manifest) -> dict[str, Any]:
    """The ``ImageProduct`` sample for a verified file (``image_id`` = transfer id)."""
    targets: list[dict[str, Any]] = []
    atr = manifest.atr
    if atr is not None and (atr.target_class is not None or atr.confidence is not None):
        pos = atr.position
        targets.append({
            "target_class": atr.target_class or "",
            "confidence": atr.confidence if atr.confidence is not None else math.nan,
            "latitude": pos.latitude if pos else math.nan,
            "longitude": pos.longitude if pos else math.nan,
            "depth": pos.depth if pos and pos.depth is not None else math.nan,
        })
    return {
        "vehicle_id": manifest.vehicle_id,
        "image_id": manifest.transfer_id,
        "file_name": manifest.name,
        "size_bytes": manifest.size,
        "sha256": manifest.sha256,
        "transfer_id": manifest.transfer_id,
        "format": manifest.image_format,
        "capture_time_ms": round(manifest.capture_time * 1000),
        "targets": targets,
    }


def chunk_count(size: int, chunk: int = BUS_CHUNK) -> int:
    """How many ``ImageData`` samples a file of ``size`` bytes takes (at least one)."""
    return max(1, -(-size // chunk))


def image_data(manifest: Manifest, index: int, count: int, data: bytes) -> dict[str, Any]:
    """``ImageData`` sample ``index`` of ``count`` carrying ``data`` (one bus chunk)."""
    return {
        "vehicle_id": manifest.vehicle_id,
        "image_id": manifest.transfer_id,
        "chunk_index": index,
        "chunk_count": count,
        "data": data,
    }


def transfer_status(status: dict[str, Any], *, now: float, rate_bps: float = 0.0
                    ) -> dict[str, Any]:
    """A ``TransferStatus`` sample from a receiver status dict (see ``BulkReceiver``)."""
    return {
        "vehicle_id": status["vehicle_id"],
        "transfer_id": status["transfer_id"],
        "image_id": status["transfer_id"],
        "state": _STATES.get(status["state"], "TRANSFER_PENDING"),
        "bytes_done": int(status["bytes_received"]),
        "bytes_total": int(status["size"]),
        "rate_bps": float(rate_bps),
        "error": status.get("detail", "") if status["state"] in ("failed", "refused") else "",
        "timestamp_ms": int(now * 1000),
    }
