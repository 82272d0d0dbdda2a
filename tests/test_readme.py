"""The README's generated mapping table matches what the translators declare."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import update_readme  # noqa: E402


def test_mapping_table_is_current() -> None:
    readme = (ROOT / "README.md").read_text()
    assert readme == update_readme.refreshed(readme), (
        "README.md's mapping table is stale: run .venv/bin/python tools/update_readme.py"
    )
