"""Run one fuzz target under atheris: ``python fuzz/run.py TARGET [libFuzzer options]``.

Examples::

    .venv/bin/python fuzz/run.py judp -runs=200000
    .venv/bin/python fuzz/run.py message -max_total_time=600 fuzz/corpus/message

A crash writes ``crash-<hash>`` in the current directory; keep it under
``tests/data/fuzz/<target>/`` so the test suite replays it from then on.
"""

from __future__ import annotations

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

with atheris.instrument_imports(include=["edge_vis", "links"]):
    import links.udt.protocol  # noqa: F401 - imported here so that it is instrumented
    from fuzz.targets import TARGETS


def main() -> None:
    """Pick the target named by the first argument and fuzz it."""
    if len(sys.argv) < 2 or sys.argv[1] not in TARGETS:
        sys.stderr.write(f"usage: run.py TARGET [options]; targets: {', '.join(TARGETS)}\n")
        raise SystemExit(2)
    target = TARGETS[sys.argv[1]]
    atheris.Setup([sys.argv[0], *sys.argv[2:]], target)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
