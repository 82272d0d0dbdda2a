"""What differs between the Cyclone DDS Python bindings edge-vis runs on. No I/O.

edge-vis runs on the PyPI wheel (cyclonedds 11.x, no DDS Security) and on the 0.10.2
binding built against Debian's Cyclone DDS (with DDS Security; ``scripts/setup.sh
--secure``). The 0.10.2 binding has no ``get_matched_publications`` /
``get_matched_subscriptions``: it reports matches only to listeners, so there a
:class:`MatchListener` on each writer and command reader keeps the same facts.
``types.byte`` is 11.x only; 0.10.2 octets are ``uint8`` (:mod:`edge_vis.dds.convert`).
"""

from __future__ import annotations

import threading
from typing import Any

from cyclonedds.core import Listener
from cyclonedds.pub import DataWriter

#: the binding has get_matched_publications/subscriptions (11.x)
HAS_MATCHED_API = hasattr(DataWriter, "get_matched_subscriptions")


def unsigned_handle(value: int) -> int:
    """An instance handle as the unsigned 64-bit number it is: the 11.x binding gives a
    sample's ``publication_handle`` unsigned but ``get_matched_publications()`` signed."""
    return value & 0xFFFF_FFFF_FFFF_FFFF


class MatchListener(Listener):  # type: ignore[misc]
    """Matched remote endpoints of one writer or reader, from match callbacks (called in
    Cyclone's threads)."""

    def __init__(self) -> None:
        super().__init__()
        self._lock = threading.Lock()
        self.subscriptions = 0
        self._publications: set[int] = set()

    def on_publication_matched(self, writer: Any, status: Any) -> None:
        self.subscriptions = int(status.current_count)

    def on_subscription_matched(self, reader: Any, status: Any) -> None:
        handle = unsigned_handle(int(status.last_publication_handle))
        with self._lock:
            if status.current_count_change > 0:
                self._publications.add(handle)
            elif status.current_count_change < 0:
                self._publications.discard(handle)

    def publications(self) -> set[int]:
        with self._lock:
            return set(self._publications)


def matched_subscriptions(writer: Any, listener: MatchListener | None) -> int:
    """How many readers match ``writer``."""
    if HAS_MATCHED_API:
        return len(writer.get_matched_subscriptions())
    return listener.subscriptions if listener is not None else 0


def matched_publications(reader: Any, listener: MatchListener | None) -> set[int]:
    """The (unsigned) handles of the writers ``reader`` matches."""
    if HAS_MATCHED_API:
        return {unsigned_handle(h) for h in reader.get_matched_publications()}
    return listener.publications() if listener is not None else set()


def match_listener() -> MatchListener | None:
    """A listener to give a new writer/reader when the binding needs one, else None."""
    return None if HAS_MATCHED_API else MatchListener()


__all__ = ["HAS_MATCHED_API", "MatchListener", "match_listener", "matched_publications",
           "matched_subscriptions", "unsigned_handle"]
