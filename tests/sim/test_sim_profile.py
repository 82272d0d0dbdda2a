"""Simulation profiles and the malformed frames the simulator injects."""

from __future__ import annotations

from pathlib import Path

import pytest

from edge_vis.catalogue import default_catalogue
from edge_vis.errors import ConfigError, DecodeError
from edge_vis.jaus import serial_framing as jserial
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import Packet, pack_datagram, unpack_datagram
from edge_vis.tools.sim.profile import load_profile, parse_profile
from edge_vis.tools.sim.runner import corrupt_datagram, corrupt_frame

PROFILES = Path(__file__).resolve().parents[2] / "profiles" / "sim"


def test_shipped_profiles_load() -> None:
    fleet = load_profile(PROFILES / "fleet.toml")
    assert [(v.name, v.kind, v.is_pty) for v in fleet.vehicles] == [
        ("ugv-alpha", "ugv", False), ("ugv-bravo", "ugv", False), ("uuv-delta", "uuv", True)]
    bravo = fleet.vehicles[1]
    assert bravo.faults.dropout_reboot and bravo.faults.malformed_rate > 0
    assert len({v.seed for v in fleet.vehicles}) == 3
    for path in PROFILES.glob("*.toml"):
        assert load_profile(path).vehicles


def test_every_problem_is_reported_at_once() -> None:
    with pytest.raises(ConfigError) as info:
        parse_profile({"vehicles": [
            {"name": "a", "subsystem": 70000, "link": "udp://10.0.0.1:3794", "colour": 1},
            {"name": "a", "subsystem": 5, "link": "pty",
             "faults": {"dropout": {"every": 5, "duration": 9}, "explode": True}},
        ]}, "x.toml")
    text = str(info.value)
    for needle in ("vehicles[0].subsystem: must be in 1..65534, got 70000", "loopback",
                   "vehicles[0].colour: unknown key", "duration 9 must be below every 5",
                   "vehicles[1].faults.explode: unknown key",
                   "'a' is also used by a"):
        assert needle in text, needle


def test_injected_defects_are_caught_by_real_decoders() -> None:
    cat = default_catalogue()
    packet = Packet(JausAddress(1, 1, 1), JausAddress(2, 1, 1), cat.encode("ReportStatus", {
        "status": 1, "reserved": 0}), sequence=9)
    datagram = pack_datagram([packet])
    for how in ("truncated", "bad_size", "bad_version"):
        with pytest.raises(DecodeError):
            unpack_datagram(corrupt_datagram(datagram, how))
    frame = jserial.frame(packet)
    for how in ("truncated", "bad_size", "bad_version"):
        deframer = jserial.SerialDeframer()
        items = deframer.feed(corrupt_frame(frame, how) + frame, 0.0)
        assert [type(i).__name__ for i in items][-1] == "SerialFrame"  # the next one is fine
        assert any(isinstance(i, jserial.SerialError) for i in items), how
