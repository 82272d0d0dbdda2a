"""Layering rules of the source tree, checked on the AST of every module in ``edge_vis/``.

* The core never imports the plugin packages ``links`` or ``translators``: they are found
  through entry points, so a user can replace or add one without touching the core.
* Only ``edge_vis/dds/`` imports ``cyclonedds``: the rest of the core stays importable and
  testable on a machine without DDS.

Every import form counts: ``import x``, ``from x import y``, and ``importlib.import_module``
/ ``__import__`` / ``importlib.util.find_spec`` called with a string literal.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "edge_vis"
PLUGIN_PACKAGES = frozenset({"links", "translators"})
DDS_PACKAGE = "cyclonedds"
DDS_HOME = PACKAGE / "dds"

_IMPORT_CALLS = frozenset({"import_module", "__import__", "find_spec"})


def imported_modules(source: str, filename: str = "<source>") -> list[tuple[int, str]]:
    """``(line, dotted module name)`` for every absolute import in ``source``."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0 and node.module:
                found.append((node.lineno, node.module))
        elif isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name in _IMPORT_CALLS and node.args:
                arg = node.args[0]
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    found.append((node.lineno, arg.value))
    return found


def top_level(module: str) -> str:
    return module.split(".", 1)[0]


def core_modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def violations(path: Path, source: str | None = None) -> list[str]:
    """Every broken layering rule in one file, as ``file:line: message``."""
    text = path.read_text(encoding="utf-8") if source is None else source
    rel = path.relative_to(PACKAGE.parent) if path.is_relative_to(PACKAGE.parent) else path
    in_dds = path.is_relative_to(DDS_HOME)
    problems = []
    for line, module in imported_modules(text, str(path)):
        top = top_level(module)
        if top in PLUGIN_PACKAGES:
            problems.append(
                f"{rel}:{line}: imports plugin package {module!r}; load it through "
                "edge_vis.plugins instead"
            )
        if top == DDS_PACKAGE and not in_dds:
            problems.append(f"{rel}:{line}: imports {module!r} outside edge_vis/dds/")
    return problems


def test_the_package_is_found() -> None:
    files = core_modules()
    assert PACKAGE / "__init__.py" in files
    assert PACKAGE / "plugins.py" in files
    assert len(files) > 5


def test_core_never_imports_plugins_and_only_dds_imports_cyclonedds() -> None:
    problems = [p for path in core_modules() for p in violations(path)]
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize(
    "source",
    [
        "import links",
        "import links.udp as udp",
        "import os, translators.ugv",
        "from links import udp",
        "from translators.ugv import Translator",
        "import importlib\nimportlib.import_module('links.udp')",
        "from importlib import import_module\nimport_module('translators')",
        "__import__('links.serial')",
        "import importlib.util\nimportlib.util.find_spec('translators.x')",
        "def f():\n    import links.udt\n",
        "try:\n    from links import udt\nexcept ImportError:\n    pass\n",
    ],
)
def test_checker_catches_every_plugin_import_form(source: str) -> None:
    assert violations(PACKAGE / "engine" / "example.py", source)


@pytest.mark.parametrize(
    "source",
    [
        "import cyclonedds",
        "from cyclonedds.domain import DomainParticipant",
        "import importlib\nimportlib.import_module('cyclonedds.idl')",
    ],
)
def test_checker_confines_cyclonedds_to_the_dds_package(source: str) -> None:
    assert violations(PACKAGE / "engine" / "example.py", source)
    assert not violations(DDS_HOME / "bridge.py", source)


@pytest.mark.parametrize(
    "source",
    [
        "from . import links",  # a relative module of the core that happens to be named so
        "from .links import Link",
        "import linksys",
        "from edge_vis import plugins\nplugins.load('edge_vis.links', 'udp')",
        "name = 'links.udp'",
    ],
)
def test_checker_allows_lookalikes(source: str) -> None:
    assert not violations(PACKAGE / "engine" / "example.py", source)
