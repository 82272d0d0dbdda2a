"""``edge-vis decode`` and ``edge-vis encode`` as a user runs them."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from edge_vis.cli import main
from edge_vis.jaus.pcap import PcapWriter, UdpDatagram, read_udp

# From the JAUS Toolset capture: ReportIdentification "SimulatedVehicle" from 126.1.199.
REPORT_ID = "020024000101012a00c7017e00004b0211271053696d756c6174656456656869636c650100"
# JAUS++: Event 0 carrying ReportGlobalPose (PV 0x0147).
EVENT_POSE = (
    "02002c000101012a0001019600f14100001600000002444701178696a8655e2146083f0f395e94402dd1b21100"
)
# The serial capture: QueryIdentification to a JAUS Toolset node manager's serial port.
SERIAL_QUERY = "10010211001002c20000110001c7017e0001012a00002b020500100350bc"
SERIAL_REPLY = (
    "10010224001002d8c80024000101012a00c7017e00004b021127101053696d756c6174656456656869636c65"
    "01001003281e"
)


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict]]:
    code = main(list(argv))
    out = capsys.readouterr().out
    return code, [json.loads(line) for line in out.splitlines() if line.strip()]


def test_decode_hex_argument(capsys: pytest.CaptureFixture[str]) -> None:
    code, (obj,) = run_cli(capsys, "decode", REPORT_ID)
    assert code == 0
    assert obj["source"] == "126.1.199" and obj["destination"] == "42.1.1"
    assert obj["message_code"] == "0x4B00" and obj["message"] == "ReportIdentification"
    assert obj["fields"] == {"query_type": 2, "type": 10001, "identification": "SimulatedVehicle"}
    assert obj["transport"]["sequence"] == 1 and obj["transport"]["priority"] == 1
    assert obj["transport"]["data_size"] == 36


def test_decode_event_unwraps_report(capsys: pytest.CaptureFixture[str]) -> None:
    _, (obj,) = run_cli(capsys, "decode", EVENT_POSE)
    assert obj["message"] == "Event"
    report = obj["report"]
    assert report["message"] == "ReportGlobalPose"
    assert report["fields"]["latitude"] == pytest.approx(28.538426, abs=1e-5)
    assert report["fields"]["longitude"] == pytest.approx(-81.379200, abs=1e-5)
    assert "position_rms" not in report["fields"]  # PV bit 3 is clear


def test_decode_stdin_lines_with_errors_in_order(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    text = f"{REPORT_ID}\n# a comment\nzz\n0200ff00\n{EVENT_POSE}\n"
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(text.encode())))
    code, objs = run_cli(capsys, "decode")
    assert code == 1  # some input did not decode
    assert [o.get("message") for o in objs] == ["ReportIdentification", None, None, "Event"]
    assert objs[1] == {"error": "not hex", "input": "stdin", "line": 3}
    assert "truncated" in objs[2]["error"] and objs[2]["line"] == 4


def test_decode_pcap_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "session.pcap"
    with path.open("wb") as stream:
        writer = PcapWriter(stream)
        writer.write(UdpDatagram(1.5, ("127.0.0.1", 3794), ("127.0.0.1", 40001),
                                 bytes.fromhex(REPORT_ID)))
        writer.write(UdpDatagram(2.0, ("127.0.0.1", 5000), ("127.0.0.1", 5001), b"other"))
        writer.write(UdpDatagram(2.5, ("127.0.0.1", 3794), ("127.0.0.1", 40001),
                                 bytes.fromhex(EVENT_POSE)))
    assert len(list(read_udp(path.read_bytes(), port=None))) == 3
    code, objs = run_cli(capsys, "decode", str(path))
    assert code == 0
    assert [o["message"] for o in objs] == ["ReportIdentification", "Event"]
    assert objs[0]["time"] == 1.5 and objs[0]["udp_source"] == "127.0.0.1:3794"


def test_decode_serial_dump_with_noise(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    noisy = "ff00" + SERIAL_QUERY + "1234" + SERIAL_REPLY
    # a corrupted copy of the query: one byte of its payload flipped, so the CRC fails
    broken = SERIAL_QUERY.replace("002b02", "002b03")
    dump = tmp_path / "radio.txt"
    dump.write_text(" ".join(noisy[i:i + 2] for i in range(0, len(noisy), 2)) + "\n" + broken)
    code, objs = run_cli(capsys, "decode", "--serial", str(dump))
    messages = [o["message"] for o in objs if "error" not in o]
    errors = [o["error"] for o in objs if "error" in o]
    assert messages == ["QueryIdentification", "ReportIdentification"]
    assert any("CRC" in e or "crc" in e for e in errors)
    assert code == 1


def test_encode_then_decode_round_trip(capsys: pytest.CaptureFixture[str]) -> None:
    fields = {"latitude": 28.5, "longitude": -81.25, "yaw": 0.5}
    code = main(["encode", "ReportGlobalPose", "--json", json.dumps(fields),
                 "--source", "126.1.199", "--destination", "42.1.1", "--sequence", "9"])
    (hexline,) = capsys.readouterr().out.split()
    assert code == 0
    _, (obj,) = run_cli(capsys, "decode", hexline)
    assert obj["transport"]["sequence"] == 9
    assert obj["fields"].keys() == fields.keys()
    for key, value in fields.items():
        assert obj["fields"][key] == pytest.approx(value, abs=1e-4)


def test_encode_large_message_fragments_and_decode_reassembles(
    capsys: pytest.CaptureFixture[str],
) -> None:
    name = "x" * 200
    code = main(["encode", "ReportIdentification", "--json",
                 json.dumps({"query_type": 2, "type": 10001, "identification": name}),
                 "--source", "126.1.199", "--destination", "42.1.1", "--mtu", "64"])
    lines = capsys.readouterr().out.split()
    assert code == 0 and len(lines) == 4  # 206-byte payload in 64-byte pieces
    _, objs = run_cli(capsys, "decode", *reversed(lines))
    assert len(objs) == 1 and objs[0]["fields"]["identification"] == name


def test_encode_reports_bad_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["encode", "NoSuchMessage", "--source", "1.1.1", "--destination", "2.1.1"]) == 2
    assert "unknown message" in capsys.readouterr().err
    assert main(["encode", "ReportGlobalPose", "--json", '{"latitude": 91}',
                 "--source", "1.1.1", "--destination", "2.1.1"]) == 2
    assert "latitude" in capsys.readouterr().err


BATTERY = (Path(__file__).resolve().parents[2] / "profiles" / "examples" / "battery"
           / "BatteryPack.xml")


def test_encode_a_custom_message_with_its_jsidl(capsys: pytest.CaptureFixture[str]) -> None:
    fields = {"voltage": 48.2, "current": -12.5, "state_of_charge": 81.0, "pack_state": 2}
    assert main(["encode", "--jsidl", str(BATTERY), "ReportBatteryPack", "--json",
                 json.dumps(fields), "--source", "77.1.3", "--destination", "200.1.1"]) == 0
    (datagram,) = capsys.readouterr().out.split()
    # the bytes the JSIDL lays out: code, presence vector (pack_state), then the fields
    assert "c1f002" in datagram
    # --jsidl takes one file, so the positional argument may come after it
    code, (obj,) = run_cli(capsys, "decode", "--jsidl", str(BATTERY), datagram)
    assert code == 0 and obj["message"] == "ReportBatteryPack"
    assert obj["source"] == "77.1.3" and obj["fields"]["pack_state"] == 2
    assert obj["fields"]["voltage"] == pytest.approx(48.2, abs=0.01)
    assert obj["fields"]["current"] == pytest.approx(-12.5, abs=0.01)


def test_encode_a_custom_message_without_its_jsidl_says_so(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["encode", "ReportBatteryPack", "--source", "77.1.3",
                 "--destination", "200.1.1"]) == 2
    assert "a message of your own needs --jsidl FILE" in capsys.readouterr().err
    assert main(["encode", "ReportBatteryPack", "--jsidl", "nowhere.xml", "--source",
                 "77.1.3", "--destination", "200.1.1"]) == 2
    assert "nowhere.xml: no such JSIDL file or directory" in capsys.readouterr().err
