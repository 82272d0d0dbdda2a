"""``python -m edge_vis`` runs the command-line interface."""

from __future__ import annotations

import sys

from edge_vis.cli import main

sys.exit(main())
