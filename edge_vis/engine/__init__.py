"""The sans-I/O relay engine: discovery, per-vehicle state and translation. No I/O.

``Engine`` (in :mod:`edge_vis.engine.engine`) is the top object; the modules beside it
hold one concern each: ``discovery``, ``vehicle``, ``control`` (JAUS access control),
``subscriptions`` (JAUS events), ``command_slots`` (throttling and dead-man),
``arbitration`` (operators) and ``manager`` (translators). What the engine asks the shell
to do are the actions of :mod:`edge_vis.kit.actions`.
"""

from __future__ import annotations

from edge_vis.engine.engine import Engine
from edge_vis.engine.manager import TranslationManager

__all__ = ["Engine", "TranslationManager"]
