"""The generic translator (profile mappings, no Python) and the rule machinery under every
translator; removing any one translator from the selection leaves the others working."""

from __future__ import annotations

import hashlib
import random
from pathlib import Path
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, command_sample, report

from edge_vis.catalogue import Catalogue
from edge_vis.catalogue.jsidl import load_jsidl
from edge_vis.config import TranslatorSelection, from_mapping
from edge_vis.dds.convert import converter_for
from edge_vis.dds.topics import TopicRegistry
from edge_vis.engine.manager import TranslationManager
from edge_vis.errors import ConfigError
from edge_vis.kit import code_of, get_path, path_problem
from edge_vis.kit.actions import Command, Publish
from translators.generic import GenericTranslator, parse_mappings

#: a user's own JSIDL: a water quality probe (also used by the end-to-end test)
JSIDL = (Path(__file__).parent / "WaterQuality.xml").read_text()

MAPPING = {"message": "ReportWaterQuality", "topic": "WaterQuality",
           "query": "QueryWaterQuality", "service": "urn:example:WaterQuality", "rate": 0.5,
           "fields": {"turbidity_ntu": "turbidity", "ph": "ph", "station": "station"}}


@pytest.fixture
def catalogue(tmp_path: Path) -> Catalogue:
    path = tmp_path / "WaterQuality.xml"
    path.write_text(JSIDL)
    extended = CAT.copy()
    extended.add(load_jsidl([path]), source="test JSIDL")
    return extended


def test_profile_mapping_translates_a_user_message(catalogue: Catalogue) -> None:
    generic = {**MAPPING, "generic": True}  # the untyped GenericReport, asked for
    prof = from_mapping({"translators": {"enabled": ["generic"],
                                         "generic": {"mappings": [generic]}}}, file="p.toml")
    manager = TranslationManager.from_selection(prof.translators)
    (tr,) = manager.translators
    assert tr.messages == ("ReportWaterQuality",) and tr.publishes == ("WaterQuality",)
    (spec,) = tr.reports
    assert (spec.query, spec.service, spec.rate) == ("QueryWaterQuality",
                                                     "urn:example:WaterQuality", 0.5)
    assert catalogue.decode(catalogue.encode(spec.query, spec.query_fields)).name == spec.query
    registry = TopicRegistry.standard()
    registry.register_all(tr.topic_types, owner=tr.name)
    topic = registry.get("WaterQuality")
    assert topic.type is TYPES["GenericReport"] and topic.owner == "generic"

    message = catalogue.decode(catalogue.encode("ReportWaterQuality",
                                                {"turbidity": 12.5, "station": "pier 3"}))
    (action,) = manager.on_message(message.name, message.fields, CTX)
    assert isinstance(action, Publish) and action.topic == "WaterQuality"
    sample = action.sample
    assert sample["message"] == "ReportWaterQuality" and sample["vehicle_id"] == "veh1"
    fields = {f["name"]: f for f in sample["fields"]}
    assert set(fields) == {"turbidity_ntu", "station"}  # ph absent: left out
    assert fields["turbidity_ntu"]["number"] == pytest.approx(12.5, abs=0.01)
    assert fields["station"] == {"name": "station", "text": "pier 3",
                                 "number": fields["station"]["number"]}
    converter_for(TYPES["GenericReport"]).to_struct(sample, "WaterQuality")


def test_a_mapping_is_typed_from_the_jsidl(catalogue: Catalogue) -> None:
    tr = GenericTranslator()
    tr.configure({"mappings": [MAPPING]})
    assert tr.topic_types == ()  # the types come from the JSIDL, known once verified
    tr.verify(catalogue)
    (decl,) = tr.topic_types
    members = {m.name: (m.shape, m.optional) for m in decl.shape.members}
    assert decl.type_name == "edge_vis::profile::WaterQuality"
    assert members == {"vehicle_id": ("string", False), "turbidity_ntu": ("double", False),
                       "ph": ("double", True), "station": ("string", True),
                       "timestamp_ms": ("int64", False)}
    registry = TopicRegistry.standard()
    registry.register_all(tr.topic_types, owner=tr.name)
    topic = registry.get("WaterQuality")
    message = catalogue.decode(catalogue.encode("ReportWaterQuality",
                                                {"turbidity": 12.5, "station": "pier 3"}))
    (action,) = tr.on_message(message.name, message.fields, CTX)
    struct = converter_for(topic.type).to_struct(action.sample, "WaterQuality")
    assert struct.turbidity_ntu == pytest.approx(12.5, abs=0.01)  # type: ignore[attr-defined]
    assert struct.station == "pier 3" and struct.ph is None  # type: ignore[attr-defined]
    assert type(struct).__idl_typename__ == "edge_vis::profile::WaterQuality"


def test_generic_is_empty_without_mappings() -> None:
    tr = GenericTranslator()
    assert (tr.messages, tr.reports, tr.publishes, tr.topic_types) == ((), (), (), ())
    assert tr.describe() == []


@pytest.mark.parametrize(("table", "where", "text"), [
    ({"mappings": [{"topic": "T"}]}, "translators.generic.mappings[0].message", "missing"),
    ({"mappings": [{**MAPPING, "rate": 0}]}, "translators.generic.mappings[0].rate", "Hz"),
    ({"mappings": [{**MAPPING, "rate": "fast"}]}, "translators.generic.mappings[0].rate", "Hz"),
    ({"mappings": [{**MAPPING, "service": ""}]}, "translators.generic.mappings[0].service",
     "together"),
    ({"mappings": [{**MAPPING, "colour": 1}]}, "translators.generic.mappings[0].colour",
     "unknown key"),
    ({"mappings": [{**MAPPING, "topic": "Water Quality"}]},
     "translators.generic.mappings[0].topic", "letters"),
    ({"mappings": [{**MAPPING, "fields": {"x": 3}}]},
     "translators.generic.mappings[0].fields.x", "JAUS field path"),
    ({"mappings": [MAPPING, MAPPING]}, "translators.generic.mappings[1].message", "already"),
    ({"mapping": []}, "translators.generic.mapping", "unknown key"),
    ({"mappings": {}}, "translators.generic.mappings", "array"),
])
def test_bad_mappings_name_the_key(table: dict[str, Any], where: str, text: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_mappings(table, "p.toml")
    assert any(path == where and text in message for _, path, message in info.value.problems), \
        info.value.problems


def test_bad_mapping_stops_the_relay_at_start() -> None:
    prof = from_mapping({"translators": {"generic": {"mappings": [{"topic": "T"}]}}})
    with pytest.raises(ConfigError):
        TranslationManager.from_selection(prof.translators)


def test_options_for_a_translator_without_options_are_refused() -> None:
    prof = from_mapping({"translators": {"ugv": {"speed": 3}}})
    with pytest.raises(ConfigError, match=r"translators.ugv: this translator takes no options"):
        TranslationManager.from_selection(prof.translators)


def test_paths_and_names() -> None:
    fields = {"a": {"b": [1, 2]}, "v": {"radian": 1.5}}
    assert get_path(fields, "a.b") == [1, 2]
    assert get_path(fields, "v.*") == 1.5
    assert get_path(fields, "a.missing.deeper", "dflt") == "dflt"
    assert code_of({0: "Standard_Operating", 4: "MPEG-4 Visual"})("mpeg 4 visual") == 4
    with pytest.raises(ValueError, match="Standard_Operating"):
        code_of({0: "Standard_Operating"})("nope")


# -- removing any one translator leaves the others working -------------------------------

ALL = ("cbrn", "core", "costmap", "emergency", "environment", "generic", "hmi", "iop",
       "management", "manipulator", "mission_spooler", "mobility", "ugv", "uuv")


def _representative(name: str) -> tuple[str, dict[str, Any], str]:
    """(message, fields, topic) that translator ``name`` must translate."""
    if name == "core":
        return "ReportStatus", {"status": 1, "reserved": 0}, "VehicleStatus"
    if name == "mobility":
        return "ReportGlobalPose", {"latitude": 1.0, "longitude": 2.0}, "GlobalPose"
    if name in ("generic", "emergency", "management"):  # nothing of their own from JAUS
        return "", {}, ""
    cls = {t.name: type(t) for t in TranslationManager.from_selection(
        TranslatorSelection((name,))).translators}[name]
    rule = cls.report_rules[-1]
    return rule.message, report(rule.message, random.Random(name), present=1.0), rule.topic


@pytest.mark.parametrize("removed", ALL)
def test_any_one_translator_can_be_removed(removed: str) -> None:
    manager = TranslationManager.from_selection(TranslatorSelection(("*",), (removed,)))
    names = [t.name for t in manager.translators]
    assert names == [n for n in ALL if n != removed]
    for name in names:
        message, fields, topic = _representative(name)
        if not message:
            continue
        actions = manager.on_message(message, fields, CTX)
        assert any(isinstance(a, Publish) and a.topic == topic for a in actions), (name, actions)
    # and every remaining translator that takes commands still turns samples into them
    for tr in manager.translators:
        for rule in getattr(tr, "command_rules", ())[:1]:
            sample = command_sample(rule, values=[0.5, 0.5], state="DRIVE",
                                    platform_state="Operational",
                                    tasks=[{"task_id": 1, "messages": []}])
            assert any(isinstance(a, Command)
                       for a in manager.on_sample(rule.topic, sample, CTX)), rule.message
    if "mobility" in names:
        drive = {"vehicle_id": "veh1", "operator_id": "op1", "propulsive_linear_x": 10.0}
        assert isinstance(manager.on_sample("WrenchEffortCommand", drive, CTX)[0], Command)


# -- the mapping table ----------------------------------------------------------------------


def test_mappings_command_lists_every_declared_rule(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from edge_vis.cli import main

    assert main(["mappings", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    rows = table["rows"]
    for tr in TranslationManager.from_selection(TranslatorSelection()).translators:
        declared = {r.message for r in getattr(tr, "report_rules", ())} | {
            c.message for c in getattr(tr, "command_rules", ())}
        listed = {r["message"] for r in rows if r["translator"] == tr.name}
        assert declared <= listed, tr.name
        assert set(tr.messages) <= listed | {"VendorHello"}, tr.name
    counts = table["counts"]
    assert counts["translated_messages"] == len(  # a query sent on command is a query
        {r["message"] for r in rows if r["direction"] in ("jaus->dds", "dds->jaus")
         and not r["message"].startswith("Query")})
    assert counts["jaus_messages_total"] >= 100
    assert main(["mappings"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("# JAUS ⇄ DDS mappings") and "## uuv" in text
    assert "| ReportOceanEnvironment (via QueryOceanEnvironment) | JAUS → DDS |" in text


def test_mappings_follow_the_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from edge_vis.cli import main

    (tmp_path / "WaterQuality.xml").write_text(JSIDL)
    profile = tmp_path / "site.toml"
    profile.write_text(
        '[translators]\nenabled = ["generic", "uuv"]\n\n[catalogue]\n'
        'jsidl = ["WaterQuality.xml"]\n\n[[translators.generic.mappings]]\n'
        'message = "ReportWaterQuality"\ntopic = "WaterQuality"\n'
        'fields = { turbidity_ntu = "turbidity" }\n')
    assert main(["mappings", "--profile", str(profile)]) == 0
    text = capsys.readouterr().out
    assert "## generic" in text and "## mobility" not in text
    assert "turbidity_ntu ← turbidity" in text  # a typed topic: the member itself


@pytest.mark.parametrize(("message", "path", "problem"), [
    ("SetElement", "request_id_rec.request_id", ""),
    ("SetElement", "element_list", ""),
    ("SetElement", "element_list.element_uid", "element_list is a list: a path cannot enter"),
    ("SetTime", "time_stamp.seconds", ""),
    ("SetTime", "time_stamp.fortnight", "no sub-field 'fortnight' in time_stamp"),
    ("QueryEvents", "query_events_var.*.message_code", ""),
    ("QueryEvents", "query_events_var.message_id_rec.message_code", ""),
    ("QueryEvents", "query_events_var.nothing", "no alternative 'nothing' in query_events_var"),
    ("SetElement", "request_id", "no field 'request_id' in the message (fields: "),
    ("SetElement", "request_id_rec.request_id.x", "request_id_rec.request_id is a single"),
])
def test_field_paths_are_checked_against_the_definition(message: str, path: str,
                                                       problem: str) -> None:
    """What get_path can reach in a decoded message is what path_problem accepts."""
    found = path_problem(CAT.by_name(message).body, path)
    assert found.startswith(problem) if problem else found == ""


@pytest.mark.parametrize("path", ["ph", "water_quality_rec.ph"])
def test_flattened_and_record_qualified_paths_publish_the_same_value(
        catalogue: Catalogue, path: str) -> None:
    """The body of ReportWaterQuality is one record, flattened when decoded: the JSIDL's
    nesting (``water_quality_rec.ph``) and the flattened path (``ph``) both publish."""
    tr = GenericTranslator()
    tr.configure({"mappings": [{**MAPPING, "fields": {"ph": path}}]}, "p.toml")
    tr.verify(catalogue, "p.toml")
    message = catalogue.decode(catalogue.encode("ReportWaterQuality", {"turbidity": 1.0,
                                                                       "ph": 7.0}))
    (action,) = tr.on_message(message.name, message.fields, CTX)
    assert action.sample["ph"] == pytest.approx(7.0, abs=0.1)
    (row,) = tr.describe()[0]["fields"]
    assert (row["dds"], row["jaus"]) == ("ph", "ph")


def test_a_wrong_record_name_alone_is_not_taken_for_a_qualifier(catalogue: Catalogue) -> None:
    """Only a first step that is no field and leads on to a real path is a qualifier."""
    for path, problem in (("water_quality_rec.nothing", "no field 'water_quality_rec'"),
                          ("turbidity.deeper", "turbidity is a single value")):
        tr = GenericTranslator()
        tr.configure({"mappings": [{**MAPPING, "fields": {"x": path}}]}, "p.toml")
        with pytest.raises(ConfigError) as info:
            tr.verify(catalogue, "p.toml")
        ((file, key, reason),) = info.value.problems
        assert (file, key) == ("p.toml", "translators.generic.mappings[0].fields.x")
        assert problem in reason, reason


#: a vehicle's JSIDL whose message announces an image file it serves over the bulk channel
SURVEY_JSIDL = Path(__file__).parent / "SurveyImages.xml"
ANNOUNCE = {"message": "ReportSurveyImage",
            "image": {"id_field": "image_id", "name_field": "file_name", "format": "png",
                      "size_field": "size", "sha256_field": "sha256"}}


def _announcing(catalogue: Catalogue) -> tuple[GenericTranslator, Catalogue]:
    extended = catalogue.copy()
    extended.add(load_jsidl([SURVEY_JSIDL]), source="test JSIDL")
    tr = GenericTranslator()
    tr.configure({"mappings": [ANNOUNCE]})
    tr.verify(extended)
    return tr, extended


def test_an_announcement_mapping_publishes_a_product_for_the_relay_to_fetch(
        catalogue: Catalogue) -> None:
    """No data field: the message announces a file the vehicle serves; the product has no
    transfer id, which is what makes the relay fetch it (tests/udt/test_relay_bulk.py)."""
    tr, extended = _announcing(catalogue)
    assert tr.publishes == ("ImageProduct",)
    digest = hashlib.sha256(b"survey").hexdigest()
    message = extended.decode(extended.encode("ReportSurveyImage", {
        "image_id": 7, "size": 123_456, "sha256": digest, "file_name": "survey-7.png"}))
    (action,) = tr.on_message(message.name, message.fields, CTX)  # no ImageData chunks
    assert isinstance(action, Publish) and action.topic == "ImageProduct"
    assert action.sample == {
        "vehicle_id": "veh1", "image_id": "ReportSurveyImage-7", "file_name": "survey-7.png",
        "size_bytes": 123_456, "sha256": digest, "format": "png",
        "capture_time_ms": CTX.timestamp_ms, "transfer_id": "", "targets": []}
    converter_for(TYPES["ImageProduct"]).to_struct(action.sample, "ImageProduct")
    (row,) = [r for r in tr.describe() if r["message"] == "ReportSurveyImage"]
    assert "the bulk channel fetches it" in row["doc"]


def test_an_announcement_of_nothing_fetchable_is_refused_with_the_reason(
        catalogue: Catalogue) -> None:
    tr, extended = _announcing(catalogue)
    message = extended.decode(extended.encode("ReportSurveyImage", {
        "image_id": 8, "size": 10, "sha256": "x" * 64, "file_name": "survey-8.png"}))
    with pytest.raises(ValueError, match="announces no file to fetch"):
        tr.on_message(message.name, message.fields, CTX)


@pytest.mark.parametrize(("image", "where", "text"), [
    ({"id_field": "image_id", "sha256_field": "sha256"}, "size_field", "announcement"),
    ({"id_field": "image_id", "size_field": "size"}, "sha256_field", "announcement"),
    ({"data": "image_file", "name_field": "file_name"}, "name_field", "id_field"),
])
def test_an_announcement_mapping_declares_what_to_fetch(image: dict[str, str], where: str,
                                                        text: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_mappings({"mappings": [{"message": "ReportSurveyImage", "image": image}]},
                       "p.toml")
    assert any(path == f"translators.generic.mappings[0].image.{where}" and text in message
               for _, path, message in info.value.problems), info.value.problems
