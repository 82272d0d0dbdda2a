"""A translator that raises: caught on both directions, counted per translator, logged a
few times a minute, and the relay goes on translating everything else."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import pytest

from edge_vis.kit import Action, Publish, RuleTranslator, TranslatorContext

from .conftest import Harness, published
from .test_engine import ROBOT, VID, discover


class Faulty(RuleTranslator):
    """Claims a report and a command topic of its own, and raises on both."""

    name = "faulty"
    extra_messages = ("ReportVelocityState",)
    extra_publishes = ("Velocity",)
    subscribes = ("VectorCommand",)

    def __init__(self) -> None:
        super().__init__()
        self.vehicle_calls = 0

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        raise ZeroDivisionError("a bug in the plugin")

    def on_sample(self, topic: str, sample: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        raise KeyError("missing_member")

    def on_vehicle(self, change: str, ctx: TranslatorContext) -> list[Action]:
        self.vehicle_calls += 1
        raise RuntimeError("cannot follow the vehicle")


@pytest.fixture
def harness(catalogue: Any) -> Harness:
    from translators.core import CoreTranslator
    from translators.mobility import MobilityTranslator

    class Mobility(MobilityTranslator):  # without the report the faulty one claims
        report_rules = tuple(r for r in MobilityTranslator.report_rules
                             if r.message != "ReportVelocityState")

    return Harness(catalogue, translators=[CoreTranslator(), Mobility(), Faulty()])


def test_a_raising_translator_is_counted_and_the_others_go_on(
        harness: Harness, caplog: pytest.LogCaptureFixture) -> None:
    h = harness
    with caplog.at_level(logging.WARNING, "edge_vis.engine.manager"):
        discover(h, events=False)
        for _ in range(20):  # JAUS side: the faulty translator's report, again and again
            h.deliver(ROBOT, "ReportVelocityState", {"velocity_x": 0.5})
        out = h.deliver(ROBOT, "ReportGlobalPose", {"latitude": 28.5, "longitude": -81.4})
        h.sample("VectorCommand", {"vehicle_id": VID, "operator_id": "op1"})  # DDS side

    errors = h.engine.manager.errors
    assert errors["faulty"] >= 22  # 20 reports, 1 sample, and every vehicle change
    assert set(errors) == {"faulty"}
    assert h.engine.manager.translators[2].vehicle_calls >= 1
    # the healthy translators kept working: the pose after the faults was published
    (pose,) = published(out, "GlobalPose")
    assert pose["vehicle_id"] == VID and pose["latitude"] == pytest.approx(28.5)
    assert not any(isinstance(a, Publish) and a.topic == "Velocity" for a in h.log)
    lines = [r.getMessage() for r in caplog.records]
    failures = [m for m in lines if m.startswith("translator faulty failed on")]
    assert 1 <= len(failures) <= 5, lines  # rate-limited, not one line per message
    assert any("ZeroDivisionError: a bug in the plugin" in m for m in failures)
    assert any("suppressed" in m for m in lines)
