"""``edge-vis idl``: print the IDL of the DDS data model, for operator stations.

Reads the IDL shipped inside the package; needs no DDS installation.
"""

from __future__ import annotations

import argparse
import sys
from importlib import resources

NAME = "idl"
HELP = "print the IDL of the DDS data model (module edge_vis)"


def idl_text() -> str:
    """The shipped ``edge_vis.idl``."""
    return resources.files("edge_vis").joinpath("data", "edge_vis.idl").read_text(encoding="utf-8")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``-o FILE`` writes the IDL to a file instead of standard output."""
    parser.add_argument("-o", "--output", metavar="FILE", help="write to FILE instead of stdout")


def run(args: argparse.Namespace) -> int:
    """Print (or write) the IDL; exit status 0."""
    text = idl_text()
    if args.output:
        with open(args.output, "w", encoding="utf-8") as out:
            out.write(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
