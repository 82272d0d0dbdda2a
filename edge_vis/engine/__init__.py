"""The sans-I/O relay engine: discovery, per-vehicle state and translation. No I/O.

``Engine`` (in :mod:`edge_vis.engine.engine`) is the top object, a thin facade over parts
that share one :class:`~edge_vis.engine.state.EngineState`: ``finder`` (finding vehicles
and their service trees), ``liveness`` (lost and found), ``access`` (JAUS access control
and management of commanded components), ``reports`` (events with polling fallback),
``commands`` (admission and sending), ``control_requests`` (operators), ``rates`` (the
bandwidth plan), ``timer_pass`` (deadlines and shutdown) and ``views`` (what
translators and status displays see). The JAUS state machines they run are ``control``
(one component's access control) and ``subscriptions`` (one report's event); beside them
are ``discovery`` (parsing discovery reports), ``vehicle``, ``command_slots`` (throttling
and dead-man), ``arbitration`` (operators) and ``manager`` (translators). What the engine
asks the shell to do are the actions of :mod:`edge_vis.kit.actions`.
"""

from __future__ import annotations

from edge_vis.engine.engine import Engine
from edge_vis.engine.manager import TranslationManager

__all__ = ["Engine", "TranslationManager"]
