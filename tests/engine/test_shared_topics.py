"""Several translators may publish one DDS topic; a JAUS message or a subscribed topic still
belongs to exactly one."""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.config import TranslatorSelection
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import PluginConflictError
from edge_vis.kit.actions import Publish
from edge_vis.kit.contract import Translator


class Writer(Translator):
    publishes = ("ImageProduct",)

    def __init__(self, name: str, message: str) -> None:
        self.name = name
        self.messages = (message,)

    def on_message(self, name: str, fields: Any, ctx: Any) -> list[Any]:
        return [Publish("ImageProduct", {"from": self.name})]


def test_two_translators_may_publish_one_topic_and_both_are_heard() -> None:
    still, atr = Writer("still", "ReportStillImageData"), Writer("atr", "ReportAtrImage")
    manager = TranslationManager([still, atr])
    assert manager.publishers["ImageProduct"] == (still, atr)
    published, _ = manager.topics()
    assert list(published) == ["ImageProduct"]  # one DDS writer for the topic
    assert manager.on_message("ReportStillImageData", {}, None) == [  # type: ignore[arg-type]
        Publish("ImageProduct", {"from": "still"})]
    assert manager.on_message("ReportAtrImage", {}, None) == [  # type: ignore[arg-type]
        Publish("ImageProduct", {"from": "atr"})]


def test_messages_and_subscriptions_are_still_exclusive() -> None:
    with pytest.raises(PluginConflictError, match=r"JAUS message 'ReportX'.*'one'.*'two'"):
        TranslationManager([Writer("one", "ReportX"), Writer("two", "ReportX")])

    class Reader(Translator):
        subscribes = ("VectorCommand",)

        def __init__(self, name: str) -> None:
            self.name = name

    with pytest.raises(PluginConflictError, match=r"subscribed topic 'VectorCommand'"):
        TranslationManager([Reader("left"), Reader("right")])


def test_installed_image_translators_both_declare_image_products() -> None:
    manager = TranslationManager.from_selection(
        TranslatorSelection(("environment", "uuv")))
    writers = {tr.name for tr in manager.publishers["ImageProduct"]}
    assert writers == {"environment", "uuv"}


def test_a_state_topic_filled_by_two_translators_is_merged(catalogue: Any) -> None:
    """HealthStatus: the level and faults from the IOP health monitor (iop translator),
    the battery from the UGV power plant (ugv translator); neither clears the other."""
    from translators.core import CoreTranslator
    from translators.iop import IopTranslator
    from translators.ugv import UgvTranslator

    from .conftest import Harness, published
    from .test_engine import ROBOT, discover

    h = Harness(catalogue, translators=[CoreTranslator(), IopTranslator(), UgvTranslator()])
    discover(h)
    h.deliver(ROBOT, "ReportUGVSummary", {"ugv_severity_rec": {"severity": 2},
                                          "severity_list": []})
    h.deliver(ROBOT, "ReportPowerPlantStatus", {"power_plant_status_list": [{
        "power_plant_desc_rec": {"power_plant_id": 1, "description": "main"},
        "power_plant_status_var": {"battery_status": [{"percent_charge_remaining": 64.0,
                                                       "voltage": 25.5}]}}]})
    health = published(h.log, "HealthStatus")[-1]
    assert health["level"] == "HEALTH_WARNING"
    assert health["battery_percent"] == pytest.approx(64.0, abs=0.01)
    h.deliver(ROBOT, "ReportUGVSummary", {"ugv_severity_rec": {"severity": 0},
                                          "severity_list": []})
    health = published(h.log, "HealthStatus")[-1]
    assert health["level"] == "HEALTH_OK"
    assert health["supply_voltage"] == pytest.approx(25.5, abs=0.02)  # kept
