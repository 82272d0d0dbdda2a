"""Bulk image transfer over UDT: goodput on loopback, through a lossy radio, and resume time.

Run: ``.venv/bin/python bench/bulk.py [--quick]``. Prints a table; asserts nothing.

* ``loopback``: files of 1 MiB and 50 MiB sent to a receiver on 127.0.0.1, timed from the
  first byte of the manifest to the receipt confirming the SHA-256 (the sender's hash is
  computed before the clock starts; the receiver's fsync'd journal and verification are
  inside it). Goodput is file bytes per second of that time, best of several runs. "new
  connection" pays UDT's connection set-up and slow start (initial RTT estimate 100 ms)
  per file; "open connection" sends on a connection already carrying files, as a batch
  (``send-image A B C``) and the relay's forwarder do.
* ``lossy``: the same through ``tests/lossy_proxy.py`` at 10 Mbit/s, 2 % loss each way,
  20 ms one-way delay, 64 KiB queue: one lane without a rate budget (UDT probes) and
  with a budget of 9.5 Mbit/s (``UDT_MAXBW``), then four and six lanes (parallel
  connections, ``--lanes N``) sharing that budget; as a fraction of the proxy's 10 Mbit/s,
  mean of two seeds of the proxy's loss pattern.
* ``resume``: a loopback transfer held to 80 Mbit/s is cut (receiver closes every
  connection); the figure is the time from the cut until the receiver has accepted the
  resumed transfer at its offset, with the sender's default backoff.
"""

from __future__ import annotations

import argparse
import logging
import random
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from lossy_proxy import LossyProxy

from links.udt import UdtBulkChannel


def _file(folder: Path, size: int, name: str) -> tuple[Path, object]:
    path = folder / name
    path.write_bytes(random.Random(size).randbytes(size))
    return path, UdtBulkChannel.manifest_for_file(path, vehicle_id=f"bench{time.monotonic_ns()}")


def _timed_send(path: Path, manifest: object, address: tuple[str, int],
                max_rate: int | None = None, lanes: int = 1) -> float:
    started = time.perf_counter()
    result = UdtBulkChannel.send_image(path, address, manifest=manifest, max_rate_bps=max_rate,
                                give_up_after=120, lanes=lanes)
    elapsed = time.perf_counter() - started
    if not result.ok:
        raise SystemExit(f"transfer failed: {result.reason}")
    return elapsed


def loopback(folder: Path, size: int, runs: int, warm: bool) -> tuple[float, float]:
    """Best goodput (MB/s) and median time (s); ``warm`` reuses one connection for all runs
    after a 10 MiB warm-up file, as a batch or the relay's forwarder does."""
    times = []
    with UdtBulkChannel.ImageService(folder / f"lo{size}{warm}") as svc, UdtBulkChannel.BulkSender(
            svc.address, give_up_after=120) as sender:
        if warm:
            path, manifest = _file(folder, 10 << 20, "warmup.bin")
            sender.send_file(path, manifest)
        for run in range(runs):
            path, manifest = _file(folder, size, f"lo{size}_{run}.bin")
            started = time.perf_counter()
            result = sender.send_file(path, manifest)
            times.append(time.perf_counter() - started)
            if not result.ok:
                raise SystemExit(f"transfer failed: {result.reason}")
            if not warm:
                sender.close()
            path.unlink()
    return size / min(times) / 1e6, statistics.median(times)


def lossy(folder: Path, size: int, max_rate: int | None, lanes: int, seed: int
          ) -> tuple[float, dict]:
    path, manifest = _file(folder, size, f"lossy{seed}.bin")
    with UdtBulkChannel.ImageService(folder / f"lossy{seed}{lanes}{max_rate}") as svc, LossyProxy(
        svc.address, loss=0.02, delay=0.020, rate_bps=10e6, queue_bytes=64 * 1024, seed=seed,
        lifetime=300,
    ) as proxy:
        elapsed = _timed_send(path, manifest, proxy.address, max_rate, lanes)
        counters = dict(proxy.counters)
    return size * 8 / elapsed / 1e6, counters


def resume_time(folder: Path, runs: int) -> list[float]:
    out = []
    for run in range(runs):
        path, manifest = _file(folder, 20 << 20, f"resume{run}.bin")
        resumed = threading.Event()
        cut_at = [0.0]
        delays: list[float] = []

        def on_sample(topic: str, sample: dict, _d: list[float] = delays,
                      _c: list[float] = cut_at, _r: threading.Event = resumed) -> None:
            if topic == "TransferStatus" and _c[0] and sample["state"] == "TRANSFER_ACTIVE" \
                    and sample["bytes_done"] > 0 and not _r.is_set():
                _d.append(time.perf_counter() - _c[0])
                _r.set()

        with UdtBulkChannel.ImageService(folder / f"resume{run}", publish=on_sample,
                                  publish_data=False) as svc:
            sender = threading.Thread(target=_timed_send,
                                      args=(path, manifest, svc.address, 80_000_000))
            sender.start()
            time.sleep(0.8)
            cut_at[0] = time.perf_counter()
            svc.receiver.drop_connections()
            resumed.wait(30)
            sender.join(60)
        out += delays
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer runs, smaller lossy file")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    runs = 2 if args.quick else 5
    lossy_size = (4 << 20) if args.quick else (8 << 20)
    rows: list[tuple[str, str, str]] = []
    with tempfile.TemporaryDirectory(prefix="bulk-bench-") as tmp:
        folder = Path(tmp)
        for size, label in ((1 << 20, "1 MiB"), (50 << 20, "50 MiB")):
            for warm in (False, True):
                mbps, median = loopback(folder, size, runs if size < (10 << 20) else 2, warm)
                how = "open connection" if warm else "new connection"
                rows.append((f"loopback {label}, {how}", f"{mbps:7.1f} MB/s",
                             f"best of runs; median {median * 1000:.0f} ms"))
        for lanes, max_rate in ((1, None), (1, 9_500_000), (4, 9_500_000), (6, 9_500_000)):
            label = f"{lanes} lane{'s' if lanes > 1 else ''}, " + (
                "no budget" if max_rate is None else "budget 9.5 Mbit/s")
            figures = [lossy(folder, lossy_size, max_rate, lanes, seed) for seed in (1, 2)]
            good = statistics.mean(f for f, _ in figures)
            c = figures[0][1]
            rows.append((f"lossy 10M/2%/20ms, {label}", f"{good:7.2f} Mbit/s",
                         f"{good / 10 * 100:.0f} % of link; {lossy_size >> 20} MiB file; "
                         f"proxy lost {c.get('up_lost', 0)}+{c.get('down_lost', 0)}, "
                         f"queue-dropped {c.get('up_queue_drop', 0)}"))
        delays = resume_time(folder, 3 if not args.quick else 1)
        if delays:
            rows.append(("resume after a drop", f"{statistics.median(delays) * 1000:7.0f} ms",
                         f"median of {len(delays)}; max {max(delays) * 1000:.0f} ms"))
    width = max(len(r[0]) for r in rows)
    print(f"{'measurement':<{width}}  {'figure':>14}  notes")
    for name, figure, note in rows:
        print(f"{name:<{width}}  {figure:>14}  {note}")


if __name__ == "__main__":
    main()
