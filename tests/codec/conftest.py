"""Shared fixtures of the codec tests: the ``tests`` folder on ``sys.path`` for ``strategies``."""

from __future__ import annotations

import sys
from pathlib import Path

TESTS = str(Path(__file__).resolve().parents[1])
if TESTS not in sys.path:  # tests/strategies.py lives beside the test folders
    sys.path.insert(0, TESTS)
