"""The one-file bundle: built by deploy/build-bundle.sh, run from a directory holding
nothing else, with a fresh environment (no PYTHONPATH, no virtual environment, cwd
elsewhere), as on a relay computer that only has Python (and libudt)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from deploykit import REPO

pytestmark = pytest.mark.slow

#: wheels are kept here between test runs, so a rebuild takes seconds
WHEELHOUSE = Path(tempfile.gettempdir()) / f"edge-vis-wheelhouse-{os.getuid()}"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("bash") is None:
        pytest.skip("bash is needed to build the bundle")
    out = tmp_path_factory.mktemp("dist") / "edge-vis.pyz"
    env = dict(os.environ, PYTHON=sys.executable, EDGE_VIS_WHEELHOUSE=str(WHEELHOUSE),
               EDGE_VIS_BUNDLE=str(out))
    done = subprocess.run(["bash", str(REPO / "deploy" / "build-bundle.sh")], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert out.is_file() and os.access(out, os.X_OK)
    return out


@pytest.fixture
def relay_box(bundle: Path, tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """A bare directory with the bundle and a PATH whose ``python3`` is a plain interpreter."""
    box = tmp_path / "relay"
    box.mkdir()
    shutil.copy2(bundle, box / "edge-vis.pyz")
    shutil.copy2(REPO / "deploy" / "relay.toml", box / "relay.toml")
    bindir = tmp_path / "bin"
    bindir.mkdir()
    # the interpreter behind the virtual environment: none of its packages are visible
    base = getattr(sys, "_base_executable", sys.executable)
    (bindir / "python3").symlink_to(os.path.realpath(base))
    env = {"PATH": f"{bindir}:/usr/bin:/bin", "HOME": str(tmp_path / "home"),
           "LANG": "C.UTF-8"}
    return box, env


def _run(box: Path, env: dict[str, str], *args: str, cwd: Path | None = None,
         timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(box / "edge-vis.pyz"), *args], env=env, cwd=cwd or box.parent,
                          capture_output=True, text=True, timeout=timeout)


def test_bundle_checks_and_runs_from_a_bare_directory(
    relay_box: tuple[Path, dict[str, str]], tmp_path: Path
) -> None:
    box, env = relay_box
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()

    checked = _run(box, env, "check", str(box / "relay.toml"), cwd=elsewhere)
    assert checked.returncode == 0, checked.stderr
    assert "OK" in checked.stdout and "2 link(s)" in checked.stdout

    # the built-in default profile travels inside the bundle
    default = _run(box, env, "check", cwd=elsewhere)
    assert default.returncode == 0, default.stderr
    assert f"{tmp_path / 'home'}/.shiv/" in default.stdout  # the extracted bundle, not the repo

    plugins = _run(box, env, "plugins", "--check", cwd=elsewhere)
    assert plugins.returncode == 0, plugins.stdout + plugins.stderr
    for name in ("udp", "serial", "core", "mobility"):
        assert name in plugins.stdout

    ran = _run(box, env, "--log-format", "json", "run", "--no-dds", "--duration", "2",
               "--link", "udp://127.0.61.21:0?multicast=off", cwd=elsewhere)
    assert ran.returncode == 0, ran.stderr
    assert '"message": "stopped"' in ran.stderr


def test_bundle_demo_says_it_needs_a_checkout(relay_box: tuple[Path, dict[str, str]]) -> None:
    box, env = relay_box
    done = _run(box, env, "demo", "--duration", "1")
    assert done.returncode == 2
    assert "source checkout" in done.stderr and "bash scripts/demo.sh" in done.stderr
    assert ".shiv" not in done.stderr  # no path from inside the unpacked bundle


def test_bundle_carries_the_binary_dependencies(
    relay_box: tuple[Path, dict[str, str]]
) -> None:
    box, env = relay_box
    wanted = ["cyclonedds.core", "serial"]
    try:
        import udt4py  # noqa: F401 - only to know whether the build included it
    except ImportError:
        pass
    else:
        wanted.append("udt4py")
    code = ("import importlib, sys\n"
            f"for name in {wanted!r}:\n"
            "    module = importlib.import_module(name)\n"
            "    assert '.shiv' in module.__file__, module.__file__\n")
    if "udt4py" in wanted:  # and the lanes' congestion control built beside its loader
        code += ("from links.udt import udt_cc\n"
                 "assert udt_cc.available(), udt_cc.library_path()\n"
                 "assert '.shiv' in str(udt_cc.library_path()), udt_cc.library_path()\n")
    code += "print('imported', *sys.argv[1:])"
    done = _run(box, dict(env, SHIV_INTERPRETER="1"), "-c", code, "ok")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "imported ok"


@pytest.mark.dds
def test_bundle_joins_dds(relay_box: tuple[Path, dict[str, str]]) -> None:
    box, env = relay_box
    from edge_vis.dds import loopback_config

    env = dict(env, CYCLONEDDS_URI=loopback_config())
    ran = _run(box, env, "run", "--duration", "1", "--domain", str(150 + os.getpid() % 80),
               "--link", "udp://127.0.61.22:0?multicast=off")
    assert ran.returncode == 0, ran.stderr
    assert "publishing" in ran.stderr and "stopped" in ran.stderr


def test_bundle_has_dds_security_exactly_when_its_build_environment_does(
    relay_box: tuple[Path, dict[str, str]]
) -> None:
    """Built from .venv-secure the bundle carries the binding built against Debian's Cyclone
    DDS (loaded from the relay's system), never the PyPI wheel of the same version."""
    box, env = relay_box
    secure_qos = pytest.importorskip("edge_vis.dds.secure_qos")
    code = ("import cyclonedds.core\n"
            "from edge_vis.dds.secure_qos import security_available\n"
            "assert '.shiv' in cyclonedds.core.__file__, cyclonedds.core.__file__\n"
            "print('security', security_available())")
    done = _run(box, dict(env, SHIV_INTERPRETER="1"), "-c", code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"security {secure_qos.security_available()}"
