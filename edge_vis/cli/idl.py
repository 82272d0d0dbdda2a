"""``edge-vis idl``: print the IDL of the DDS data model, for operator stations.

Reads the IDL shipped inside the package; needs no DDS installation. With ``--profile``
it prints instead the types a deployment profile adds: each typed topic of its
``[[translators.generic.mappings]]`` and ``.commands``, built from the profile's JSIDL
(module ``edge_vis::profile``), after the same checks as ``edge-vis check``.
"""

from __future__ import annotations

import argparse
import sys
from importlib import resources

NAME = "idl"
HELP = "print the IDL of the DDS data model (module edge_vis), or of a profile's typed topics"


def idl_text() -> str:
    """The shipped ``edge_vis.idl``."""
    return resources.files("edge_vis").joinpath("data", "edge_vis.idl").read_text(encoding="utf-8")


def profile_idl(path: str) -> str:
    """The IDL of the typed topics deployment profile ``path`` adds; ConfigError if the
    profile or a mapping is wrong."""
    from edge_vis.catalogue.jsidl import profile_catalogue
    from edge_vis.config import load_profile
    from edge_vis.engine.manager import TranslationManager
    from edge_vis.kit.shapes import idl_text as shapes_idl

    profile = load_profile(path)
    manager = TranslationManager.from_selection(profile.translators)
    manager.verify(profile_catalogue(profile.jsidl), path)
    decls = [(tr.name, d) for tr in manager.translators for d in tr.topic_types
             if getattr(d, "shape", None) is not None]
    doc = {d.shape.name: f"topic {d.name} ({d.kind}, translator {name})"
           for name, d in decls}
    header = (f"// Typed topics of {path}, built from its JSIDL; compile together with\n"
              "// the shipped model (edge-vis idl).\n")
    return header + shapes_idl([d.shape for _name, d in decls], doc)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``-o FILE`` writes the IDL to a file instead of standard output."""
    parser.add_argument("-o", "--output", metavar="FILE", help="write to FILE instead of stdout")
    parser.add_argument("--profile", metavar="P",
                        help="print the typed topics deployment profile P adds instead")


def run(args: argparse.Namespace) -> int:
    """Print (or write) the IDL; exit status 0 (1 when the profile is refused)."""
    from edge_vis.errors import ConfigError

    if args.profile:
        try:
            text = profile_idl(args.profile)
        except ConfigError as exc:
            print(f"edge-vis idl: {exc}", file=sys.stderr)
            return 1
    else:
        text = idl_text()
    if args.output:
        with open(args.output, "w", encoding="utf-8") as out:
            out.write(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
