"""Subcommands of the ``edge-vis`` command line, one module each.

Each module defines ``NAME`` (the subcommand), ``HELP`` (one line), and the functions
``add_arguments(parser: argparse.ArgumentParser) -> None`` and
``run(args: argparse.Namespace) -> int``. :mod:`edge_vis.cli` finds them by listing this
package, so adding a subcommand is adding a module.
"""
