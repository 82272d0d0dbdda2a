"""An operator station in its own process that counts ``ImageProduct`` instances.

``python image_watcher.py DOMAIN PARTITION COUNT``: prints ``ready``, reads
``ImageProduct`` until COUNT images carry a transfer id (then two quiet seconds, or 60 s
at most), and prints one JSON line: every sample seen, in order, as vehicle id, image id,
transfer id, SHA-256 and thumbnail length.
"""

from __future__ import annotations

import json
import sys
import time

from edge_vis.dds import DdsBridge


def watch(domain: int, partition: str, count: int) -> None:
    bridge = DdsBridge(domain, (partition,))
    reader = bridge.reader("ImageProduct")
    print("ready", flush=True)
    seen: list[dict] = []
    deadline, quiet_until = time.monotonic() + 60, None
    while time.monotonic() < deadline:
        got = reader.take(0.1)
        for s in got:
            seen.append({"vehicle_id": s["vehicle_id"], "image_id": s["image_id"],
                         "transfer_id": s["transfer_id"], "sha256": s["sha256"],
                         "thumbnail": len(s["thumbnail_png"])})
        fetched = {(s["vehicle_id"], s["image_id"]) for s in seen if s["transfer_id"]}
        if len(fetched) >= count and quiet_until is None:
            quiet_until = time.monotonic() + 2.0
        if quiet_until is not None and time.monotonic() > quiet_until:
            break
    print(json.dumps(seen), flush=True)
    bridge.close()


if __name__ == "__main__":
    watch(int(sys.argv[1]), sys.argv[2], int(sys.argv[3]))
