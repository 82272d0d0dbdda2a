"""Refresh the generated parts of README.md: ``python tools/update_readme.py``.

The JAUS ⇄ DDS mapping table between the ``mappings`` markers is the output of
``edge-vis mappings``, so it is generated from the translators' own declarations and a
test (``tests/test_readme.py``) fails when it drifts.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- mappings:begin -->", "<!-- mappings:end -->"


def mapping_table() -> str:
    """The Markdown of ``edge-vis mappings``, headings moved down one level for the README."""
    from edge_vis.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        main(["mappings"])
    text = out.getvalue().strip()
    text = re.sub(r"^# .*\n+", "", text)  # the README section has its own heading
    return re.sub(r"^## ", "#### ", text, flags=re.MULTILINE)


def refreshed(readme: str) -> str:
    """``readme`` with the block between the markers replaced."""
    start, end = readme.index(BEGIN) + len(BEGIN), readme.index(END)
    return readme[:start] + "\n" + mapping_table() + "\n" + readme[end:]


if __name__ == "__main__":
    path = ROOT / "README.md"
    path.write_text(refreshed(path.read_text()))
    sys.stdout.write("README.md mapping table refreshed\n")
