#!/usr/bin/env bash
# Set up (if needed) and run the demo: simulated JAUS vehicles, the relay and the live
# operator view, all on this computer.
#
#   bash scripts/demo.sh [arguments passed on to `edge-vis demo`, e.g. --duration 20]
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${EDGE_VIS_VENV:-$ROOT/.venv}"

bash "$ROOT/scripts/setup.sh" || { echo "demo: set-up failed" >&2; exit 1; }
cd "$ROOT"
exec "$VENV/bin/edge-vis" demo "$@"
