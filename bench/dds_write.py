"""How fast GlobalPose samples can be written to Cyclone DDS, bare and through DdsBridge.

Prints samples per second on one core for:

* ``bare``: ``DataWriter.write`` of a prebuilt ``edge_vis::GlobalPose`` instance (the floor
  any relay pays: Python-side CDR serialisation plus Cyclone's write path);
* ``convert``: dict -> GlobalPose conversion alone (:mod:`edge_vis.dds.convert`);
* ``bridge``: ``DdsBridge.publish("GlobalPose", dict)`` (conversion + write).

By default a best-effort reader in a second participant is matched, so the write path
includes delivery; ``--no-reader`` writes into the void. Discovery stays on loopback.

    python bench/dds_write.py [--seconds 2] [--no-reader] [--domain 201]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

from edge_vis.dds import DdsBridge, loopback_config, model
from edge_vis.dds.convert import converter_for


def rate(step: Callable[[int], object], seconds: float) -> float:
    """Calls per second of ``step(i)`` over about ``seconds`` (checked every 256 calls)."""
    count = 0
    start = time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(256):
            step(count)
            count += 1
        now = time.perf_counter()
        if now >= deadline:
            return count / (now - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="per measurement (2)")
    parser.add_argument("--domain", type=int, default=201, help="DDS domain id (201)")
    parser.add_argument("--no-reader", action="store_true", help="no matched reader")
    args = parser.parse_args()
    os.environ.setdefault("CYCLONEDDS_URI", loopback_config())

    partition = f"bench-{os.getpid()}"
    relay = DdsBridge(domain_id=args.domain, partitions=[partition])
    reader_side = None
    if not args.no_reader:
        reader_side = DdsBridge(domain_id=args.domain, partitions=[partition])
        reader = reader_side.reader("GlobalPose")
        relay.wait_for_subscribers("GlobalPose")
    writer = relay._writer("GlobalPose")

    def sample(i: int) -> dict[str, object]:
        return {"vehicle_id": "ugv1", "latitude": 48.1 + i * 1e-7, "longitude": 11.5,
                "altitude": 520.0, "roll": 0.01, "pitch": -0.02, "yaw": 1.57,
                "timestamp_ms": 1_700_000_000_000 + i}

    prebuilt = model.GlobalPose(**sample(0))  # type: ignore[arg-type]
    dicts = [sample(i) for i in range(1024)]
    convert = converter_for(model.GlobalPose)

    bare = rate(lambda i: writer.write(prebuilt), args.seconds)
    conversion = rate(lambda i: convert.to_struct(dicts[i & 1023], "GlobalPose"), args.seconds)
    bridge = rate(lambda i: relay.publish("GlobalPose", dicts[i & 1023]), args.seconds)

    where = "no reader" if args.no_reader else "1 matched best-effort reader"
    print(f"GlobalPose writes, one core, {where}:")
    print(f"  bare DataWriter.write       {bare:10.0f} samples/s  ({1e6 / bare:6.1f} us each)")
    print(f"  dict -> GlobalPose convert  {conversion:10.0f} samples/s  "
          f"({1e6 / conversion:6.1f} us each)")
    print(f"  DdsBridge.publish(dict)     {bridge:10.0f} samples/s  ({1e6 / bridge:6.1f} us each)")
    print(f"  bridge / bare               {bridge / bare:10.2f}")
    if reader_side is not None:
        reader.take()
        reader_side.close()
    relay.close()


if __name__ == "__main__":
    main()
