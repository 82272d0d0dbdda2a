"""The sans-I/O relay engine: discovery, per-vehicle state and translation. No I/O.

``Engine`` (in :mod:`edge_vis.engine.engine`) is the top object; the modules beside it
hold one concern each: ``actions`` (what the engine asks the runtime to do),
``discovery``, ``vehicle``, ``control``, ``subscriptions`` (JAUS events), ``commands``
(throttling and dead-man), ``arbitration`` (operators) and ``manager`` (translators).
"""

from __future__ import annotations

from typing import Any

from edge_vis.engine.actions import (
    Action,
    Command,
    DeclareVehicle,
    Publish,
    SendMessage,
    ShutdownComplete,
)

__all__ = [
    "Action", "Command", "DeclareVehicle", "Engine", "Publish", "SendMessage",
    "ShutdownComplete", "TranslationManager",
]


def __getattr__(name: str) -> Any:
    # imported lazily: edge_vis.translator imports the actions from this package
    if name == "Engine":
        from edge_vis.engine.engine import Engine

        return Engine
    if name == "TranslationManager":
        from edge_vis.engine.manager import TranslationManager

        return TranslationManager
    raise AttributeError(name)
