"""The engine's declaration of the JAUS messages it handles matches the engine's code."""

from __future__ import annotations

import re
from pathlib import Path

from edge_vis.catalogue import default_catalogue
from edge_vis.engine import engine as engine_module
from edge_vis.engine.handled import ENGINE_DECLINED, ENGINE_HANDLED, ENGINE_RECEIVES

ENGINE_DIR = Path(engine_module.__file__).parent
NAMES = {d.name for d in default_catalogue()}


def names_in_engine_code() -> set[str]:
    """Every catalogue message name the engine's modules spell as a string literal."""
    found: set[str] = set()
    for path in ENGINE_DIR.glob("*.py"):
        if path.name == "handled.py":
            continue
        found |= set(re.findall(r'"([A-Z][A-Za-z]+)"', path.read_text())) & NAMES
    return found


def test_every_message_the_engine_names_is_declared() -> None:
    undeclared = names_in_engine_code() - ENGINE_HANDLED
    assert not undeclared, f"declare in edge_vis/engine/handled.py: {sorted(undeclared)}"


def test_every_declared_message_is_used_by_the_engine() -> None:
    # ReportHeartbeatPulse is not named: any message from a vehicle is its sign of life
    unused = ENGINE_HANDLED - names_in_engine_code() - {"ReportHeartbeatPulse"}
    assert not unused, f"declared but never used by the engine: {sorted(unused)}"


def test_handlers_are_declared_as_received() -> None:
    from edge_vis.config import RelayProfile
    from edge_vis.engine.engine import Engine

    engine = Engine(RelayProfile(), [])
    assert set(engine._handlers) <= set(ENGINE_RECEIVES)


def test_declarations_name_real_messages_and_do_not_overlap() -> None:
    assert ENGINE_HANDLED <= NAMES and set(ENGINE_DECLINED) <= NAMES
    assert not ENGINE_HANDLED & set(ENGINE_DECLINED)
    assert all(ENGINE_DECLINED.values())
