"""edge-vis: a vehicle interface service between JAUS robots and a DDS data model.

The ``edge_vis`` package is the core: the sans-I/O JAUS codec and catalogue, the router,
the engine and the thin I/O shell. Link layers (``links``) and translators
(``translators``) are plugins found through entry points; the core never imports them
by name.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
