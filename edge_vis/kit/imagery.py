"""Images and files on the data bus: an ``ImageProduct`` plus ``ImageData`` chunks. No I/O.

Every image a translator publishes - a still image of a JAUS sensor, a file a custom
message carries - goes out the same way: one ``ImageProduct`` sample (metadata, SHA-256)
and the bytes as ``ImageData`` samples of at most :data:`CHUNK_BYTES`, in order. The
message holding the image is a large JAUS data set, reassembled by the router before a
translator sees it.
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

from edge_vis.kit.actions import Publish

IMAGE_PRODUCT = "ImageProduct"
IMAGE_DATA = "ImageData"
#: largest ImageData chunk: well under Cyclone's default 64 kB sample fragment budget
CHUNK_BYTES = 32 * 1024


def image_chunks(vehicle_id: str, image_id: str, data: bytes,
                 size: int = CHUNK_BYTES) -> list[dict[str, Any]]:
    """``ImageData`` samples carrying ``data`` in order (one empty chunk for no data)."""
    count = max(1, math.ceil(len(data) / size))
    return [{"vehicle_id": vehicle_id, "image_id": image_id, "chunk_index": i,
             "chunk_count": count, "data": data[i * size:(i + 1) * size]}
            for i in range(count)]


def publish_image(product: dict[str, Any], data: bytes) -> list[Publish]:
    """The ``ImageProduct`` sample ``product`` (its size and SHA-256 filled in from
    ``data`` when absent) followed by the ``ImageData`` chunks of ``data``."""
    product = {"size_bytes": len(data), **product}
    if "sha256" not in product:  # translators usually have it already: hash an image once
        product["sha256"] = hashlib.sha256(data).hexdigest()
    return [Publish(IMAGE_PRODUCT, product),
            *(Publish(IMAGE_DATA, chunk) for chunk in
              image_chunks(product["vehicle_id"], product["image_id"], data))]
