"""``edge-vis receive-images``: receive, verify, store and forward image files over UDT.

Runs the ``udt`` link plugin's image service (loaded by entry point; the core does not
import ``links``) until SIGINT/SIGTERM. With ``--forward`` it is a store-and-forward relay;
with ``--domain`` it publishes ``ImageProduct``, ``ImageData`` and ``TransferStatus`` on
that DDS domain. Does network, disk and (optionally) DDS I/O.
"""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from pathlib import Path
from typing import Any

from edge_vis import plugins
from edge_vis.errors import ConfigError

log = logging.getLogger(__name__)

NAME = "receive-images"
HELP = "receive image files over UDT into a directory; optionally forward and publish on DDS"

_SIZE = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def parse_size(text: str) -> int:
    """``"500M"``, ``"2G"``, ``"1048576"`` → bytes (binary suffixes; argparse type)."""
    raw = text.strip().lower().removesuffix("ib").removesuffix("b")
    unit = raw[-1:] if raw[-1:] in _SIZE and raw[-1:] else ""
    try:
        value = float(raw[: len(raw) - len(unit)]) * _SIZE[unit]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a size: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"size must not be negative: {text!r}")
    return int(value)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from edge_vis.cli.send_image import parse_rate

    parser.add_argument("--dir", required=True, type=Path,
                        help="where verified images go, as DIR/<vehicle>/<name>")
    parser.add_argument("--listen", required=True, metavar="HOST:PORT",
                        help="UDT address to receive on (port 0 picks one and prints it)")
    parser.add_argument("--spool", type=Path, metavar="DIR",
                        help="spool directory (default DIR/.spool)")
    parser.add_argument("--forward", action="append", default=[], metavar="HOST:PORT",
                        help="forward every verified image to this receiver (repeatable)")
    parser.add_argument("--quota", type=parse_size, metavar="BYTES",
                        help="spool quota (suffix K/M/G); new transfers beyond it are refused")
    parser.add_argument("--max-rate", type=parse_rate, metavar="BPS",
                        help="bulk budget in bit/s for forwarding (suffix k/M/G)")
    parser.add_argument("--forward-lanes", type=int, default=0, metavar="N",
                        help="parallel UDT connections per forwarded file (1-16; default 0: "
                             "adapt to the loss and delay the transfer meets)")
    parser.add_argument("--keys", type=Path, metavar="FILE",
                        help="pre-shared bulk keys (TOML [keys] vehicle = \"hex\"): only "
                             "these vehicles may deliver, each proving it holds its key")
    parser.add_argument("--domain", type=int, metavar="N",
                        help="publish ImageProduct/ImageData/TransferStatus on DDS domain N")
    parser.add_argument("--partition", action="append", default=[], metavar="NAME",
                        help="with --domain, DDS partition to publish in (repeatable)")
    parser.add_argument("--no-image-data", action="store_true",
                        help="with --domain, publish metadata only, not the image bytes")


def _bridge(domain: int, partitions: list[str]) -> Any:
    """A started DDS bridge on ``domain``; its ``publish(topic, dict)`` is what we need."""
    try:
        from edge_vis.dds import bridge as dds_bridge
    except ImportError as exc:
        raise ConfigError(f"--domain needs the DDS bridge (cyclonedds): {exc}") from exc
    bridge = dds_bridge.DdsBridge(domain, partitions)
    bridge.open_writers(["ImageProduct", "ImageData", "TransferStatus"])
    return bridge


def run(args: argparse.Namespace) -> int:
    udt = plugins.load(plugins.BULK, "udt")  # checked against the group's BulkChannel contract
    try:
        listen = udt.parse_address(args.listen)
        forward = [udt.parse_address(f) for f in args.forward]
    except ValueError as exc:
        raise ConfigError(f"address: {exc}") from None
    if not 0 <= args.forward_lanes <= 16:
        raise ConfigError(f"--forward-lanes {args.forward_lanes}: must be 0 (adapt) or 1..16")
    keys = udt.load_keys(args.keys) if args.keys is not None else None
    bridge = _bridge(args.domain, args.partition) if args.domain is not None else None
    stop = threading.Event()

    def _signal(signum: int, _frame: object) -> None:
        log.info("signal %d: stopping (received data stays in the spool)", signum)
        stop.set()

    signal.signal(signal.SIGTERM, _signal)
    signal.signal(signal.SIGINT, _signal)
    service = udt.ImageService(
        args.dir, listen, spool_dir=args.spool, forward=forward, quota_bytes=args.quota,
        publish=None if bridge is None else bridge.publish,
        publish_data=not args.no_image_data, max_rate_bps=args.max_rate,
        forward_lanes=args.forward_lanes, keys=keys,
    )
    try:
        service.start()
        host, port = service.address
        print(f"receiving images on {host}:{port} into {args.dir}", flush=True)
        while not stop.wait(1.0):
            pass
    finally:
        service.stop()
        if bridge is not None:
            bridge.close()
    return 0
