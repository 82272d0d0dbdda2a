"""``edge-vis links``: open link URLs briefly, listen, and print their health counters.

Each ``--link URL`` is opened with its plugin, listens for ``--listen`` seconds (JAUS
traffic already on the network is counted: messages, bytes, malformed frames, peers
heard), then closed. A link that cannot be opened is reported with the reason and makes
the exit status 1. This is a one-shot probe of the media from this host; it does not
query a relay that is already running (a running relay publishes the same counters on
its ``LinkStatus`` topic), and it cannot open a port that relay holds.

``--mirror-udp PORT`` / ``--mirror-pcap FILE`` copy what is heard meanwhile, e.g. to
check a serial radio with ``edge-vis decode FILE.pcap``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
from pathlib import Path

from edge_vis.errors import EdgeVisError
from edge_vis.routing.link import Link, LinkStats, create_link
from edge_vis.shell.mirror import Mirror

NAME = "links"
HELP = "open link URLs briefly and print their status and traffic counters"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("--link", action="append", default=[], metavar="URL", required=True,
                        help="link URL (repeatable), e.g. udp://0.0.0.0:3794 or "
                        "serial:///dev/ttyUSB0?baud=57600")
    parser.add_argument("--listen", type=float, default=1.0, metavar="SECONDS",
                        help="how long to listen before reporting (default 1)")
    parser.add_argument("--json", action="store_true", help="one JSON object per link")
    parser.add_argument("--mirror-udp", type=int, metavar="PORT",
                        help="copy heard datagrams to this UDP port on 127.0.0.1")
    parser.add_argument("--mirror-pcap", type=Path, metavar="FILE",
                        help="write heard datagrams to a pcap file")


async def probe(urls: list[str], listen: float, mirror: Mirror | None
                ) -> list[tuple[str, LinkStats | None, str]]:
    """Open each URL, listen, close; ``(url, stats or None, error)`` per URL."""
    results: list[tuple[str, LinkStats | None, str]] = []
    opened: list[tuple[str, Link]] = []
    for url in urls:
        try:
            link = create_link(url)
            if mirror is not None:
                mirror.attach(link)
            await link.open(lambda *_: None)
        except EdgeVisError as exc:
            results.append((url, None, str(exc)))
            continue
        opened.append((url, link))
    await asyncio.sleep(max(listen, 0.0))
    for url, link in opened:
        results.append((url, link.stats(), ""))
        await link.close()
    order = {url: i for i, url in enumerate(urls)}
    return sorted(results, key=lambda r: order[r[0]])


def _row(url: str, stats: LinkStats | None, error: str) -> str:
    if stats is None:
        return f"{url}\n  state: error: {error}"
    bandwidth = f"{stats.bandwidth_bps:.0f} bit/s" if stats.bandwidth_bps else "unlimited"
    lines = [
        url,
        f"  state: {stats.state}   mtu: {stats.mtu}   bandwidth: {bandwidth}",
        f"  in:  {stats.messages_in} messages, {stats.bytes_in} bytes;"
        f"  malformed: {stats.malformed}",
        f"  out: {stats.messages_out} messages, {stats.bytes_out} bytes;"
        f"  queued: {stats.queue_depth} bytes",
    ]
    if stats.drops:
        lines.append("  drops: " + ", ".join(f"{k} {v}" for k, v in sorted(stats.drops.items())))
    for peer, p in sorted(stats.peers.items()):
        lines.append(f"  peer {peer}: in {p.messages_in} msgs/{p.bytes_in} B, "
                     f"out {p.messages_out} msgs/{p.bytes_out} B, malformed {p.malformed}")
    if stats.last_error:
        lines.append(f"  last error: {stats.last_error}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Probe the links and print the report."""
    mirror = None
    if args.mirror_udp is not None or args.mirror_pcap is not None:
        mirror = Mirror(udp_port=args.mirror_udp, pcap=args.mirror_pcap)
    try:
        results = asyncio.run(probe(args.link, args.listen, mirror))
    finally:
        if mirror is not None:
            mirror.close()
    for url, stats, error in results:
        if args.json:
            entry: dict[str, object] = {"url": url}
            entry.update(stats.as_dict() if stats else {"state": "error", "error": error})
            print(json.dumps(entry))
        else:
            print(_row(url, stats, error))
    return 1 if any(stats is None for _, stats, _ in results) else 0
