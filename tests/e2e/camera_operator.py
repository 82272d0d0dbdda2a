"""An operator station in its own process, for the camera pod tests: it builds the typed
topics from the shipped example profile (as a station compiled from ``edge-vis idl
--profile`` would have them) and reads images off DDS.

``python camera_operator.py images DOMAIN PARTITION COUNT``: prints ``ready``, then one
JSON line per complete image (``ImageProduct`` plus every ``ImageData`` chunk): its id,
the size and SHA-256 the product announces, and the size and SHA-256 of the bytes
reassembled from the chunks.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time

from edge_vis.dds import DdsBridge


def images(domain: int, partition: str, count: int) -> None:
    bridge = DdsBridge(domain, (partition,))
    products, chunks = bridge.reader("ImageProduct"), bridge.reader("ImageData")
    print("ready", flush=True)
    announced: dict[str, dict] = {}
    parts: dict[str, dict[int, bytes]] = {}
    done: set[str] = set()
    deadline = time.monotonic() + 60
    while len(done) < count and time.monotonic() < deadline:
        for p in products.take(0.05):
            announced[p["image_id"]] = p
        for c in chunks.take(0.05):
            parts.setdefault(c["image_id"], {})[c["chunk_index"]] = (c["chunk_count"],
                                                                     bytes(c["data"]))
        for image_id, got in parts.items():
            counts = {n for n, _ in got.values()}
            if image_id in done or image_id not in announced or len(counts) != 1 \
                    or len(got) != counts.pop():
                continue
            data = b"".join(got[i][1] for i in sorted(got))
            p = announced[image_id]
            print(json.dumps({"image_id": image_id, "format": p["format"],
                              "file_name": p["file_name"], "size_bytes": p["size_bytes"],
                              "sha256": p["sha256"], "chunks": len(got), "got_size": len(data),
                              "got_sha256": hashlib.sha256(data).hexdigest()}), flush=True)
            done.add(image_id)
    bridge.close()


if __name__ == "__main__":
    images(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]))
