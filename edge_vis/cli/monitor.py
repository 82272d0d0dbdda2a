"""``edge-vis monitor``: a live view of every vehicle the relay publishes on DDS.

A DDS participant only - it never speaks JAUS. On a terminal it is a curses screen
(80x24 is enough) where the operator can take control of a vehicle, drive it with the
arrow keys (``WrenchEffortCommand``), release it and send a short waypoint plan. When
stdout is not a terminal, or with ``--once``/``--interval``, it prints the same table as
plain text: once after ``--wait`` seconds, or every ``--interval`` seconds.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

from edge_vis.errors import EdgeVisError
from edge_vis.tools.contact_sheet import ContactSheet
from edge_vis.tools.monitor_view import READ_TOPICS, WRITE_TOPICS, FleetView, Operator

log = logging.getLogger(__name__)

NAME = "monitor"
HELP = "live operator view of the vehicles on DDS; take control, drive, send waypoints"

#: seconds between WrenchEffortCommand repeats while driving (the relay's dead-man is 1 s)
DRIVE_REPEAT = 0.2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--domain", type=int, default=0, help="DDS domain id (default 0)")
    parser.add_argument("--partition", action="append", default=[], metavar="NAME",
                        help="DDS partition (repeatable; default: the default partition)")
    parser.add_argument("--loopback", action="store_true",
                        help="DDS on 127.0.0.1 only (when the relay runs on this host "
                             "with a loopback configuration)")
    parser.add_argument("--operator", default=f"operator-{os.getpid()}", metavar="ID",
                        help="operator id sent with commands")
    parser.add_argument("--authority", type=int, default=100, metavar="N",
                        help="authority asked for when taking control (0..255, default 100)")
    parser.add_argument("--once", action="store_true",
                        help="print the table once after --wait seconds and exit")
    parser.add_argument("--interval", type=float, metavar="S",
                        help="print the table every S seconds (plain text)")
    parser.add_argument("--wait", type=float, default=3.0, metavar="S",
                        help="seconds to listen before the first table (default 3)")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="stop after S seconds")
    parser.add_argument("--contact-sheet", type=Path, metavar="FILE",
                        help="keep FILE an HTML page with the latest image of each vehicle "
                             "(thumbnails from ImageProduct) for a browser")
    parser.add_argument("--summary", action="store_true",
                        help="with --once/--interval: also print a JSON summary at the end")


class _Feed:
    """DDS readers for the monitored topics and writers for commands (the I/O part)."""

    def __init__(self, args: argparse.Namespace) -> None:
        from edge_vis.dds import DdsBridge, loopback_config

        config = loopback_config() if args.loopback else None
        self.bridge = DdsBridge(args.domain, args.partition, config=config)
        self.readers = {topic: self.bridge.reader(topic) for topic in READ_TOPICS}
        self.bridge.open_writers(WRITE_TOPICS)
        self.sheet_path: Path | None = args.contact_sheet
        self.sheet = ContactSheet()

    def poll(self, view: FleetView) -> int:
        now = time.monotonic()
        count = 0
        changed = False
        for topic, reader in self.readers.items():
            for sample in reader.take():
                view.ingest(topic, sample, now)
                if topic == "ImageProduct" and self.sheet_path is not None:
                    changed = self.sheet.ingest(sample) or changed
                count += 1
        if changed:
            self.write_sheet()
        return count

    def write_sheet(self) -> None:
        """Rewrite the contact sheet (atomically: a browser never reads half a page)."""
        if self.sheet_path is None:
            return
        tmp = self.sheet_path.with_name(f".{self.sheet_path.name}.tmp")
        try:
            tmp.write_text(self.sheet.render(), encoding="utf-8")
            tmp.replace(self.sheet_path)
        except OSError as exc:
            log.warning("cannot write the contact sheet %s: %s", self.sheet_path, exc)

    def publish(self, commands: list[tuple[str, dict[str, Any]]]) -> None:
        for topic, sample in commands:
            self.bridge.publish(topic, sample)

    def close(self) -> None:
        self.bridge.close()


def _listen(feed: _Feed, view: FleetView, seconds: float, stop: list[bool]) -> None:
    end = time.monotonic() + seconds
    while not stop and time.monotonic() < end:
        feed.poll(view)
        time.sleep(0.05)


def _plain(args: argparse.Namespace, feed: _Feed, view: FleetView, stop: list[bool]) -> None:
    started = time.monotonic()
    _listen(feed, view, args.wait, stop)
    while True:
        for line in view.render(time.monotonic()):
            print(line)
        sys.stdout.flush()
        if args.once or stop:
            break
        left = None if args.duration is None else started + args.duration - time.monotonic()
        if left is not None and left <= 0:
            break
        print()
        _listen(feed, view, args.interval if left is None else min(args.interval, left), stop)
    if args.summary:
        print(json.dumps(view.summary(), indent=2))


def _curses(args: argparse.Namespace, feed: _Feed, view: FleetView, stop: list[bool]) -> None:
    import curses

    operator = Operator(args.operator, args.authority)
    keys = {curses.KEY_UP: "UP", curses.KEY_DOWN: "DOWN", curses.KEY_LEFT: "LEFT",
            curses.KEY_RIGHT: "RIGHT"}
    started = time.monotonic()

    def screen(stdscr: Any) -> None:
        curses.curs_set(0)
        stdscr.nodelay(True)
        stdscr.keypad(True)
        last_drive = last_draw = 0.0
        while not stop and not operator.quit:
            now = time.monotonic()
            if args.duration is not None and now - started >= args.duration:
                break
            feed.poll(view)
            code = stdscr.getch()
            while code != -1:
                key = keys.get(code, chr(code) if 0 <= code < 256 else "")
                feed.publish(operator.key(key, view))
                last_draw = 0.0
                code = stdscr.getch()
            if operator.driving and now - last_drive >= DRIVE_REPEAT:
                feed.publish(operator.drive())
                last_drive = now
            if now - last_draw >= 0.25:
                last_draw = now
                if operator.selected is None:
                    operator.select(view, 0)
                _draw(stdscr, view, operator, args, now)
            time.sleep(0.03)
        if operator.driving:
            feed.publish(operator.stop())

    curses.wrapper(screen)


def _draw(stdscr: Any, view: FleetView, operator: Operator, args: argparse.Namespace,
          now: float) -> None:
    height, width = stdscr.getmaxyx()
    stdscr.erase()
    title = (f"edge-vis monitor  domain {args.domain}  operator {operator.operator_id} "
             f"(authority {operator.authority})")
    lines = [title, "", *view.render(now, max(width - 1, 80), operator.selected)]
    help_line = ("arrows select  c control  r release  d drive  w waypoints  e E-STOP  q quit"
                 if not operator.driving else
                 "DRIVING: up/down effort  left/right turn  space stop  e E-STOP  d end  q quit")
    import curses

    for y, line in enumerate(lines[: max(0, height - 3)]):
        loud = "EMERGENCY STOP" in line or "!E-STOP!" in line
        stdscr.addnstr(y, 0, line, width - 1,
                       curses.A_REVERSE | curses.A_BOLD if loud else curses.A_NORMAL)
    if height >= 3:
        stdscr.addnstr(height - 2, 0, operator.message, width - 1)
        stdscr.addnstr(height - 1, 0, help_line, width - 1)
    stdscr.refresh()


def run(args: argparse.Namespace) -> int:
    if not 0 <= args.authority <= 255:
        print("edge-vis monitor: --authority must be 0..255", file=sys.stderr)
        return 2
    if args.interval is not None and args.interval <= 0:
        print("edge-vis monitor: --interval must be positive", file=sys.stderr)
        return 2
    try:
        feed = _Feed(args)
    except ImportError as exc:
        print(f"edge-vis monitor: {exc}", file=sys.stderr)
        return 2
    except EdgeVisError:
        raise
    feed.write_sheet()
    stop: list[bool] = []

    def _signal(signum: int, _frame: object) -> None:
        stop.append(True)

    signal.signal(signal.SIGTERM, _signal)
    view = FleetView()
    try:
        if args.once or args.interval is not None or not sys.stdout.isatty():
            if args.interval is None:
                args.once = True
            _plain(args, feed, view, stop)
        else:
            _curses(args, feed, view, stop)
    except KeyboardInterrupt:
        pass
    finally:
        feed.close()
    return 0
