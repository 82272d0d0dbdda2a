#!/usr/bin/env bash
# Set up (if needed) and show edge-vis at work.
#
#   bash scripts/demo.sh [arguments passed on to the demo]
#
# Runs `edge-vis demo` when this version has that subcommand; otherwise decodes the first
# sample capture shipped in profiles/samples/*.hex with `edge-vis decode`.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${EDGE_VIS_VENV:-$ROOT/.venv}"

bash "$ROOT/scripts/setup.sh" || { echo "demo: set-up failed" >&2; exit 1; }
cd "$ROOT"
EDGE_VIS="$VENV/bin/edge-vis"

HELP_TEXT="$("$EDGE_VIS" --help 2>&1)" || {
    echo "demo: 'edge-vis --help' fails:" >&2; echo "$HELP_TEXT" >&2; exit 1
}
has_command() {  # subcommands are listed in --help as "    NAME   help text"
    grep -Eq "^ {4}$1( |$)" <<<"$HELP_TEXT"
}

if has_command demo; then
    exec "$EDGE_VIS" demo "$@"
fi

shopt -s nullglob
samples=("$ROOT"/profiles/samples/*.hex)
if has_command decode && ((${#samples[@]})); then
    echo "demo: edge-vis decode ${samples[0]#"$ROOT"/}" >&2
    exec "$EDGE_VIS" decode "${samples[0]}" "$@"
fi
echo "demo: nothing to show: no 'edge-vis demo' and no profiles/samples/*.hex to decode" >&2
exit 1
