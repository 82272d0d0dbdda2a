"""Run-time JSIDL import: a user's own service definitions become message definitions.

Each test writes a small JSIDL service (AS5684 XML) into ``tmp_path``, loads it with
``edge_vis.catalogue.jsidl.load_jsidl`` and checks the layout a user would get, or checks that a
malformed file is rejected with a ConfigError naming the file, the element and the problem.
The last tests compare the committed built-in modules with the public JSIDL they were
generated from (skipped when the reference material is not beside the repository).
"""

from __future__ import annotations

import importlib
import math
import struct
from pathlib import Path

import pytest

from edge_vis.catalogue.jsidl import load_jsidl
from edge_vis.codec.types import (
    BitField,
    Enum,
    Field,
    JausMessage,
    List,
    MessageDef,
    Record,
    Scaled,
    SubField,
    Variant,
    VarString,
    f,
    opt,
    record,
    u8,
    u16,
    u32,
)
from edge_vis.errors import ConfigError

NS = 'xmlns="urn:jaus:jsidl:1.0"'

TYPES_XML = f"""<?xml version="1.0" encoding="UTF-8"?>
<declared_type_set {NS} name="DemoTypes" id="urn:example:demo:Types" version="1.0">
  <declared_const_set_ref name="consts" id="urn:example:demo:Constants" version="1.0"/>
  <fixed_field name="Heading" field_type="unsigned short integer" field_units="radian"
    optional="false">
    <scale_range real_lower_limit="-consts.PI" real_upper_limit="consts.PI"
      integer_function="round"/>
  </fixed_field>
  <fixed_field name="Mode" field_type="unsigned byte" field_units="one" optional="false">
    <value_set offset_to_lower_limit="false">
      <value_enum enum_index="0" enum_const="IDLE"/>
      <value_enum enum_index="1" enum_const="SURVEY"/>
      <value_range lower_limit="2" lower_limit_type="inclusive" upper_limit="255"
        upper_limit_type="inclusive" interpretation="Reserved"/>
    </value_set>
  </fixed_field>
  <bit_field name="Flags" field_type_unsigned="unsigned byte" optional="false">
    <sub_field name="LowBattery"><bit_range from_index="0" to_index="0"/></sub_field>
    <sub_field name="FaultCode"><bit_range from_index="4" to_index="7"/></sub_field>
  </bit_field>
  <record name="WaypointRec" optional="false">
    <fixed_field name="WaypointID" field_type="unsigned short integer" field_units="one"
      optional="false"/>
    <declared_fixed_field name="Heading" declared_type_ref="Heading" optional="false"/>
  </record>
</declared_type_set>
"""

CONSTS_XML = f"""<?xml version="1.0" encoding="UTF-8"?>
<declared_const_set {NS} name="DemoConstants" id="urn:example:demo:Constants" version="1.0">
  <const_def name="PI" const_type="long float" const_value="3.14159265358979323846"
    field_units="one"/>
</declared_const_set>
"""


def service(messages: str, *, refs: str = "") -> str:
    """A service_def holding ``messages`` (message_def elements) in its output set."""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<service_def {NS} name="DemoSensor" id="urn:example:demo:DemoSensor" version="1.2">
  <description>A sensor of our own.</description>
  <assumptions>Messages may be lost.</assumptions>
  <declared_type_set name="Types">
    <declared_type_set_ref name="demo" id="urn:example:demo:Types" version="1.0"/>
    {refs}
  </declared_type_set>
  <message_set>
    <input_set/>
    <output_set>
{messages}
    </output_set>
  </message_set>
  <internal_events_set/>
  <protocol_behavior is_stateless="true"/>
</service_def>
"""


def msg(name: str, code: str, body: str, extra: str = "") -> str:
    """A message_def with the usual two-byte header and empty footer."""
    return f"""
      <message_def name="{name}" message_id="{code}" is_command="false" {extra}>
        <description>{name} of the demo sensor. Second sentence.</description>
        <header name="Header">
          <record name="HeaderRec" optional="false">
            <fixed_field name="MessageID" field_type="unsigned short integer"
              field_units="one" optional="false"/>
          </record>
        </header>
        <body name="Body">{body}</body>
        <footer name="Footer"/>
      </message_def>"""


REPORT_STATUS = msg("ReportDemoStatus", "D001", """
          <record name="DemoStatusRec" optional="false">
            <presence_vector field_type_unsigned="unsigned byte"/>
            <fixed_field name="SensorID" field_type="unsigned short integer"
              field_units="one" optional="false"/>
            <fixed_field name="Latitude" field_type="unsigned integer" field_units="degree"
              optional="true">
              <scale_range real_lower_limit="-90" real_upper_limit="90"
                integer_function="round"/>
            </fixed_field>
            <declared_fixed_field name="Heading" declared_type_ref="demo.Heading"
              optional="true"/>
            <declared_fixed_field name="Mode" declared_type_ref="demo.Mode"
              optional="false"/>
            <declared_bit_field name="Flags" declared_type_ref="demo.Flags"
              optional="true"/>
            <variable_length_string name="Label" optional="true">
              <count_field field_type_unsigned="unsigned byte" max_count="32"/>
            </variable_length_string>
          </record>""")

REPORT_ROUTE = msg("ReportDemoRoute", "D002", """
          <list name="WaypointList" optional="false">
            <count_field field_type_unsigned="unsigned short integer"/>
            <declared_record name="WaypointRec" declared_type_ref="demo.WaypointRec"
              optional="false"/>
          </list>""")

REPORT_SOURCE = msg("ReportDemoSource", "D003", """
          <variant name="SourceVar" optional="false">
            <vtag_field field_type_unsigned="unsigned byte" min_count="0" max_count="1"/>
            <record name="GpsRec" optional="false">
              <fixed_field name="Satellites" field_type="unsigned byte" field_units="one"
                optional="false"/>
            </record>
            <record name="RelayRec" optional="false">
              <variable_length_field name="Relayed" field_format="JAUS MESSAGE"
                optional="false">
                <count_field field_type_unsigned="unsigned integer"/>
              </variable_length_field>
            </record>
          </variant>""")


def write_demo(tmp_path: Path, messages: str = REPORT_STATUS + REPORT_ROUTE + REPORT_SOURCE,
               *, types: str = TYPES_XML) -> list[Path]:
    """The demo service in three files, as a user would keep them."""
    files = [tmp_path / "DemoSensor.xml", tmp_path / "types" / "DemoTypes.xml",
             tmp_path / "types" / "DemoConstants.xml"]
    files[1].parent.mkdir(exist_ok=True)
    files[0].write_text(service(messages))
    files[1].write_text(types)
    files[2].write_text(CONSTS_XML)
    return files


def by_name(defs: list[MessageDef]) -> dict[str, MessageDef]:
    return {d.name: d for d in defs}


# -- a well-formed user service -------------------------------------------------------------


def test_user_service_loads_with_layout_units_and_services(tmp_path: Path) -> None:
    defs = by_name(load_jsidl(write_demo(tmp_path)))
    assert set(defs) == {"ReportDemoStatus", "ReportDemoRoute", "ReportDemoSource"}

    status = defs["ReportDemoStatus"]
    assert status.code == 0xD001
    assert status.services == (("urn:example:demo:DemoSensor", "1.2"),)
    assert status.doc == "ReportDemoStatus of the demo sensor."
    # the body's single record is flattened, keeping its presence vector
    assert status.body == Record(
        (
            f("sensor_id", u16, jsidl="SensorID"),
            opt("latitude", Scaled(u32, -90.0, 90.0, "degree"), jsidl="Latitude"),
            opt("heading", Scaled(u16, -math.pi, math.pi, "radian"), jsidl="Heading"),
            f("mode", Enum(u8, {0: "IDLE", 1: "SURVEY"}, ((2, 255, "Reserved"),)),
              jsidl="Mode"),
            opt("flags", BitField(u8, (SubField("low_battery", 0, 0),
                                       SubField("fault_code", 4, 7))), jsidl="Flags"),
            opt("label", VarString(u8, 32), jsidl="Label"),
        ),
        u8,
        "ReportDemoStatus",
    )

    route = defs["ReportDemoRoute"]
    waypoint = record(f("waypoint_id", u16, jsidl="WaypointID"),
                      f("heading", Scaled(u16, -math.pi, math.pi, "radian"), jsidl="Heading"),
                      name="WaypointRec")
    assert route.body.fields == (
        f("waypoint_list", List(u16, waypoint, "WaypointList"), jsidl="WaypointList"),
    )
    assert route.body.pv is None

    source = defs["ReportDemoSource"]
    (var_field,) = source.body.fields
    assert var_field.type == Variant(
        u8,
        (
            f("gps_rec", record(f("satellites", u8, jsidl="Satellites"), name="GpsRec"),
              jsidl="GpsRec"),
            f("relay_rec", record(f("relayed", JausMessage(u32), jsidl="Relayed"),
                                  name="RelayRec"), jsidl="RelayRec"),
        ),
        None,
        "SourceVar",
    )


def test_every_field_keeps_its_jsidl_name(tmp_path: Path) -> None:
    def walk(fields: tuple[Field, ...]) -> None:
        for fld in fields:
            assert fld.jsidl_name, f"{fld.name} has no jsidl_name"
            t = fld.type
            if isinstance(t, List):
                t = t.element
            if isinstance(t, Record):
                walk(t.fields)
            elif isinstance(t, Variant):
                walk(t.alternatives)

    for defn in load_jsidl(write_demo(tmp_path)):
        walk(defn.body.fields)


def test_a_directory_loads_like_its_files(tmp_path: Path) -> None:
    files = write_demo(tmp_path)
    assert load_jsidl(tmp_path) == load_jsidl(files)
    assert load_jsidl(str(tmp_path), service_set="demo")[0].service_set == "demo"


def test_user_message_decodes_its_bytes(tmp_path: Path) -> None:
    """The loaded definition decodes a body laid out as the JSIDL says."""
    engine = pytest.importorskip("edge_vis.codec.bodies")
    status = by_name(load_jsidl(write_demo(tmp_path)))["ReportDemoStatus"]
    # PV: latitude (bit 0) and label (bit 3); mode is mandatory
    body = struct.pack("<BHIB", 0b1001, 7, 0xFFFFFFFF, 1) + b"\x03abc"
    assert engine.decode_body(status, body) == {
        "sensor_id": 7, "latitude": pytest.approx(90.0), "mode": 1, "label": "abc"}


def test_array_and_variable_field_representation(tmp_path: Path) -> None:
    """A fixed array is a record of indexed elements; a variable_field a tagged variant."""
    body = """
          <record name="OffsetRec" optional="false">
            <array name="Offset" optional="false">
              <fixed_field name="Axis" field_type="unsigned short integer" field_units="meter"
                optional="false">
                <scale_range real_lower_limit="-10" real_upper_limit="10"
                  integer_function="round"/>
              </fixed_field>
              <dimension name="AxisDimension" size="3"/>
            </array>
            <variable_field name="JointValue" optional="false">
              <type_and_units_field>
                <type_and_units_enum name="radian" index="1" field_type="unsigned integer"
                  field_units="radian">
                  <scale_range real_lower_limit="-2*consts.PI" real_upper_limit="2*consts.PI"
                    integer_function="round"/>
                </type_and_units_enum>
                <type_and_units_enum name="meter" index="2" field_type="unsigned integer"
                  field_units="meter">
                  <scale_range real_lower_limit="-5" real_upper_limit="5"
                    integer_function="round"/>
                </type_and_units_enum>
              </type_and_units_field>
            </variable_field>
          </record>"""
    files = write_demo(tmp_path, msg("ReportDemoOffset", "D010", body))
    files[0].write_text(files[0].read_text().replace(
        "</declared_type_set>",
        '<declared_const_set_ref name="consts" id="urn:example:demo:Constants" version="1.0"/>'
        "</declared_type_set>"))
    (defn,) = load_jsidl(files)
    axis = Scaled(u16, -10.0, 10.0, "meter")
    assert defn.body.fields == (
        f("offset", record(*(f(f"axis_{i}", axis, jsidl="Axis") for i in range(3)),
                           name="Offset"), jsidl="Offset"),
        f("joint_value", Variant(u8, (
            f("radian", Scaled(u32, -2 * math.pi, 2 * math.pi, "radian"), jsidl="radian"),
            f("meter", Scaled(u32, -5.0, 5.0, "meter"), jsidl="meter"),
        ), (1, 2), "JointValue"), jsidl="JointValue"),
    )


# -- malformed files: ConfigError naming file, element and problem ---------------------------


def test_recursive_declared_type(tmp_path: Path) -> None:
    types = TYPES_XML.replace(
        '<declared_fixed_field name="Heading" declared_type_ref="Heading" optional="false"/>',
        '<declared_record name="Again" declared_type_ref="WaypointRec" optional="false"/>')
    with pytest.raises(ConfigError, match=r'<record name="WaypointRec">.*contains itself'):
        load_jsidl(write_demo(tmp_path, types=types))


def problem_of(exc: pytest.ExceptionInfo[ConfigError]) -> tuple[str, str, str]:
    assert len(exc.value.problems) == 1
    return exc.value.problems[0]


def test_broken_xml_names_file_and_line(tmp_path: Path) -> None:
    files = write_demo(tmp_path)
    files[0].write_text(service(REPORT_STATUS).replace("</output_set>", "</outputset>"))
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files)
    file, where, problem = problem_of(exc)
    assert file == str(files[0])
    assert where.startswith("line ")
    assert "not well-formed" in problem
    assert str(files[0]) in str(exc.value)


def test_unresolved_declared_type(tmp_path: Path) -> None:
    bad = REPORT_STATUS.replace('declared_type_ref="demo.Mode"', 'declared_type_ref="demo.Mood"')
    files = write_demo(tmp_path, bad)
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files)
    file, where, problem = problem_of(exc)
    assert file == str(files[0])
    assert where.startswith('<declared_fixed_field name="Mode">')
    assert "unresolved declared type 'demo.Mood'" in problem


def test_missing_type_set_is_named(tmp_path: Path) -> None:
    files = write_demo(tmp_path)
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files[:1])  # the service without its type files
    file, where, problem = problem_of(exc)
    assert file == str(files[0])
    assert 'name="demo"' in where
    assert "unresolved declared_type_set urn:example:demo:Types version 1.0" in problem


def test_missing_message_id(tmp_path: Path) -> None:
    files = write_demo(tmp_path, REPORT_STATUS.replace('message_id="D001"', ""))
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files)
    file, where, problem = problem_of(exc)
    assert file == str(files[0])
    assert where.startswith('<message_def name="ReportDemoStatus">')
    assert "no message_id" in problem


def test_message_id_not_hex(tmp_path: Path) -> None:
    files = write_demo(tmp_path, REPORT_STATUS.replace('message_id="D001"', 'message_id="D0Z1"'))
    with pytest.raises(ConfigError, match="'D0Z1' is not hexadecimal"):
        load_jsidl(files)


@pytest.mark.parametrize(
    ("lower", "upper", "expected"),
    [
        ("90", "-90", "bad scale range: upper limit -90 is not above lower limit 90"),
        ("5", "5", "bad scale range"),
        ("-90", "ninety", "unresolved constant 'ninety'"),
    ],
)
def test_bad_scale_range(tmp_path: Path, lower: str, upper: str, expected: str) -> None:
    bad = REPORT_STATUS.replace('real_lower_limit="-90" real_upper_limit="90"',
                                f'real_lower_limit="{lower}" real_upper_limit="{upper}"')
    files = write_demo(tmp_path, bad)
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files)
    file, where, problem = problem_of(exc)
    assert file == str(files[0])
    assert where.startswith('<scale_range> in <fixed_field name="Latitude"> (line ')
    assert expected in problem


def test_unknown_field_type(tmp_path: Path) -> None:
    files = write_demo(tmp_path, types=TYPES_XML.replace(
        'name="Mode" field_type="unsigned byte"', 'name="Mode" field_type="unsigned nibble"'))
    with pytest.raises(ConfigError) as exc:
        load_jsidl(files)
    file, where, problem = problem_of(exc)
    assert file == str(files[1])  # the error is where the type is defined
    assert where.startswith('<fixed_field name="Mode">')
    assert "unknown field_type 'unsigned nibble'" in problem


def test_optional_field_without_presence_vector(tmp_path: Path) -> None:
    bad = REPORT_STATUS.replace('<presence_vector field_type_unsigned="unsigned byte"/>', "")
    with pytest.raises(ConfigError, match=r'<record name="DemoStatusRec">.*4 optional member'):
        load_jsidl(write_demo(tmp_path, bad))


def test_every_broken_message_is_reported_at_once(tmp_path: Path) -> None:
    bad = (REPORT_STATUS.replace('message_id="D001"', "")
           + REPORT_ROUTE.replace('declared_type_ref="demo.WaypointRec"',
                                  'declared_type_ref="demo.NoSuchRec"'))
    with pytest.raises(ConfigError) as exc:
        load_jsidl(write_demo(tmp_path, bad))
    wheres = [where for _, where, _ in exc.value.problems]
    assert len(wheres) == 2
    assert wheres[0].startswith('<message_def name="ReportDemoStatus">')
    assert wheres[1].startswith('<declared_record name="WaypointRec">')


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such JSIDL file"):
        load_jsidl(tmp_path / "nope.xml")


# -- the built-in modules against the JSIDL they come from ------------------------------------

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "jaus"
needs_shared = pytest.mark.skipif(not (SHARED / "jsidl").is_dir(),
                                  reason=f"JAUS reference material not found at {SHARED}")


def builtin(set_name: str) -> dict[int, MessageDef]:
    module = importlib.import_module(f"edge_vis.jaus.messages.{set_name}")
    return {m.code: m for m in module.MESSAGES}


@needs_shared
@pytest.mark.parametrize(
    ("set_name", "folder"),
    [
        ("core", "jsidl/urn.jaus.jss.core-v1.1"),
        ("mobility", "jsidl/urn.jaus.jss.mobility"),
        ("environment", "jsidl/urn.jaus.jss.environmentSensing"),
    ],
)
def test_builtin_modules_match_a_fresh_parse(set_name: str, folder: str) -> None:
    """Re-reading the JSIDL at run time gives the committed definitions (not stale)."""
    fresh = {m.code: m for m in load_jsidl(SHARED / folder, service_set=set_name)}
    committed = builtin(set_name)
    for code, defn in fresh.items():
        if code not in committed:
            continue  # owned by another built-in set (the mobility list manager is core's)
        kept = committed[code]
        assert (kept.name, kept.body) == (defn.name, defn.body), f"0x{code:04X} {defn.name}"
        assert set(defn.services) <= set(kept.services)
    assert len(set(fresh) & set(committed)) >= len(committed) - 2


def test_builtin_sets_hold_at_least_330_distinct_codes() -> None:
    from edge_vis.jaus.messages import BUILTIN_SETS

    codes: dict[int, str] = {}
    for set_name in BUILTIN_SETS:
        for code, defn in builtin(set_name).items():
            assert code not in codes, f"0x{code:04X} in both {codes.get(code)} and {set_name}"
            codes[code] = set_name
            assert defn.service_set == set_name
    assert len(codes) >= 330
