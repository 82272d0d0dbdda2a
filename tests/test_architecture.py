"""Layering rules of the source tree, checked on the AST of every module.

The tree has four layers, told apart by their folders:

* **core** (sans-I/O: bytes, decoded messages, samples and ``now`` in, actions out):
  ``codec``, ``jaus``, ``catalogue``, ``kit``, ``engine``, ``routing``, ``bandwidth``,
  ``config``, and the leaf modules ``errors`` and ``plugins``;
* **dds**: the Cyclone DDS adapter (the data model's types, QoS, the bridge);
* **shell**: the asyncio shell (``shell``), the only place sockets and the clock meet
  the core;
* **tools**: the command line (``cli``) and the tools around the relay (``tools``: sim,
  operator view, in-process test links).

Plugins (``links``, ``translators``) live outside the package and are found through
entry points. The rules:

* the core imports no other layer, no plugin, and nothing that does I/O or reads a clock
  (asyncio, socket, threading, selectors, subprocess, signal, time, datetime);
* only ``dds`` imports ``cyclonedds``; the shell and dds never import the tools;
* the core, dds and shell never import the plugin packages by name;
* a translator imports only the kit (``edge_vis.kit``), never another translator; a
  message-set module imports only the message-definition vocabulary
  (``edge_vis.codec.types``);
* no two modules share a name across packages, except ``__init__``/``__main__`` and the
  command-line modules, which are named after their subcommands.

Every import form counts: ``import x``, ``from x import y``, and ``importlib.import_module``
/ ``__import__`` / ``importlib.util.find_spec`` called with a string literal.
"""

from __future__ import annotations

import ast
import tomllib
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "edge_vis"
PLUGIN_PACKAGES = frozenset({"links", "translators"})
DDS_PACKAGE = "cyclonedds"
DDS_HOME = PACKAGE / "dds"

CORE = frozenset({"codec", "jaus", "catalogue", "kit", "engine", "routing", "bandwidth",
                  "config", "errors", "plugins", "__init__"})
LAYER_OF = {**dict.fromkeys(CORE, "core"), "dds": "dds", "shell": "shell", "cli": "tools",
            "tools": "tools", "__main__": "tools"}
#: which layers each layer may import
MAY_IMPORT = {
    "core": {"core"},
    "dds": {"core", "dds"},
    "shell": {"core", "dds", "shell"},
    "tools": {"core", "dds", "shell", "tools"},
}
#: modules that do I/O or read a clock: not below the shell
IO_MODULES = frozenset({"asyncio", "socket", "threading", "selectors", "subprocess",
                        "signal", "time", "datetime"})
#: what translator and message-set plugins may import from edge-vis
KIT = "edge_vis.kit"
MESSAGE_VOCABULARY = "edge_vis.codec.types"

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


def layer_of_path(path: Path) -> str:
    """The layer of a file under ``edge_vis/`` (from its first folder or module name)."""
    first = path.relative_to(PACKAGE).parts[0].removesuffix(".py")
    return LAYER_OF[first]


def layer_of_module(module: str) -> str | None:
    """The layer of a dotted ``edge_vis.*`` module name, None for anything else."""
    parts = module.split(".")
    if parts[0] != "edge_vis":
        return None
    return LAYER_OF.get(parts[1], "core") if len(parts) > 1 else "core"


def violations(path: Path, source: str | None = None) -> list[str]:
    """Every broken layering rule in one file under ``edge_vis/``, as ``file:line: message``."""
    text = path.read_text(encoding="utf-8") if source is None else source
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    in_dds = path.is_relative_to(DDS_HOME)
    layer = layer_of_path(path)
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
        target = layer_of_module(module)
        if target is not None and target not in MAY_IMPORT[layer]:
            problems.append(f"{rel}:{line}: the {layer} layer imports {module!r} "
                            f"({target} layer)")
        if layer == "core" and top in IO_MODULES:
            problems.append(f"{rel}:{line}: the core imports {module!r}: I/O and clocks "
                            "belong to the shell")
    return problems


def _entry_point_modules(group: str) -> set[str]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    points = data["project"]["entry-points"].get(group, {})
    return {value.split(":", 1)[0] for value in points.values()}


def plugin_violations(path: Path, source: str | None = None,
                      message_sets: frozenset[str] = frozenset()) -> list[str]:
    """Broken rules in one translator-package module: only the kit (or, for a message
    set, the message vocabulary), never a sibling translator."""
    text = path.read_text(encoding="utf-8") if source is None else source
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    module_name = f"translators.{path.stem}"
    allowed = MESSAGE_VOCABULARY if module_name in message_sets else KIT
    problems = []
    for line, module in imported_modules(text, str(path)):
        top = top_level(module)
        if top == "translators":
            problems.append(f"{rel}:{line}: imports translator {module!r}: translators "
                            "share code through the kit only")
        elif top == "edge_vis" and not (module == allowed or module.startswith(allowed + ".")):
            problems.append(f"{rel}:{line}: imports {module!r}; a "
                            f"{'message set' if allowed != KIT else 'translator'} imports "
                            f"only {allowed}")
    return problems


def test_the_package_is_found() -> None:
    files = core_modules()
    assert PACKAGE / "__init__.py" in files
    assert PACKAGE / "plugins.py" in files
    assert len(files) > 5


def test_every_folder_of_the_package_has_a_layer() -> None:
    unknown = sorted({p.relative_to(PACKAGE).parts[0].removesuffix(".py")
                      for p in core_modules()} - set(LAYER_OF))
    assert not unknown, f"give these a layer in LAYER_OF: {unknown}"


def test_layers_import_only_downwards_and_the_core_does_no_io() -> None:
    problems = [p for path in core_modules() for p in violations(path)]
    assert not problems, "\n".join(problems)


def test_translators_import_only_the_kit() -> None:
    message_sets = frozenset(_entry_point_modules("edge_vis.messages"))
    files = sorted((ROOT / "translators").glob("*.py"))
    assert len(files) > 5
    problems = [p for path in files for p in plugin_violations(path, None, message_sets)]
    assert not problems, "\n".join(problems)


def test_no_two_modules_share_a_name() -> None:
    where: dict[str, list[str]] = defaultdict(list)
    for base in ("edge_vis", "links", "translators"):
        for path in sorted((ROOT / base).rglob("*.py")):
            rel = path.relative_to(ROOT)
            if path.stem in ("__init__", "__main__") or rel.parts[:2] == ("edge_vis", "cli"):
                continue
            if rel.parts[:3] == ("edge_vis", "jaus", "messages"):
                continue  # message definitions, named after their service sets
            where[path.stem].append(str(rel))
    shared = {name: paths for name, paths in where.items() if len(paths) > 1}
    assert not shared, shared


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
    ("where", "source"),
    [
        ("engine", "from edge_vis.shell.relay import Relay"),
        ("kit", "import edge_vis.tools.sim"),
        ("routing", "from edge_vis.dds.model import GlobalPose"),
        ("codec", "from edge_vis.cli import main"),
        ("engine", "import asyncio"),
        ("routing", "import socket"),
        ("bandwidth", "import threading"),
        ("kit", "from time import monotonic"),
        ("config", "from datetime import datetime"),
        ("dds", "from edge_vis.tools.monitor_view import View"),
        ("shell", "from edge_vis.cli.run import run"),
    ],
)
def test_checker_catches_imports_that_run_up_the_layers(where: str, source: str) -> None:
    assert violations(PACKAGE / where / "example.py", source)


@pytest.mark.parametrize(
    ("where", "source"),
    [
        ("shell", "import asyncio\nfrom edge_vis.engine import Engine"),
        ("tools", "from edge_vis.shell.relay import Runtime"),
        ("dds", "import threading\nfrom edge_vis.kit import Publish"),
        ("engine", "from edge_vis.kit import Publish\nfrom edge_vis.routing.traffic import x"),
    ],
)
def test_checker_allows_imports_down_the_layers(where: str, source: str) -> None:
    assert not violations(PACKAGE / where / "example.py", source)


@pytest.mark.parametrize(
    "source",
    [
        "from translators.generic import RuleTranslator",
        "import translators.core",
        "from edge_vis.engine.discovery import derive_vehicle_id",
        "from edge_vis.catalogue import default_catalogue",
        "from edge_vis.codec.types import u8",
    ],
)
def test_checker_keeps_translators_on_the_kit(source: str) -> None:
    assert plugin_violations(ROOT / "translators" / "example.py", source)
    assert not plugin_violations(ROOT / "translators" / "example.py",
                                 "from edge_vis.kit import ReportRule\nimport math")


def test_checker_lets_a_message_set_use_the_message_vocabulary() -> None:
    path = ROOT / "translators" / "example_messages.py"
    sets = frozenset({"translators.example_messages"})
    assert not plugin_violations(path, "from edge_vis.codec.types import u8", sets)
    assert plugin_violations(path, "from edge_vis.engine import Engine", sets)


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
