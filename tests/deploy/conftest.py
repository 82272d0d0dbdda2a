"""Fixtures for the deployment tests."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator

import pytest
from deploykit import NotifyListener


@pytest.fixture
def notify_socket() -> Iterator[NotifyListener]:
    # a short directory: AF_UNIX paths are limited to 107 bytes
    with tempfile.TemporaryDirectory(prefix="ev-notify-") as tmp:
        listener = NotifyListener(os.path.join(tmp, "notify"))
        yield listener
        listener.close()
