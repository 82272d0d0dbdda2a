"""``edge-vis send-image``: send one image file over the UDT bulk channel, resumably.

Reads the file and talks UDT through the ``udt`` link plugin (loaded by entry point; the
core does not import ``links``). Shows a progress bar on a terminal and periodic lines
otherwise; exits 0 only when the receiver's receipt confirms the SHA-256.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from edge_vis import plugins
from edge_vis.errors import ConfigError

NAME = "send-image"
HELP = "send image files over UDT with resume; exit 0 when the receiver verified every one"

_SUFFIX = {"": 1, "k": 10**3, "m": 10**6, "g": 10**9}


def parse_rate(text: str) -> int:
    """``"2500000"``, ``"500k"``, ``"10M"`` → bits per second (argparse type)."""
    raw = text.strip().lower().removesuffix("bps").removesuffix("bit/s")
    unit = raw[-1:] if raw[-1:] in _SUFFIX and raw[-1:] else ""
    number = raw[: len(raw) - len(unit)]
    try:
        value = float(number) * _SUFFIX[unit]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a rate in bit/s: {text!r}") from None
    if value < 8:
        raise argparse.ArgumentTypeError(f"rate must be at least 8 bit/s, got {text!r}")
    return int(value)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("files", type=Path, nargs="+", metavar="FILE",
                        help="image file(s) to send, one after the other on one connection")
    parser.add_argument("--to", required=True, metavar="HOST:PORT", help="receiver address")
    parser.add_argument("--vehicle", default="vehicle", metavar="ID",
                        help="vehicle id recorded in the manifest (default 'vehicle')")
    parser.add_argument("--max-rate", type=parse_rate, metavar="BPS",
                        help="bulk budget in bit/s (suffix k/M/G), enforced by UDT_MAXBW")
    parser.add_argument("--format", dest="image_format", metavar="NAME",
                        help="image format (default from the file suffix)")
    parser.add_argument("--capture-time", type=float, metavar="EPOCH_S",
                        help="capture time, seconds since 1970 UTC (default file mtime)")
    parser.add_argument("--target-class", help="ATR target class")
    parser.add_argument("--confidence", type=float, help="ATR confidence 0..1")
    parser.add_argument("--position", metavar="LAT,LON[,DEPTH]",
                        help="ATR target position, degrees and metres")
    parser.add_argument("--keys", type=Path, metavar="FILE",
                        help="pre-shared bulk keys (TOML [keys] vehicle = \"hex\"); the "
                             "--vehicle key answers a receiver that requires authentication")
    parser.add_argument("--lanes", type=int, default=0, metavar="N",
                        help="parallel UDT connections per file (1-16); default 0 adapts the "
                             "number to the loss and delay the transfer meets")
    parser.add_argument("--give-up", type=float, default=120.0, metavar="SECONDS",
                        help="stop retrying after this long without progress (default 120)")


class Progress:
    """Progress bar on a TTY (bytes, rate, ETA); one line every ``every`` seconds otherwise."""

    def __init__(self, name: str, stream: TextIO, every: float = 2.0) -> None:
        self.name = name
        self.stream = stream
        self.tty = stream.isatty()
        self.every = every
        self.start = time.monotonic()
        self._last = 0.0
        self._samples: list[tuple[float, int]] = []

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        self._samples.append((now, done))
        while len(self._samples) > 2 and now - self._samples[0][0] > 5.0:
            self._samples.pop(0)
        if done < total and now - self._last < (0.1 if self.tty else self.every):
            return
        self._last = now
        t0, d0 = self._samples[0]
        rate = (done - d0) / (now - t0) if now > t0 and done > d0 else 0.0
        eta = (total - done) / rate if rate > 0 else None
        pct = 100.0 * done / total if total else 100.0
        text = (f"{self.name}: {_mib(done)}/{_mib(total)} MiB {pct:5.1f}% "
                f"{rate * 8 / 1e6:7.2f} Mbit/s ETA {_eta(eta)}")
        if self.tty:
            width = 24
            fill = int(width * pct / 100)
            self.stream.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {text}\x1b[K")
            if done >= total:
                self.stream.write("\n")
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.1f}"


def _eta(seconds: float | None) -> str:
    if seconds is None:
        return "--:--"
    s = int(seconds + 0.5)
    return f"{s // 60:02d}:{s % 60:02d}" if s < 3600 else f"{s // 3600}h{s % 3600 // 60:02d}m"


def _atr(udt: Any, args: argparse.Namespace) -> Any:
    if args.target_class is None and args.confidence is None and args.position is None:
        return None
    position = None
    if args.position:
        try:
            parts = [float(x) for x in args.position.split(",")]
        except ValueError:
            raise ConfigError(f"--position {args.position!r}: expected LAT,LON[,DEPTH]") from None
        if len(parts) not in (2, 3):
            raise ConfigError(f"--position {args.position!r}: expected LAT,LON[,DEPTH]")
        position = udt.Position(*parts)
    return udt.AtrMetadata(args.target_class, args.confidence, position)


def run(args: argparse.Namespace) -> int:
    udt = plugins.load(plugins.BULK, "udt")  # checked against the group's BulkChannel contract
    for path in args.files:
        if not path.is_file():
            raise ConfigError(f"{path}: no such file")
    try:
        to = udt.parse_address(args.to)
    except ValueError as exc:
        raise ConfigError(f"--to: {exc}") from None
    atr = _atr(udt, args)
    failures = 0
    if not 0 <= args.lanes <= 16:
        raise ConfigError(f"--lanes {args.lanes}: must be 0 (adapt) or 1..16")
    keys = udt.load_keys(args.keys) if args.keys is not None else None
    if keys is not None and args.vehicle not in keys:
        raise ConfigError(f"{args.keys}: no key for vehicle {args.vehicle!r}")
    with udt.BulkSender(to, max_rate_bps=args.max_rate, give_up_after=args.give_up,
                        lanes=args.lanes, keys=keys) as sender:
        for path in args.files:
            try:
                manifest = udt.manifest_for_file(
                    path, vehicle_id=args.vehicle, image_format=args.image_format,
                    capture_time=args.capture_time, atr=atr,
                )
            except ValueError as exc:  # ManifestError: bad name, vehicle id, ATR values
                raise ConfigError(f"{path}: {exc}") from None
            sender.progress = Progress(path.name, sys.stderr)
            started = time.monotonic()
            result = sender.send_file(path, manifest)
            elapsed = time.monotonic() - started
            if result.ok:
                rate = manifest.size * 8 / elapsed / 1e6 if elapsed > 0 else 0.0
                resumed = sum(1 for off in result.resumed_from if off)
                print(f"sent {path.name} ({manifest.size} bytes, sha256 {manifest.sha256}) "
                      f"to {args.to} in {elapsed:.1f} s ({rate:.2f} Mbit/s, "
                      f"{result.attempts} connection attempt(s), {resumed} resume(s)): "
                      "receiver verified the hash", flush=True)
                continue
            failures += 1
            code = result.code.name if result.code is not None else "FAILED"
            print(f"edge-vis send-image: {path.name} not delivered ({code}): {result.reason}",
                  file=sys.stderr)
    return 0 if failures == 0 else 1
