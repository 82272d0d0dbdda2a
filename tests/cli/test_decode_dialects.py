"""``edge-vis decode --dialect`` (and ``encode --dialect``): a capture from an IOP or a
manipulator v1.0 vehicle decodes as that vehicle meant it, per vehicle or recognised from
the services it reports earlier in the capture."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.cli import main
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.pcap import PcapWriter, UdpDatagram
from edge_vis.jaus.transport import Packet, pack_datagram

IOP_VEHICLE, OTHER, OCU = JausAddress(150, 1, 2), JausAddress(151, 1, 2), JausAddress(200, 1, 1)
#: IOP's ReportGlobalVector: speed always there, so the presence-vector bits mean other fields
VECTOR = {"speed": 2.5, "heading": 1.0}


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict[str, Any]]]:
    code = main(list(argv))
    out = capsys.readouterr().out
    return code, [json.loads(line) for line in out.splitlines() if line.strip()]


def datagram(payload: bytes, source: JausAddress = IOP_VEHICLE,
             destination: JausAddress = OCU) -> str:
    return pack_datagram([Packet(destination, source, payload)]).hex()


def iop_vector() -> bytes:
    return default_catalogue().encode("ReportGlobalVector", VECTOR, ("iop",))


def test_encode_dialect_writes_the_iop_layout(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["encode", "ReportGlobalVector", "--json", json.dumps(VECTOR),
            "--source", str(IOP_VEHICLE), "--destination", str(OCU)]
    assert main([*argv, "--dialect", "iop"]) == 0
    written = bytes.fromhex(capsys.readouterr().out.strip())
    assert iop_vector() in written
    assert main(argv) == 0  # the SAE layout is another body
    assert iop_vector() not in bytes.fromhex(capsys.readouterr().out.strip())


def test_without_the_dialect_the_iop_vector_reads_wrong(
        capsys: pytest.CaptureFixture[str]) -> None:
    hex_datagram = datagram(iop_vector())
    _, (plain,) = run_cli(capsys, "decode", hex_datagram)
    assert plain["fields"] != VECTOR and "dialect" not in plain
    _, (read,) = run_cli(capsys, "decode", "--dialect", "iop", hex_datagram)
    assert read["fields"]["speed"] == pytest.approx(2.5, abs=0.01)
    assert read["fields"]["heading"] == pytest.approx(1.0, abs=0.001)
    assert read["dialect"] == "iop" and read["message"] == "ReportGlobalVector"


def test_a_dialect_for_one_subsystem_leaves_the_others_alone(
        capsys: pytest.CaptureFixture[str]) -> None:
    catalogue = default_catalogue()
    sae = catalogue.encode("ReportGlobalVector", {"speed": 1.0, "altitude": 12.0})
    lines = [datagram(iop_vector()), datagram(sae, source=OTHER),
             datagram(catalogue.encode("SetGlobalVector", VECTOR, ("iop",)), source=OCU,
                      destination=IOP_VEHICLE)]
    code, outs = run_cli(capsys, "decode", "--dialect", "150=iop", *lines)
    assert code == 0
    assert [o.get("dialect") for o in outs] == ["iop", None, "iop"]  # from, other, to 150
    assert outs[1]["fields"]["altitude"] == pytest.approx(12.0, abs=0.01)
    assert outs[2]["fields"]["speed"] == pytest.approx(2.5, abs=0.01)


def test_auto_recognises_the_dialect_from_reported_services(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A capture: the vehicle's ReportServices (IOP services), then an Event with its
    ReportGlobalVector; ``auto`` reads the event's report the IOP way."""
    catalogue = default_catalogue()
    services = catalogue.encode("ReportServices", {"node_list": [{
        "node_rec": {"node_id": 1}, "component_list": [{
            "component_rec": {"component_id": 2, "instance_id": 0},
            "service_list": [{"uri": "urn:jaus:jss:iop:PlatformMode",
                              "major_version_number": 1, "minor_version_number": 0},
                             {"uri": "urn:jaus:jss:mobility:GlobalPoseSensor",
                              "major_version_number": 1, "minor_version_number": 0}]}]}]})
    event = catalogue.wrap_event(3, 1, iop_vector())
    path = tmp_path / "iop.pcap"
    with path.open("wb") as f:
        writer = PcapWriter(f)
        for i, payload in enumerate((iop_vector(), services, event)):
            writer.write(UdpDatagram(float(i), ("127.0.0.5", 3794), ("127.0.0.6", 3794),
                                     bytes.fromhex(datagram(payload))))
    _, outs = run_cli(capsys, "decode", "--dialect", "auto", str(path))
    before, reported, after = outs
    assert "dialect" not in before  # nothing known of the vehicle yet
    assert reported["message"] == "ReportServices"
    assert after["report"]["dialect"] == "iop"
    assert after["report"]["fields"]["speed"] == pytest.approx(2.5, abs=0.01)


def test_manipulator_v1_names_and_layout(capsys: pytest.CaptureFixture[str]) -> None:
    catalogue = default_catalogue()
    v1 = ("manipulator-1.0",)
    profile = {"motion_profile_list": [{"revolute_motion_profile_rec": {
        "joint_max_speed": 1.0, "joint_max_acceleration_rate": 2.0,
        "joint_max_deceleration_rate": 3.0}}]}
    hex_datagram = datagram(catalogue.encode("ReportJointMotionProfile", profile, v1))
    _, (out,) = run_cli(capsys, "decode", "--dialect", "manipulator-1.0", hex_datagram)
    assert out["message"] == "ReportJointMotionProfile"
    assert out["dialect_name"] == "ReportMotionProfile"
    rec = out["fields"]["motion_profile_list"][0]["revolute_motion_profile_rec"]
    assert rec["joint_max_acceleration_rate"] == pytest.approx(2.0, abs=1e-6)


@pytest.mark.parametrize("option", ["klingon", "0=iop", "x=iop"])
def test_a_bad_dialect_is_named(option: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["decode", "--dialect", option, datagram(iop_vector())])
    err = capsys.readouterr().err
    assert code != 0
    assert option in err and ("manipulator-1.0" in err or "subsystem id" in err)
