"""``edge-vis check``: the kind of file, and each kind of problem refused with file, key
path and reason, as ``edge-vis run`` would refuse it (links by their own plugins, generic
mappings against the catalogue with the profile's JSIDL)."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from edge_vis.cli import main
from edge_vis.config import from_mapping
from edge_vis.config.kinds import profile_kind
from edge_vis.errors import ConfigError, EdgeVisError
from edge_vis.routing.link import check_link_url, create_link

ROOT = Path(__file__).resolve().parents[2]
WATER_QUALITY = ROOT / "tests" / "translators" / "WaterQuality.xml"


def check(path: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str]:
    status = main(["check", *extra, str(path)])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def write(tmp_path: Path, text: str, name: str = "site.toml") -> Path:
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def problem_lines(out: str) -> list[str]:
    return [line.strip() for line in out.splitlines() if line.startswith("  ")]


# -- links: what the plugin that would open them says ---------------------------------------


@pytest.mark.parametrize(("url", "key", "reason"), [
    ("udpp://0.0.0.0:3794", "links.radio.url",
     "unknown link scheme 'udpp' (installed: loop, serial, udp)"),
    ("udp://127.0.0.1:3794?bogus=1", "links.radio.url.bogus",
     "udp://127.0.0.1:3794?bogus=1: unknown option (known: bandwidth, broadcast, cycle, "
     "interface, loop, mtu, multicast, name, pack, peers, thread, ttl)"),
    ("udp://127.0.0.1:3794?cycle=0.5", "links.radio.url.cycle",
     "udp://127.0.0.1:3794?cycle=0.5: must be in 0..0.1, got 0.5 s"),
    ("udp://127.0.0.1:3794?ttl=300", "links.radio.url.ttl",
     "udp://127.0.0.1:3794?ttl=300: must be in 0..255, got 300"),
    ("udp://127.0.0.1:3794?pack=maybe", "links.radio.url.pack",
     "udp://127.0.0.1:3794?pack=maybe: pack='maybe' is not a boolean (1/0, true/false, "
     "yes/no, on/off)"),
    ("udp://0.0.0.0:3794?multicast=10.0.0.1", "links.radio.url.multicast",
     "udp://0.0.0.0:3794?multicast=10.0.0.1: '10.0.0.1' is not a multicast group (or off)"),
    ("serial:///dev/ttyUSB0?baud=fast", "links.radio.url.baud",
     "serial:///dev/ttyUSB0?baud=fast: baud='fast' is not an integer"),
    ("serial://?baud=9600", "links.radio.url",
     "serial://?baud=9600: no device path (serial:///dev/...)"),
    ("udt://0.0.0.0:9000", "links.radio.url",
     "udt:// is a bulk channel for image files, not a JAUS link: give it in the profile's "
     "[bulk] table"),
    ("no-scheme", "links.radio.url",
     "'no-scheme' is not a link URL: no scheme (e.g. udp://0.0.0.0:3794)"),
])
def test_bad_links_are_refused_as_run_would(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            url: str, key: str, reason: str) -> None:
    path = write(tmp_path, f'[links.radio]\nurl = "{url}"\n')
    status, out = check(path, capsys)
    assert status == 2
    assert f"{path}: deployment profile: 1 problem(s)" in out
    (line,) = problem_lines(out)
    assert line.startswith(f"{path}: {key}: {reason}"), line
    # run opens links with create_link: the same plugin and the same refusal
    with pytest.raises(EdgeVisError) as info:
        create_link(url)
    assert reason in str(info.value)


def test_link_options_table_is_checked_with_the_url(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, '[links.radio]\nurl = "serial:///dev/ttyUSB0?baud=9600"\n'
                           'options = { baud = 19200, pace = "sometimes", colour = 1 }\n'
                           'bandwidth = -5\n')
    status, out = check(path, capsys)
    assert status == 2
    keys = [line.split(": ")[1] for line in problem_lines(out)]
    assert keys == ["links.radio.bandwidth", "links.radio.options.baud",
                    "links.radio.options.pace", "links.radio.options.colour"]
    assert "also given in the url (baud=9600)" in out
    assert "must be at least 0, got -5 bit/s" in out


def test_good_link_options_reach_the_link() -> None:
    profile = from_mapping({"links": {"radio": {
        "url": "serial:///dev/ttyUSB0", "options": {"baud": 57600, "pace": False},
        "bandwidth": 9600}}})
    (link,) = profile.links
    assert link.link_url == "serial:///dev/ttyUSB0?baud=57600&pace=0&bandwidth=9600"
    opened = create_link(link.link_url, name=link.name)
    assert (opened.baud, opened.pace, opened.bandwidth_bps) == (57600, False, 9600.0)
    assert check_link_url(link.link_url) == opened.config


# -- profile values: unknown key, wrong type, out of range ---------------------------------


def test_profile_values_are_refused_with_key_path(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, '[relay]\njaus_id = "200.1.1"\nauthority = 300\ncolour = "blue"\n'
                           '[discovery]\nperiod = "fast"\n[dds]\ndomain = 999\n')
    status, out = check(path, capsys)
    assert status == 2
    assert problem_lines(out) == [
        f"{path}: relay.authority: must be in 0..255, got 300",
        f"{path}: dds.domain: must be in 0..232, got 999",
        f"{path}: discovery.period: expected float (s), got str 'fast'",
        f"{path}: relay.colour: unknown key",
    ]


# -- generic mappings against the catalogue and the profile's JSIDL -------------------------

MAPPING_HEAD = """
[catalogue]
jsidl = ["WaterQuality.xml"]

[translators]
enabled = ["core", "generic"]

[[translators.generic.mappings]]
topic = "WaterQuality"
"""


def mapping_check(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                  body: str) -> tuple[int, str]:
    (tmp_path / "WaterQuality.xml").write_text(WATER_QUALITY.read_text())
    return check(write(tmp_path, MAPPING_HEAD + body), capsys)


def test_a_mapping_that_exists_passes(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    status, out = mapping_check(tmp_path, capsys, """
message = "ReportWaterQuality"
query = "QueryWaterQuality"
service = "urn:example:WaterQuality"
fields = { turbidity = "turbidity", ph = "ph", station = "station" }
""")
    assert status == 0, out
    assert out.startswith("OK ") and ": deployment profile: " in out


def test_record_qualified_and_flattened_paths_both_pass(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = mapping_check(tmp_path, capsys, """
message = "ReportWaterQuality"
fields = { ph = "water_quality_rec.ph", turbidity = "turbidity" }
""")
    assert status == 0, out


@pytest.mark.parametrize(("body", "key", "reason"), [
    ('message = "ReportWaterQualityX"', "message",
     "no message 'ReportWaterQualityX' in the catalogue; did you mean 'ReportWaterQuality'?"),
    ('message = "ReportWaterQuality"\nquery = "QueryNothing"\nservice = '
     '"urn:example:WaterQuality"', "query", "no message 'QueryNothing' in the catalogue"),
    ('message = "ReportWaterQuality"\nquery = "QueryWaterQuality"\nservice = '
     '"urn:example:Nowhere"', "service",
     "no service 'urn:example:Nowhere' declares a message in the catalogue"),
    ('message = "ReportWaterQuality"\nfields = { t = "temperature" }', "fields.t",
     "'temperature' of ReportWaterQuality: no field 'temperature' in the message "
     "(fields: turbidity, ph, station)"),
    ('message = "ReportWaterQuality"\nfields = { t = "turbidity.raw" }', "fields.t",
     "'turbidity.raw' of ReportWaterQuality: turbidity is a single value"),
    ('message = "ReportWaterQuality"\nfields = { ph = "water_quality_rec.nothing" }',
     "fields.ph", "no field 'water_quality_rec' in the message (fields: turbidity, ph, "
     "station)"),
    ('message = "ReportWaterQuality"\nfields = { ph = "water_qualty_rec.ph" }', "fields.ph",
     "no field or record 'water_qualty_rec' in the message (its body is the record "
     "'water_quality_rec'"),
    ('message = "ReportWaterQuality"\nquery = "QueryWaterQuality"\nservice = '
     '"urn:example:WaterQuality"\nquery_fields = { presence_vector = 3 }',
     "query_fields.presence_vector",
     "no field 'presence_vector' in QueryWaterQuality (fields: none)"),
])
def test_a_mapping_to_what_does_not_exist_is_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, key: str,
        reason: str) -> None:
    status, out = mapping_check(tmp_path, capsys, body)
    assert status == 2
    (line,) = problem_lines(out)
    assert line.startswith(f"{tmp_path / 'site.toml'}: translators.generic.mappings[0].{key}: ")
    assert reason in line


def test_run_refuses_the_mapping_check_refuses(tmp_path: Path) -> None:
    from edge_vis.shell.relay import Runtime

    profile = from_mapping({"translators": {"enabled": ["generic"], "generic": {"mappings": [
        {"message": "ReportGlobalPose", "topic": "Pose", "fields": {"x": "pose_rec.x"}}]}}},
        file="site.toml")
    runtime = Runtime(profile, publisher_factory=None)
    with pytest.raises(ConfigError) as info:
        asyncio.run(runtime.start())
    ((file, key, reason),) = info.value.problems
    assert (file, key) == ("site.toml", "translators.generic.mappings[0].fields.x")
    assert "no field 'pose_rec'" in reason


# -- the kind of file ---------------------------------------------------------------------


def test_each_kind_is_checked_with_its_own_schema(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cases = {
        "vehicles/v.toml": ('vehicle_id = "v"\nsubsystem = 0\ncolour = 1\n', "vehicle",
                            ["subsystem: must be in 1..65534, got 0", "colour: unknown key"]),
        "sim/s.toml": ('[[vehicles]]\nname = "a"\nsubsystem = 5\nlink = "udp://10.0.0.1:1"\n'
                       'max_speed = 0\n', "sim",
                       ["vehicles[0].link: 'udp://10.0.0.1:1': simulated vehicles bind "
                        "loopback (127.x)",
                        "vehicles[0].max_speed: must be in 0.1..300, got 0.0 m/s"]),
        "links/l.toml": ("bit_rate = 9600\nmtu = 5\n[priorities]\nvoice = 1\n", "link",
                         ["mtu: must be in 32..4079, got 5 bytes",
                          "priorities.voice: unknown key (known: control, command, liveness, "
                          "telemetry, bulk)"]),
    }
    for name, (text, kind, expected) in cases.items():
        path = write(tmp_path, text, name)
        status, out = check(path, capsys)
        assert status == 2, out
        assert out.startswith(f"{path}: {kind} profile: {len(expected)} problem(s)"), out
        assert problem_lines(out) == [f"{path}: {line}" for line in expected]


def test_the_kinds_know_the_keys_of_the_sim_schema() -> None:
    from edge_vis.config.kinds import KEYS, SIM
    from edge_vis.schema import toml_keys
    from edge_vis.tools.sim.profile import SimProfile

    assert KEYS[SIM] == toml_keys(SimProfile)


def test_the_kind_is_told_by_keys_then_folder() -> None:
    assert profile_kind({"relay": {}}) == ("deployment", "")
    assert profile_kind({"vehicle_id": "v"}) == ("vehicle", "")
    assert profile_kind({"bit_rate": 1}) == ("link", "")
    assert profile_kind({"vehicles": [{"name": "a", "link": "pty"}]}) == ("sim", "")
    assert profile_kind({"vehicles": [{"vehicle_id": "a"}]}) == ("deployment", "")
    assert profile_kind({"report_rates": {}}, "profiles/vehicles/x.toml") == ("vehicle", "")
    assert profile_kind({}, "profiles/sim/x.toml") == ("sim", "")
    kind, why = profile_kind({"relay": {}, "bit_rate": 1}, "x.toml")
    assert kind is None
    assert why == ("its keys are those of a deployment profile (relay) and a link profile "
                   "(bit_rate)")


def test_a_file_of_no_known_kind_says_what_is_expected(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "[report_rates]\nReportGlobalPose = 1.0\n", "x.toml")
    status, out = check(path, capsys)
    assert status == 2
    assert out.startswith(f"{path}: cannot tell which kind of profile this is: its keys "
                          "(report_rates) belong to more than one kind")
    for kind in ("deployment profile", "vehicle profile", "sim profile", "link profile"):
        assert kind in out
    status, out = check(path, capsys, "--kind", "vehicle")
    assert status == 2 and "vehicle_id: missing" in out
    status, out = check(path, capsys, "--kind", "deployment")
    assert status == 0 and out.startswith(f"OK {path}: deployment profile: ")
