"""Shipped profiles: every one (deployment, vehicle, sim and link profiles) passes
``edge-vis check`` as its own kind, and the packaged copies are the ones the profiles
folder shows (no second copy to drift)."""

from __future__ import annotations

from pathlib import Path

import pytest

from edge_vis.cli import main

ROOT = Path(__file__).resolve().parents[1]
DEPLOYMENTS = [ROOT / "profiles" / "default.toml", ROOT / "profiles" / "demo.toml",
               ROOT / "deploy" / "relay.toml"]
#: every TOML file shipped in profiles/ and edge_vis/data/ (some are the same file through
#: a symlink: each is checked under both names, as a user may name either)
SHIPPED = sorted({*(ROOT / "profiles").glob("*.toml"), *(ROOT / "profiles").glob("*/*.toml"),
                  *(ROOT / "profiles" / "examples").glob("*/*.toml"),
                  *(ROOT / "edge_vis" / "data").glob("*.toml"),
                  *(ROOT / "edge_vis" / "data").glob("*/*.toml"), ROOT / "deploy" / "relay.toml"})
KIND_BY_FOLDER = {"sim": "sim", "vehicles": "vehicle", "links": "link"}


def test_every_shipped_profile_is_found() -> None:
    folders = {p.parent.name for p in SHIPPED}
    assert {"profiles", "data", "deploy", "sim", "vehicles", "links"} <= folders
    assert len(SHIPPED) >= 18


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_profile_checks_ok(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    kind = KIND_BY_FOLDER.get(path.parent.name, "deployment")
    if path.parent.parent.name == "examples":  # an example's folder holds every kind
        text = path.read_text()
        kind = "deployment" if "[relay]" in text else "sim" if 'kind = "custom"' in text \
            else "vehicle"
    assert capsys.readouterr().out.startswith(f"OK {path}: {kind} profile: ")


@pytest.mark.parametrize("path", DEPLOYMENTS, ids=lambda p: p.name)
def test_deployment_profiles_check(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.startswith("OK")


def test_profiles_folder_shows_the_packaged_files() -> None:
    assert (ROOT / "profiles" / "default.toml").resolve() == \
        (ROOT / "edge_vis" / "data" / "default.toml").resolve()
    assert (ROOT / "profiles" / "links").resolve() == \
        (ROOT / "edge_vis" / "data" / "links").resolve()
