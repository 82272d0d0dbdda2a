"""Engine test harness: a fake clock, messages that really go through the catalogue.

Every message given to the engine is encoded and decoded by the catalogue first, and
every SendMessage the engine emits is encoded too, so a wrong field name fails a test.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from edge_vis.config import RelayProfile, from_mapping
from edge_vis.engine.engine import Engine
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Publish, SendMessage

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"


def make_catalogue() -> Any:
    from edge_vis.catalogue import default_catalogue

    return default_catalogue()


@pytest.fixture(scope="session")
def catalogue() -> Any:
    return make_catalogue()


def profile(**sections: Any) -> RelayProfile:
    data: dict[str, Any] = {"relay": {"jaus_id": "42.1.1", "authority": 100}}
    data.update(sections)
    return from_mapping(data, file="test.toml")


class Harness:
    """An engine, a clock and helpers to talk to it as a vehicle would."""

    def __init__(self, catalogue: Any, prof: RelayProfile | None = None,
                 translators: Iterable[Any] | None = None) -> None:
        from translators.core import CoreTranslator
        from translators.mobility import MobilityTranslator

        self.catalogue = catalogue
        trs = list(translators) if translators is not None else [
            CoreTranslator(), MobilityTranslator()]
        self.engine = Engine(prof or profile(), trs, catalogue=catalogue)
        self.now = 0.0
        self.log: list[Any] = []

    # -- driving -------------------------------------------------------------------------

    def deliver(self, source: str | JausAddress, name: str, fields: Mapping[str, Any] | None = None
                ) -> list[Any]:
        """Encode, decode and hand a message to the engine; return the new actions."""
        src = JausAddress.parse(source) if isinstance(source, str) else source
        message = self.catalogue.decode(self.catalogue.encode(name, dict(fields or {})))
        self.engine.receive_message(src, message, self.now)
        return self.drain()

    def deliver_payload(self, source: str, payload: bytes) -> list[Any]:
        self.engine.receive_message(JausAddress.parse(source), self.catalogue.decode(payload),
                                    self.now)
        return self.drain()

    def sample(self, topic: str, sample: Mapping[str, Any]) -> list[Any]:
        self.engine.receive_sample(topic, dict(sample), self.now)
        return self.drain()

    def advance(self, seconds: float, step: float | None = None) -> list[Any]:
        """Move the clock, firing the timer at every deadline on the way."""
        end = self.now + seconds
        out: list[Any] = []
        for _ in range(100_000):
            deadline = self.engine.next_deadline()
            if deadline is None or deadline > end:
                break
            self.now = max(self.now, deadline)
            self.engine.on_timer(self.now)
            out.extend(self.drain())
        self.now = end
        self.engine.on_timer(self.now)
        out.extend(self.drain())
        return out

    def drain(self) -> list[Any]:
        actions = self.engine.drain_actions()
        for action in actions:
            if isinstance(action, SendMessage):  # must be encodable as emitted
                name: str | int = action.name
                if action.service_set is not None:  # a name two message sets use
                    name = self.catalogue.by_name(action.name, action.service_set).code
                dialects = self.engine.dialects_of(action.destination)
                if dialects:  # as the relay does: in the layout the vehicle speaks
                    self.catalogue.encode(name, dict(action.fields), dialects)
                else:
                    self.catalogue.encode(name, dict(action.fields))
        self.log.extend(actions)
        return actions


def wire(catalogue: Any, out: Sequence[Any]) -> list[tuple[str, dict[str, Any]]]:
    """(name, fields) of each message a state machine emitted, each proven encodable by
    the catalogue."""
    for item in out:
        catalogue.encode(item.name, dict(item.fields))
    return [(item.name, dict(item.fields)) for item in out]


def sent(actions: Iterable[Any], name: str | None = None,
         to: str | None = None) -> list[SendMessage]:
    dest = JausAddress.parse(to) if to else None
    return [a for a in actions if isinstance(a, SendMessage)
            and (name is None or a.name == name) and (dest is None or a.destination == dest)]


def published(actions: Iterable[Any], topic: str | None = None) -> list[Mapping[str, Any]]:
    return [a.sample for a in actions if isinstance(a, Publish)
            and (topic is None or a.topic == topic)]


@pytest.fixture
def harness(catalogue: Any) -> Harness:
    return Harness(catalogue)
