"""``edge-vis serve-images``: the vehicle side of pull - serve a directory's images over UDT.

A relay that hears this vehicle announce an image (ReportAtrImageAvailable) connects
here, asks for the file by name and fetches it, resuming after drops, verifying the
SHA-256 the announcement carried. Runs until SIGINT/SIGTERM. Does network and disk I/O.
"""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from pathlib import Path

from edge_vis import plugins
from edge_vis.errors import ConfigError

log = logging.getLogger(__name__)

NAME = "serve-images"
HELP = "serve a directory's image files over UDT to relays that fetch what was announced"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from edge_vis.cli.send_image import parse_rate

    parser.add_argument("--dir", required=True, type=Path, help="the images to serve")
    parser.add_argument("--listen", default="0.0.0.0:9100", metavar="HOST:PORT",
                        help="UDT address to serve on (default 0.0.0.0:9100; port 0 picks one)")
    parser.add_argument("--vehicle", default="vehicle", metavar="ID",
                        help="vehicle id written into each manifest")
    parser.add_argument("--max-rate", type=parse_rate, metavar="BPS",
                        help="most bit/s per connection (suffix k/M/G); a fetcher may ask "
                             "for less")


def run(args: argparse.Namespace) -> int:
    udt = plugins.load(plugins.BULK, "udt")
    try:
        listen = udt.parse_address(args.listen)
    except ValueError as exc:
        raise ConfigError(f"--listen: {exc}") from None
    if not args.dir.is_dir():
        raise ConfigError(f"--dir {args.dir}: not a directory")
    stop = threading.Event()

    def _signal(signum: int, _frame: object) -> None:
        log.info("signal %d: stopping", signum)
        stop.set()

    signal.signal(signal.SIGTERM, _signal)
    signal.signal(signal.SIGINT, _signal)
    server = udt.ImageServer(args.dir, listen, vehicle_id=args.vehicle,
                             max_rate_bps=args.max_rate)
    try:
        server.start()
        host, port = server.address
        print(f"serving images of {args.dir} on {host}:{port}", flush=True)
        while not stop.wait(1.0):
            pass
    finally:
        server.stop()
    return 0
