"""``edge-vis idl`` prints the shipped IDL, with or without Cyclone DDS installed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from edge_vis.cli import main
from edge_vis.cli.idl import idl_text

# Runs the CLI with ``cyclonedds`` made unimportable, as on a machine without the extra.
WITHOUT_CYCLONEDDS = """
import sys
sys.modules["cyclonedds"] = None
from edge_vis.cli import main
status = main(sys.argv[1:])
try:
    import edge_vis.dds
except ImportError as exc:
    print("IMPORT-ERROR:", exc, file=sys.stderr)
sys.exit(status)
"""


def test_idl_prints_module_edge_vis(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["idl"]) == 0
    out = capsys.readouterr().out
    assert out == idl_text()
    assert out.count("module edge_vis {") == 1
    assert "struct GlobalPose {" in out and "@key string vehicle_id;" in out


def test_idl_writes_a_file(tmp_path: Path) -> None:
    target = tmp_path / "edge_vis.idl"
    assert main(["idl", "-o", str(target)]) == 0
    assert target.read_text(encoding="utf-8") == idl_text()


def test_idl_needs_no_dds_and_the_dds_package_says_what_is_missing() -> None:
    child = subprocess.run(
        [sys.executable, "-c", WITHOUT_CYCLONEDDS, "idl"],
        capture_output=True, text=True, timeout=60,
    )
    assert child.returncode == 0, child.stderr
    assert child.stdout == idl_text()
    assert "IMPORT-ERROR: edge_vis.dds needs Cyclone DDS" in child.stderr
    assert "pip install 'edge-vis[dds]'" in child.stderr
