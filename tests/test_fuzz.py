"""Fuzz targets: stored crash inputs replayed, and a short coverage-guided run of each
(500 inputs; 4,000 with ``pytest --long``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fuzz.targets import TARGETS  # noqa: E402

DATA = ROOT / "tests" / "data" / "fuzz"
STORED = sorted(
    (target.name, path) for target in DATA.iterdir() if target.is_dir()
    for path in sorted(target.iterdir())
) if DATA.exists() else []


@pytest.mark.parametrize(("target", "path"), STORED, ids=[f"{t}/{p.name}" for t, p in STORED])
def test_stored_inputs_stay_fixed(target: str, path: Path) -> None:
    TARGETS[target](path.read_bytes())


#: inputs per target: a short run by default, the full one with ``pytest --long``
SHORT_RUNS, LONG_RUNS = 500, 4000


@pytest.mark.parametrize("target", sorted(TARGETS))
def test_short_fuzz_run_finds_nothing(target: str, tmp_path: Path, long_run: bool) -> None:
    pytest.importorskip("atheris")
    runs = LONG_RUNS if long_run else SHORT_RUNS
    result = subprocess.run(
        [sys.executable, str(ROOT / "fuzz" / "run.py"), target, f"-runs={runs}", "-seed=1",
         f"-artifact_prefix={tmp_path}/"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    crashes = list(tmp_path.glob("crash-*"))
    assert result.returncode == 0 and not crashes, result.stderr[-3000:]
    assert f"Done {runs} runs" in result.stderr
