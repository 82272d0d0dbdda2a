"""Shipped profiles: every one passes ``edge-vis check``, and the packaged copies are the
ones the profiles folder shows (no second copy to drift)."""

from __future__ import annotations

from pathlib import Path

import pytest

from edge_vis.cli import main

ROOT = Path(__file__).resolve().parents[1]
DEPLOYMENTS = [ROOT / "profiles" / "default.toml", ROOT / "profiles" / "demo.toml",
               ROOT / "deploy" / "relay.toml"]


@pytest.mark.parametrize("path", DEPLOYMENTS, ids=lambda p: p.name)
def test_deployment_profiles_check(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.startswith("OK")


def test_profiles_folder_shows_the_packaged_files() -> None:
    assert (ROOT / "profiles" / "default.toml").resolve() == \
        (ROOT / "edge_vis" / "data" / "default.toml").resolve()
    assert (ROOT / "profiles" / "links").resolve() == \
        (ROOT / "edge_vis" / "data" / "links").resolve()
