"""Simulated JAUS vehicles for demos and tests.

Each simulated vehicle is a whole JAUS subsystem (its own subsystem id, nodes and
components) that behaves like a real robot on the wire, awkward parts included: control
that times out, events that expire, messages it does not support, faults injected from
its profile. The protocol logic (:mod:`edge_vis.tools.sim.subsystem`) is sans-I/O and driven by
an explicit ``now``; :mod:`edge_vis.tools.sim.runner` is the thin asyncio adapter that owns
the sockets and pseudo-terminals.
"""

from __future__ import annotations
