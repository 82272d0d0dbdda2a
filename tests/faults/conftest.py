"""Fixtures of the fault matrix and the table of results printed after the run.

Each cell records what it checked and how long recovery took through the ``fault_record``
fixture; ``pytest_terminal_summary`` prints one line per cell (also for a failed cell,
with what it was waiting for). Cyclone DDS runs on loopback only, with a domain and
partition per test: those fixtures are the shared ones in ``tests/conftest.py``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest

try:
    import cyclonedds  # noqa: F401
except ImportError:  # Cyclone DDS is not installed: nothing here can run
    collect_ignore_glob = ["test_*.py"]


@dataclass
class FaultResult:
    """One cell of the matrix."""

    medium: str
    fault: str
    outcome: str = "FAILED"
    recovery_s: float | None = None
    checks: list[str] = field(default_factory=list)
    note: str = ""


_RESULTS: list[FaultResult] = []


@pytest.fixture
def fault_record(request: pytest.FixtureRequest) -> Iterator[FaultResult]:
    """The result row of this cell; marked passed when the test body succeeds."""
    callspec = getattr(request.node, "callspec", None)
    medium = callspec.params.get("medium", "udp") if callspec else "udp"
    result = FaultResult(medium, request.node.originalname.removeprefix("test_"))
    _RESULTS.append(result)
    yield result


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]):  # type: ignore
    report = yield
    if call.when == "call" and "fault_record" in getattr(item, "funcargs", {}):
        result: FaultResult = item.funcargs["fault_record"]  # type: ignore[attr-defined]
        if report.passed:
            result.outcome = "ok"
        elif call.excinfo is not None:
            result.note = str(call.excinfo.value).splitlines()[0][:70]
    return report


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:  # type: ignore
    if not _RESULTS:
        return
    write = terminalreporter.write_line
    terminalreporter.section("fault matrix")
    write(f"{'medium':<7}{'fault':<40}{'result':<8}{'recovery':>9}  checked")
    for r in _RESULTS:
        took = f"{r.recovery_s:7.2f} s" if r.recovery_s is not None else "      -  "
        write(f"{r.medium:<7}{r.fault:<40}{r.outcome:<8}{took:>9}  "
              f"{', '.join(r.checks)}{'; ' + r.note if r.note else ''}")
