"""``edge-vis check`` and ``idl --profile`` on the shipped camera pod example, and on copies
of it with one mistake each: every bad command or image option is refused by its key."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from edge_vis.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "profiles" / "examples" / "camera_pod"
TEXT = (EXAMPLE / "relay.toml").read_text()
COMMAND = 'fields = { pan = "pan", tilt = "tilt", zoom = "zoom" }'


def test_the_example_checks_and_shows_its_types(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(EXAMPLE / "relay.toml")]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert main(["idl", "--profile", str(EXAMPLE / "relay.toml")]) == 0
    idl = " ".join(capsys.readouterr().out.split())
    assert "module edge_vis { module profile {" in idl
    assert ("struct CameraStatusLenses { octet lens_id; double focal_length; // meter };"
            in idl)
    assert ("struct CameraStatus { @key string vehicle_id; double pan; // radian "
            "double tilt; // radian double zoom; octet mode; @optional string label; "
            "sequence<CameraStatusLenses> lenses; int64 timestamp_ms; };" in idl)
    assert ("struct CameraPointing { @key string vehicle_id; string operator_id; "
            "double pan; // radian double tilt; // radian @optional double zoom; };" in idl)


BAD = [
    # (replace, with, key the error names, words of the reason)
    ('message = "SetCameraPointing"', 'message = "SetCameraPointng"',
     "translators.generic.commands[0].message", "did you mean 'SetCameraPointing'"),
    (COMMAND, 'fields = { pan = "pan", tilt = "tilt", zoom = "zom" }',
     "translators.generic.commands[0].fields.zoom", "no field 'zom'"),
    (COMMAND, 'fields = { pan = "pan", zoom = "zoom" }',
     "translators.generic.commands[0].fields", "SetCameraPointing needs tilt"),
    (COMMAND, 'fields = { pan = "pan", tilt = "tilt", operator_id = "zoom" }',
     "translators.generic.commands[0].fields.operator_id", "member of every command"),
    ('service = "urn:example:CameraPod"\nfields = { pan',
     'service = "urn:example:CameraPad"\nfields = { pan',
     "translators.generic.commands[0].service", "no service 'urn:example:CameraPad'"),
    ("rate = 2.0\nlifespan = 1.0", "rate = 0\nlifespan = 1.0",
     "translators.generic.commands[0].rate", "must be > 0"),
    ("rate = 2.0\nlifespan = 1.0", "rate = 2.0\nlifespan = -1",
     "translators.generic.commands[0].lifespan", "positive"),
    ("lifespan = 1.0", "lifespan = 1.0\nthrottle = 3",
     "translators.generic.commands[0].throttle", "unknown key"),
    ('topic = "CameraPointing"', 'topic = "CameraStatus"',
     "translators.generic.commands[0].topic", "a report topic of a mapping"),
    ('data = "image_file"', 'data = "sha256"',
     "translators.generic.mappings[1].image.data", "needs a variable-length field"),
    ('size_field = "size"', 'size_field = "sizes"',
     "translators.generic.mappings[1].image.size_field", "no field 'sizes'"),
    ('format_field = "format"', 'format_field = "format", format = "png"',
     "translators.generic.mappings[1].image.format_field", "not both"),
    ('format_field = "format"', 'format_field = "format", kind = "video"',
     "translators.generic.mappings[1].image.kind", "image"),
]


@pytest.mark.parametrize(("old", "new", "key", "reason"), BAD, ids=[b[2].split(".", 2)[2]
                                                                     + ":" + b[3][:12]
                                                                     for b in BAD])
def test_check_refuses_a_bad_command_or_image_option_by_name(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, key: str,
        reason: str) -> None:
    assert old in TEXT
    shutil.copy(EXAMPLE / "CameraPod.xml", tmp_path)
    profile = tmp_path / "relay.toml"
    profile.write_text(TEXT.replace(old, new, 1))
    assert main(["check", str(profile)]) == 2
    err = capsys.readouterr().err
    line = next((x for x in err.splitlines() if f"{key}:" in x), None)
    assert line is not None, err
    assert re.search(re.escape(reason), line), line
    # idl --profile refuses the same profile
    assert main(["idl", "--profile", str(profile)]) == 1
