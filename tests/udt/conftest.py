"""Fixtures of the UDT bulk-transfer tests (helpers live in ``udt_helpers.py``)."""

from __future__ import annotations

import random
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

TESTS = str(Path(__file__).resolve().parents[1])
if TESTS not in sys.path:  # tests/lossy_proxy.py lives beside the test folders
    sys.path.insert(0, TESTS)
HERE = str(Path(__file__).resolve().parent)
if HERE not in sys.path:  # udt_helpers.py
    sys.path.insert(0, HERE)


@pytest.fixture
def make_file(tmp_path: Path) -> Callable[..., tuple[Path, bytes]]:
    """``make_file(size, name="img.png")`` → (path, content) with seeded random bytes."""

    def make(size: int, name: str = "img.png", seed: int = 7) -> tuple[Path, bytes]:
        content = random.Random(seed).randbytes(size)
        folder = tmp_path / "vehicle"
        folder.mkdir(exist_ok=True)
        path = folder / name
        path.write_bytes(content)
        return path, content

    return make
