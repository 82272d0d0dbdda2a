#!/usr/bin/env bash
# Set up (if needed), lint and run the whole test suite; exit non-zero on any failure.
#
#   bash scripts/test.sh [extra pytest arguments]
#
# Runs scripts/setup.sh, then `ruff check .`, `mypy` (the core packages, as configured in
# pyproject.toml) and `pytest -q tests/`. All always run so one report shows every problem. A pytest run that collects no test (exit 5) is a
# failure. $EDGE_VIS_TEST_TIMEOUT (seconds, default 1800) bounds the pytest run so a hung
# test fails instead of blocking CI.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${EDGE_VIS_VENV:-$ROOT/.venv}"
VPY="$VENV/bin/python"
TIMEOUT="${EDGE_VIS_TEST_TIMEOUT:-1800}"

bash "$ROOT/scripts/setup.sh" || { echo "test: set-up failed; nothing was tested" >&2; exit 1; }
cd "$ROOT" || exit 1

status=0
echo "test: ruff check ." >&2
if ! "$VPY" -m ruff check --quiet .; then
    echo "test: FAILED: ruff found problems (above)" >&2
    status=1
fi

echo "test: mypy (core packages)" >&2
if ! "$VPY" -m mypy; then
    echo "test: FAILED: mypy found problems (above)" >&2
    status=1
fi

echo "test: pytest -q tests/" >&2
timeout --foreground -k 30 "$TIMEOUT" "$VPY" -m pytest -q tests/ "$@"
rc=$?
case "$rc" in
    0) ;;
    5) echo "test: FAILED: pytest collected no tests" >&2; status=1 ;;
    124|137) echo "test: FAILED: pytest still running after ${TIMEOUT}s; stopped" >&2; status=1 ;;
    *) echo "test: FAILED: pytest exit status $rc" >&2; status=1 ;;
esac
exit "$status"
