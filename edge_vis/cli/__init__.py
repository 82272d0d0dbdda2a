"""The ``edge-vis`` command line: argument parsing, exit codes and error reporting.

Subcommands are the modules of this package, one each: a module defines ``NAME`` (the
subcommand), ``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``, and is
found by listing the package, so adding a subcommand is adding a module. ``main`` maps the
:class:`~edge_vis.errors.EdgeVisError` tree to exit status 2 with a one-line message,
so a user sees the problem rather than a traceback.

A subcommand's module is imported only when it is the one asked for (or for ``--help``):
``edge-vis run`` does not carry the simulator, the monitor or the demo in its memory.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType

from edge_vis import __version__
from edge_vis.errors import EdgeVisError

#: global options that take a value (skipped when looking for the subcommand)
_VALUED = ("--log-level", "--log-format")


def _command_modules(only: str | None = None) -> list[ModuleType]:
    names = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.ispkg)
    if only is not None and only.replace("-", "_") in names:
        names = [only.replace("-", "_")]
        if only == "run":  # the relay never speaks TLS: no OpenSSL in its memory
            from edge_vis.shell.memory import import_without_openssl

            import_without_openssl()
    modules = []
    for name in names:
        try:
            modules.append(importlib.import_module(f"edge_vis.cli.{name}"))
        except ImportError as exc:  # one broken command must not take the others down
            modules.append(_unavailable(name.replace("_", "-"), exc))
    return modules


def _unavailable(name: str, exc: ImportError) -> ModuleType:
    """A stand-in command module that explains why the real one cannot load."""
    stub = ModuleType(f"edge_vis.cli.{name}")

    def run(args: argparse.Namespace) -> int:
        print(f"edge-vis {name}: unavailable: {exc}", file=sys.stderr)
        return 2

    stub.NAME = name  # type: ignore[attr-defined]
    stub.HELP = f"(unavailable: {exc})"  # type: ignore[attr-defined]
    stub.add_arguments = lambda parser: parser.add_argument(  # type: ignore[attr-defined]
        "rest", nargs=argparse.REMAINDER)
    stub.run = run  # type: ignore[attr-defined]
    return stub


def _command_of(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv``, if any (before any help option)."""
    args = iter(argv)
    for arg in args:
        if arg in ("-h", "--help", "--version"):
            return None
        if arg in _VALUED:
            next(args, None)
        elif not arg.startswith("-"):
            return arg
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: with every subcommand, or only ``command``'s when it names one."""
    parser = argparse.ArgumentParser(
        prog="edge-vis",
        description="Relay JAUS robots to a UCS-MDE-style data model over DDS.",
    )
    parser.add_argument("--version", action="version", version=f"edge-vis {__version__}")
    parser.add_argument(
        "--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        help="logging threshold (default INFO)",
    )
    parser.add_argument(
        "--log-format", default="text", choices=["text", "json"],
        help="log line format on stderr (default text)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in _command_modules(command):
        child = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(child)
        child.set_defaults(_run=module.run)
    return parser


class _JsonFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        import json
        from datetime import UTC, datetime

        entry = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(
                timespec="milliseconds"),
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
        }
        if record.exc_info:
            entry["exception"] = self.formatException(record.exc_info)
        return json.dumps(entry)


def setup_logging(level: str, fmt: str) -> None:
    """Log to stderr, one line per record, as text or JSON."""
    handler = logging.StreamHandler(sys.stderr)
    if fmt == "json":
        handler.setFormatter(_JsonFormatter())
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_of(argv))
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    setup_logging(args.log_level, args.log_format)
    try:
        return int(args._run(args))
    except EdgeVisError as exc:
        print(f"edge-vis {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
