"""Fixtures shared by every test folder: real Cyclone DDS participants on loopback, and
the root logger put back after every test.

Cyclone is configured for loopback only (``edge_vis.dds.loopback_config``: interface
127.0.0.1, no multicast, unicast discovery to 127.0.0.1) through ``CYCLONEDDS_URI``, set
for the whole session so child processes inherit it. Every test gets its own DDS domain id
and a partition of its own, so concurrent test runs on the same host never see each
other's samples.

Loopback addresses. Tests that run JAUS nodes bind fixed loopback addresses on port 3794,
and ``scripts/test.sh`` runs its parts side by side (each in a network namespace of its
own when it runs as root, all on one loopback otherwise), so each file keeps addresses of
its own. A new test takes addresses outside these:

* part A: ``tests/faults`` 127.0.0.150-189 and 127.44.*;
* part B: ``tests/e2e`` 127.0.0.31-34, 41-54, 61-64, 81-83, 87-95, 101-104, 111-112,
  141-147, 171-174, 221-224, 231-243, 245-246, 251-252 and 127.0.19.*; ``tests/sim``
  127.0.0.71-74 and 88-89; ``tests/links`` 127.0.0.2-4 (on free ports);
* the rest: ``tests/test_limits.py`` 127.0.0.190-191, ``tests/test_security.py``
  198-199, ``tests/test_demo.py`` 75-76 (and the demo's own claimed slots);
* the DDS Security pass, beside parts A and B: ``tests/dds/test_dds_security.py``
  127.0.0.206-207, besides files of part B and the rest.
"""

from __future__ import annotations

import itertools
import logging
import os
import uuid
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from edge_vis.dds import DdsBridge


# Domain ids 0..232 are valid; start at a pid-dependent point to spread concurrent runs.
_DOMAIN_IDS = itertools.count(0)
_DOMAIN_BASE = 20 + os.getpid() % 150


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--long", action="store_true", default=False,
        help="the long runs too: tests marked 'long', and the full size of tests that have "
             "a short one (the fuzz runs: 4,000 inputs, not 500); README 'Long runs'",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--long"):
        return
    later = pytest.mark.skip(reason="long run: add --long to run it (README 'Long runs')")
    for item in items:
        if "long" in item.keywords:
            item.add_marker(later)


@pytest.fixture(scope="session")
def long_run(request: pytest.FixtureRequest) -> bool:
    """True under ``--long``: tests with a short and a full size pick the full one."""
    return bool(request.config.getoption("--long"))


@pytest.fixture(scope="session", autouse=True)
def loopback_cyclone() -> Iterator[str]:
    """Point Cyclone DDS at the loopback interface for the whole session."""
    try:
        from edge_vis.dds import loopback_config
    except ImportError:  # no Cyclone DDS: nothing to configure
        yield ""
        return
    config = loopback_config()
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CYCLONEDDS_URI", config)
        yield config


@pytest.fixture(autouse=True)
def restore_root_logger() -> Iterator[None]:
    """Undo ``edge-vis`` CLI runs' logging set-up: their handler writes to the test's
    captured stderr, which is closed once the test ends, so a background thread of a later
    test (a UDT connection ending, say) would log into a closed file."""
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)


@pytest.fixture
def domain_id() -> int:
    """A DDS domain id no other test of this session uses."""
    return _DOMAIN_BASE + next(_DOMAIN_IDS) % 60


@pytest.fixture
def partition() -> str:
    """A DDS partition unique to this test."""
    return f"edge-vis-test-{uuid.uuid4().hex[:12]}"


@pytest.fixture
def make_bridge(domain_id: int, partition: str) -> Iterator[Callable[..., DdsBridge]]:
    """Factory of bridges on this test's domain and partition, closed at teardown."""
    from edge_vis.dds import DdsBridge

    bridges: list[DdsBridge] = []

    def make(**kwargs: Any) -> DdsBridge:
        kwargs.setdefault("domain_id", domain_id)
        kwargs.setdefault("partitions", (partition,))
        bridge = DdsBridge(**kwargs)
        bridges.append(bridge)
        return bridge

    yield make
    for bridge in bridges:
        bridge.close()
