"""Bulk image transfer over UDT: goodput on loopback, through a lossy radio, and resume time.

Run: ``.venv/bin/python bench/bulk.py [--quick] [--only ROWS] [--repeat N] [--stalls]
[--gap S] [--size MIB]``. Prints a table; asserts nothing. ``--only`` runs some rows
(comma-separated: ``loopback``, ``fixed`` = one connection and six lanes, ``adaptive`` = no flags,
``budget``, ``forwarder``, ``pull``, ``resume``, ``teardown``); ``--repeat`` runs each radio
row that many times; ``--stalls`` adds to each radio row how often the bench's own process (the
sender, the relay and the receiver all live in it) stood still 40 ms or more while the
row's clock ran, from a thread that sleeps 5 ms at a time and notes when it wakes late;
``--gap S`` waits S seconds before each radio row (libudt tears down the connections of
the row before a second or two after they close); ``--size MIB`` sets the file size of
the radio rows (16 MiB by default, 8 with ``--quick``): a transfer's start and end cost
about the same whatever the size, so a bigger file shows the rate the lanes keep.

* ``loopback``: files of 1 MiB and 50 MiB sent to a receiver on 127.0.0.1, timed from the
  first byte of the manifest to the receipt confirming the SHA-256 (the sender's hash is
  computed before the clock starts; the receiver's fsync'd journal and verification are
  inside it). Goodput is file bytes per second of that time, best of several runs. "new
  connection" pays UDT's connection set-up and slow start (initial RTT estimate 100 ms)
  per file; "open connection" sends on a connection already carrying files, as a batch
  (``send-image A B C``) and the relay's forwarder do.
* ``radio``: through ``tests/lossy_proxy.py`` in a process of its own at 10 Mbit/s, 20 ms
  one-way delay, 64 KiB queue, with 2 % loss each way and with none, side by side:
  one connection (``--lanes 1``, what ``send-image`` did by default before), six fixed
  lanes (``--lanes 6``), the adaptive default (no flags: 16 lanes paced together at the
  rate the rate probe finds), and the adaptive default with a 5 Mbit/s budget
  (``--max-rate 5M``); goodput (file bytes) as a fraction of the proxy's 10 Mbit/s,
  timed from the manifest to the receipt confirming the SHA-256 (connection set-up, slow
  start and the last segment's tail included). One connection gets a 4 MiB file (its
  rate does not depend on the size and a bigger one takes minutes).
* ``forwarder``: a relay (``ImageService`` with ``forward``) passes a file on to an
  operator-side receiver through the same proxy, with 2 % loss and with none, adaptive
  lanes, no flags; timed from the relay's verification (its ``TransferStatus``, before
  the relay's thumbnail and ``ImageProduct``) to the operator's ``ImageProduct``.
* ``pull``: the relay fetches an announced image from a vehicle's image server
  (``serve-images``) through the same lossy proxy, no flags (lanes paced by the image
  server); timed from the announcement to the relay's ``ImageProduct`` of the verified
  file, the file size of the lanes' rows (the announced SHA-256 is computed before the
  clock starts: the vehicle hashes its image before announcing it).
* every radio row also says where its time went, from the emulated radio's own record of
  when its link was busy (``Timeline``), in the direction the file's data took: how long
  after the clock started the first data packet went onto the link, how long the link
  sat idle while the data flowed (and of that, in the data's first and last second), how
  long after the last data packet the clock stopped, and the link's busy time (data
  packets, and control packets: UDT's ACK2 and NAK, manifests). A row's time is the sum
  of the first, the second, the third and the busy time; then how many segments the
  lanes sent again on a fresh lane (one that stalled at the end), when any. Of the
  control time, the row says how much went to its commonest size of packet: on the
  data's way, UDT's 20-byte ACK2, which each lane's connection sends for every ACK its
  receiver sends (about every 10 ms while data flows), so the more lanes send at once,
  the more of them.
* ``teardown``: a 16-lane push on loopback, then for 3 s a socket call (looking a socket's
  state up, behind libudt's global lock) every 2 ms; the figure is the longest one took.
  libudt's garbage collector tears the closed connections down a second or two after
  they closed, holding that lock, and every new connection (the next file's lanes) and
  socket call waits behind it; it tears down one multiplexer (a UDP socket and two
  threads) per local port, so the lanes of one transfer share one.
* ``resume``: a loopback transfer held to 80 Mbit/s is cut (receiver closes every
  connection); the figure is the time from the cut until the receiver has accepted the
  resumed transfer at its offset, with the sender's default backoff.

``EDGE_VIS_UDT_CC=off`` in the environment runs the lanes on libudt's own congestion
control instead of ``links/udt/udt_cc.cpp``'s (:mod:`links.udt.udt_cc`), for comparison.

With ``--repeat`` 2 or more, a summary follows the table: for each no-flags row (push,
forwarder, pull) at each loss, how many of its runs reached the target (85 % of the link
at 2 % loss, 95 % without) and the least, median and most.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import logging
import random
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from lossy_proxy import separate_process

from edge_vis.tools.lossy_udp import Timeline
from links.udt import UdtBulkChannel, udt_calls
from links.udt.transfer import udt4py

RADIO_BPS = 10e6
"""The emulated radio's rate."""
RADIO = {"delay": 0.020, "rate_bps": RADIO_BPS, "queue_bytes": 64 * 1024, "seed": 1,
         "lifetime": 600, "timeline": True}
"""The emulated radio of every radio row (with the row's loss): see the module doc."""
_RUN = itertools.count()
"""Each run's own folders and files: a repeated row must not find the last one's spool."""


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


class Stalls:
    """Notes when this process stood still: a thread sleeps ``TICK`` seconds at a time
    and records each wake-up ``LATE`` seconds or more behind (``--stalls``)."""

    TICK = 0.005
    LATE = 0.040

    def __init__(self) -> None:
        self.seen: list[tuple[float, float]] = []  # (when it began, how long)
        threading.Thread(target=self._watch, name="bench-stalls", daemon=True).start()

    def _watch(self) -> None:
        while True:
            before = time.monotonic()
            time.sleep(self.TICK)
            late = time.monotonic() - before - self.TICK
            if late >= self.LATE:
                self.seen.append((before, late))

    def between(self, started: float, ended: float) -> str:
        """The stalls that began while a row's clock ran, as a note."""
        inside = [late for when, late in self.seen if started <= when < ended]
        if not inside:
            return "; process never stood still 40 ms or more"
        return (f"; process stood still {len(inside)} times (longest "
                f"{max(inside) * 1000:.0f} ms, in its first second "
                f"{sum(1 for when, _ in self.seen if started <= when < started + 1)})")


STALLS: Stalls | None = None
"""The watchdog of ``--stalls``, or None."""


class SentAgain(logging.Handler):
    """When the lanes sent a segment again on a fresh lane (their log says so)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.times: list[float] = []

    def emit(self, record: logging.LogRecord) -> None:
        if "sending it again" in record.getMessage():
            self.times.append(time.monotonic())

    def between(self, started: float, ended: float) -> str:
        n = sum(started <= t <= ended for t in self.times)
        return f"; {n} segment{'s' * (n != 1)} sent again on a fresh lane" if n else ""


SENT_AGAIN = SentAgain()


def _where(counters: dict, started: float, ended: float) -> str:
    """Where a radio row's time went (see the module doc), from the proxy's timelines."""
    notes = SENT_AGAIN.between(started, ended) + (
        STALLS.between(started, ended) if STALLS is not None else "")
    lines = [counters.get(f"{d}_timeline") for d in ("up", "down")]
    line = max((t for t in lines if t is not None and t.first_full is not None),
               key=lambda t: t.busy_full, default=None)
    if line is None:
        return notes.lstrip("; ")
    first, last = line.first_full, line.last_full
    return (f"data on the radio {(first - started) * 1000:.0f} ms after the start, idle "
            f"{line.idle(first, last) * 1000:.0f} ms while it flowed (first s "
            f"{line.idle(first, first + 1) * 1000:.0f}, last s "
            f"{line.idle(last - 1, last) * 1000:.0f}), done {(ended - last) * 1000:.0f} ms "
            f"after it; radio busy {line.busy_full + line.busy_small:.2f} s (control "
            f"{line.busy_small * 1000:.0f} ms{_most_control(line)})" + notes)


TARGETS = {0.02: 85.0, 0.0: 95.0}
"""The targets of a no-flags transfer on the radio, by loss: % of the link."""


def _summary(shares_of: dict[tuple[str, float], list[float]]) -> list[str]:
    """One line per no-flags row run more than once: runs at the target, least, median,
    most (``shares_of``: (row, loss) -> % of the link of each run)."""
    lines = []
    for (row, loss), shares in shares_of.items():
        if len(shares) < 2:
            continue
        target = TARGETS[loss]
        met = sum(share >= target for share in shares)
        lines.append(f"{row} at {loss:.0%}: {met} of {len(shares)} runs at {target:g} % or "
                     f"more; least "
                     f"{min(shares):.1f}, median {statistics.median(shares):.1f}, most "
                     f"{max(shares):.1f} %")
    return lines


def _of_link(mbps: float) -> str:
    """A goodput as a share of the emulated radio's rate."""
    return f"{mbps * 1e6 / RADIO_BPS * 100:.1f} %"


def _most_control(line: Timeline) -> str:
    """Which size of control packet took most of the link's control time: on the data's
    way, UDT's 20-byte ACK2s (see the module doc)."""
    if not line.small_sizes:
        return ""
    size, count = max(line.small_sizes.items(), key=lambda kv: kv[0] * kv[1])
    return (f", {size * count * 8 / RADIO_BPS * 1000:.0f} ms of it {count:,} packets of "
            f"{size} bytes")


def _paced(history: list) -> str:
    """The rate probe's course: where the start ended and the range paced at after it."""
    if not history:
        return ""
    paced = [rate for _, rate, phase in history if phase == "paced"]
    start = max((rate for _, rate, phase in history if phase == "startup"), default=0.0)
    if not paced:
        return f"16 lanes paced, start up to {start / 1e6:.1f} Mbit/s"
    return (f"16 lanes paced, start up to {start / 1e6:.1f}, then "
            f"{min(paced) / 1e6:.1f}-{max(paced) / 1e6:.1f} Mbit/s")


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


def radio(folder: Path, size: int, loss: float, lanes: int, max_rate: int | None
          ) -> tuple[float, dict, list, str]:
    """Goodput (Mbit/s), the proxy's counters, the rate probe's course and where the
    time went."""
    run = next(_RUN)
    path, manifest = _file(folder, size, f"radio{lanes}{loss}{max_rate}-{run}.bin")
    with UdtBulkChannel.ImageService(folder / f"radio{lanes}{loss}{max_rate}-{run}") as svc, \
            separate_process(svc.address, loss=loss, **RADIO) as (address, counters), \
            UdtBulkChannel.BulkSender(address, max_rate_bps=max_rate, lanes=lanes,
                                      give_up_after=120) as sender:
        started = time.perf_counter()
        result = sender.send_file(path, manifest)
        elapsed = time.perf_counter() - started
    if not result.ok:
        raise SystemExit(f"transfer failed: {result.reason}")
    return (size * 8 / elapsed / 1e6, counters, sender.rate_history,
            _where(counters, started, started + elapsed))


def forwarded(folder: Path, size: int, loss: float) -> tuple[float, str, list]:
    """Goodput (Mbit/s) of the relay's forwarder to the operator side, adaptive lanes,
    where the time went and the rate probe's course."""
    run = next(_RUN)
    path, manifest = _file(folder, size, f"fwd{run}.bin")
    marks: dict[str, float] = {}

    def seen(where: str, topic_seen: str, state: str | None = None) -> object:
        def publish(topic: str, sample: dict) -> None:
            if topic == topic_seen and where not in marks and (
                    state is None or sample.get("state") == state):
                marks[where] = time.perf_counter()
        return publish

    with UdtBulkChannel.ImageService(folder / f"operator{run}", publish_data=False,
                                     publish=seen("operator", "ImageProduct")) as ops, \
            separate_process(ops.address, loss=loss, **RADIO) as (address, counters), \
            UdtBulkChannel.ImageService(folder / f"relay{run}", forward=[address],
                                        publish=seen("relay", "TransferStatus",
                                                     "TRANSFER_COMPLETE"),
                                        publish_data=False) as relay:
        result = UdtBulkChannel.send_image(path, relay.address, manifest=manifest, lanes=1)
        deadline = time.monotonic() + 180
        while "operator" not in marks and time.monotonic() < deadline:
            time.sleep(0.05)
    history = relay.forwarders[0].rate_history  # set once its lanes are done
    if not result.ok or "operator" not in marks:
        raise SystemExit("forwarding failed")
    return (size * 8 / (marks["operator"] - marks["relay"]) / 1e6,
            _where(counters, marks["relay"], marks["operator"]), history)


def pulled(folder: Path, size: int, loss: float) -> tuple[float, str, list]:
    """Goodput (Mbit/s) of the relay fetching an announced image from an image server,
    where the time went and the image server's rate probe's course."""
    run = next(_RUN)
    served = folder / f"vehicle{loss}-{run}"
    served.mkdir()
    content = random.Random(size).randbytes(size)
    (served / "atr-1.png").write_bytes(content)
    sha256 = hashlib.sha256(content).hexdigest()  # the vehicle's work, before it announces
    verified: list[float] = []

    def publish(topic: str, sample: dict) -> None:
        if topic == "ImageProduct" and sample.get("transfer_id") and not verified:
            verified.append(time.perf_counter())

    with UdtBulkChannel.ImageServer(served, vehicle_id="uuv1") as server, \
            separate_process(server.address, loss=loss, **RADIO) as (address, counters), \
            UdtBulkChannel.ImageService(folder / f"puller{loss}-{run}", publish=publish,
                                        publish_data=False,
                                        sources={"*": f"{address[0]}:{address[1]}"}) as relay:
        started = time.perf_counter()
        relay.announce({"vehicle_id": "uuv1", "image_id": "atr-1", "file_name": "atr-1.png",
                        "size_bytes": size, "sha256": sha256,
                        "transfer_id": "", "format": "png",
                        "capture_time_ms": 1_700_000_000_000, "targets": []})
        deadline = time.monotonic() + 180
        while not verified and time.monotonic() < deadline:
            time.sleep(0.02)
    if not verified:
        raise SystemExit("fetch failed")
    return (size * 8 / (verified[0] - started) / 1e6, _where(counters, started, verified[0]),
            server.rate_history)


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


def teardown(folder: Path, runs: int) -> list[float]:
    """The longest a socket call waited (s) in the 3 s after each of ``runs`` 16-lane
    pushes on loopback had closed its connections, one figure per run."""
    bare = udt4py().UDTSocket()  # any socket: looking one up takes libudt's global lock
    out = []
    try:
        for run in range(runs):
            path, manifest = _file(folder, 16 << 20, f"teardown{run}.bin")
            with UdtBulkChannel.ImageService(folder / f"teardown{run}") as svc:
                result = UdtBulkChannel.send_image(path, svc.address, manifest=manifest,
                                                   lanes=16, give_up_after=60)
                if not result.ok:
                    raise SystemExit(f"transfer failed: {result.reason}")
                closed, longest = time.monotonic(), 0.0
                while time.monotonic() - closed < 3.0:
                    before = time.monotonic()
                    udt_calls.state(bare)
                    longest = max(longest, time.monotonic() - before)
                    time.sleep(0.002)
            out.append(longest)
            time.sleep(2.0)  # the service's own connections torn down before the next run
    finally:
        bare.close()
    return out


ROWS = ("loopback", "fixed", "adaptive", "budget", "forwarder", "pull", "resume", "teardown")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer runs, smaller lossy file")
    parser.add_argument("--only", default=",".join(ROWS),
                        help=f"comma-separated rows to run, of {', '.join(ROWS)} (default: all)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run each radio row this many times (default 1)")
    parser.add_argument("--stalls", action="store_true",
                        help="say in each radio row how often this process stood still")
    parser.add_argument("--gap", type=float, default=0.0,
                        help="seconds to wait before each radio row (default 0)")
    parser.add_argument("--size", type=int, default=0, metavar="MIB",
                        help="file size of the radio rows in MiB (default 16, 8 with --quick)")
    args = parser.parse_args()
    global STALLS
    if args.stalls:
        STALLS = Stalls()
    only = set(args.only.split(","))
    if only - set(ROWS):
        parser.error(f"unknown rows: {', '.join(sorted(only - set(ROWS)))}")
    logging.basicConfig(level=logging.WARNING)
    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)  # the lanes' INFO below is counted, not printed
    lanes_log = logging.getLogger("links.udt.lane_run")
    lanes_log.setLevel(logging.INFO)
    lanes_log.addHandler(SENT_AGAIN)
    runs = 2 if args.quick else 5
    if args.size < 0:
        parser.error("--size must be a positive number of MiB")
    radio_size = args.size << 20 if args.size else (8 << 20) if args.quick else (16 << 20)
    rows: list[tuple[str, str, str]] = []
    shares_of: dict[tuple[str, float], list[float]] = {}  # (no-flags row, loss) -> % of link

    def ran(row: str, loss: float, mbps: float) -> None:
        shares_of.setdefault((row, loss), []).append(mbps * 1e6 / RADIO_BPS * 100)
    with tempfile.TemporaryDirectory(prefix="bulk-bench-") as tmp:
        folder = Path(tmp)
        for size, label in ((1 << 20, "1 MiB"), (50 << 20, "50 MiB")):
            for warm in (False, True):
                if "loopback" not in only:
                    continue
                mbps, median = loopback(folder, size, runs if size < (10 << 20) else 2, warm)
                how = "open connection" if warm else "new connection"
                rows.append((f"loopback {label}, {how}", f"{mbps:7.1f} MB/s",
                             f"best of runs; median {median * 1000:.0f} ms"))
        for loss in (0.02, 0.0):
            for label, lanes, max_rate, kind in (
                    ("1 connection (--lanes 1)", 1, None, "fixed"),
                    ("6 fixed lanes (--lanes 6)", 6, None, "fixed"),
                    ("adaptive (no flags)", 0, None, "adaptive"),
                    ("adaptive, budget 5 Mbit/s", 0, 5_000_000, "budget")):
                if (loss == 0.0 and max_rate) or kind not in only:
                    continue
                size = (4 << 20) if lanes == 1 and loss else radio_size
                for _ in range(args.repeat):
                    time.sleep(args.gap)
                    good, c, history, where = radio(folder, size, loss, lanes, max_rate)
                    steps = _paced(history) if lanes == 0 else ""
                    if kind == "adaptive":
                        ran("push, no flags", loss, good)
                    rows.append((f"radio 10M/{loss:.0%}/20ms, {label}", f"{good:7.2f} Mbit/s",
                                 f"{_of_link(good)} of link; {size >> 20} MiB; proxy "
                                 f"lost {c.get('up_lost', 0)}+{c.get('down_lost', 0)}, "
                                 f"queue-dropped {c.get('up_queue_drop', 0)}"
                                 + (f"; {steps}" if steps else "") + f"; {where}"))
        for loss in (0.02, 0.0):
            for _ in range(args.repeat if "forwarder" in only else 0):
                time.sleep(args.gap)
                good, where, history = forwarded(folder, radio_size, loss)
                ran("forwarder", loss, good)
                rows.append((f"radio 10M/{loss:.0%}/20ms, relay forwarder, adaptive",
                             f"{good:7.2f} Mbit/s", f"{_of_link(good)} of link; "
                             f"{radio_size >> 20} MiB, relay verified -> operator verified; "
                             f"{_paced(history)}; {where}"))
        for loss in (0.02, 0.0):
            for _ in range(args.repeat if "pull" in only else 0):
                time.sleep(args.gap)
                good, where, history = pulled(folder, radio_size, loss)
                ran("pull", loss, good)
                rows.append((f"radio 10M/{loss:.0%}/20ms, relay pulls (serve-images)",
                             f"{good:7.2f} Mbit/s", f"{_of_link(good)} of link; "
                             f"{radio_size >> 20} MiB, announced -> relay verified; "
                             f"{_paced(history)}; {where}"))
        delays = resume_time(folder, 3 if not args.quick else 1) if "resume" in only else []
        if delays:
            rows.append(("resume after a drop", f"{statistics.median(delays) * 1000:7.0f} ms",
                         f"median of {len(delays)}; max {max(delays) * 1000:.0f} ms"))
        waits = teardown(folder, 3 if not args.quick else 1) if "teardown" in only else []
        if waits:
            rows.append(("socket call during a teardown", f"{max(waits) * 1000:7.0f} ms",
                         "longest wait in the 3 s after a 16-lane push on loopback closed, "
                         f"worst of {len(waits)} (each: "
                         f"{', '.join(f'{w * 1000:.0f}' for w in waits)} ms)"))
    width = max(len(r[0]) for r in rows)
    print(f"{'measurement':<{width}}  {'figure':>14}  notes")
    for name, figure, note in rows:
        print(f"{name:<{width}}  {figure:>14}  {note}")
    for line in _summary(shares_of):
        print(line)


if __name__ == "__main__":
    main()
