"""``[routing] forward``: the relay passes JAUS traffic between its links as a node manager.

The relay's runtime (what ``edge-vis run`` starts) with a UDP link and a serial link on a
real pty: a JAUS peer on UDP (another OCU) talks to a component on the serial side (a
robot) through it, and the robot's reply comes back. The peers' wire format, serial
framing and CRC are written here from the AS5669A layout, not taken from the relay.
"""

from __future__ import annotations

import asyncio
import os
import socket
import struct
import tty
from collections.abc import Awaitable
from pathlib import Path
from typing import Any, TypeVar

import pytest
from linkkit import free_port, until

from edge_vis.cli import main
from edge_vis.config import from_mapping
from edge_vis.jaus.address import JausAddress
from edge_vis.shell import sharedloop
from edge_vis.shell.relay import Runtime
from edge_vis.shell.reload import Reloader

RELAY = JausAddress(200, 1, 1)
OCU = JausAddress(42, 1, 1)
ROBOT = JausAddress(126, 1, 199)
HOST, OCU_IP = "127.0.0.2", "127.0.0.3"
T = TypeVar("T")
DLE, SOH, STX, ETX = 0x10, 0x01, 0x02, 0x03


# -- the peers' side of the wire, written from AS5669A ---------------------------------------
def jaus_id(address: JausAddress) -> int:
    return address.subsystem << 16 | address.node << 8 | address.component


def message(dst: JausAddress, src: JausAddress, payload: bytes, seq: int) -> bytes:
    """One general transport message: type, data size, flags (normal priority), dst, src,
    payload, sequence number; little-endian."""
    return struct.pack("<BHBII", 0, 14 + len(payload), 1, jaus_id(dst), jaus_id(src)) + \
        payload + struct.pack("<H", seq)


def parties(wire: bytes) -> tuple[int, int]:
    """(destination id, source id) of a general transport message."""
    return struct.unpack_from("<II", wire, 4)  # type: ignore[return-value]


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/MCRF4XX, bit by bit."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
    return crc


def stuffed(data: bytes) -> bytes:
    return data.replace(b"\x10", b"\x10\x10")


def serial_frame(wire: bytes) -> bytes:
    head = struct.pack("<BH", 2, len(wire))
    head_crc = struct.pack("<H", crc16(head))
    body_crc = struct.pack("<H", crc16(head_crc + wire, crc16(head)))
    return bytes((DLE, SOH)) + stuffed(head) + bytes((DLE, STX)) + stuffed(head_crc) + \
        stuffed(wire) + bytes((DLE, ETX)) + stuffed(body_crc)


class Robot:
    """The serial side: a pty whose far end the relay's serial link opens."""

    def __init__(self) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(self.master, False)
        self.buffer = b""
        self.messages: list[bytes] = []

    def read(self) -> list[bytes]:
        """Every whole frame received so far, its CRCs checked, as messages."""
        while True:
            try:
                data = os.read(self.master, 65536)
            except (BlockingIOError, OSError):
                break
            if not data:
                break
            self.buffer += data
        while True:
            start = self.buffer.find(bytes((DLE, SOH)))
            if start < 0:
                break
            tokens, end = self._unstuff(self.buffer, start + 2)
            if tokens is None:
                break
            self.buffer = self.buffer[end:]
            head, head_crc, wire, body_crc = tokens
            assert struct.unpack("<H", head_crc)[0] == crc16(head)
            assert struct.unpack("<H", body_crc)[0] == crc16(head_crc + wire, crc16(head))
            self.messages.append(wire)
        return self.messages

    @staticmethod
    def _unstuff(buf: bytes, pos: int) -> tuple[list[bytes] | None, int]:
        """head up to DLE STX, 2 CRC bytes, message up to DLE ETX, 2 CRC bytes."""
        parts: list[bytes] = []
        current = bytearray()
        want = [None, 2, None, 2]  # None: up to the next marker
        while len(parts) < 4:
            if pos >= len(buf):
                return None, pos
            byte = buf[pos]
            if byte == DLE:
                if pos + 1 >= len(buf):
                    return None, pos
                nxt = buf[pos + 1]
                pos += 2
                if nxt == DLE:
                    current.append(DLE)
                else:  # STX or ETX: the end of a marked part
                    parts.append(bytes(current))
                    current = bytearray()
                    continue
            else:
                current.append(byte)
                pos += 1
            if want[len(parts)] == len(current):
                parts.append(bytes(current))
                current = bytearray()
        return parts, pos

    def send(self, wire: bytes) -> None:
        os.write(self.master, serial_frame(wire))

    def from_ocu(self) -> list[bytes]:
        return [w for w in self.read() if parties(w)[1] == jaus_id(OCU)]

    def close(self) -> None:
        os.close(self.master)


class Ocu:
    """The UDP side: another JAUS component on the relay's LAN."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((OCU_IP, port))
        self.sock.setblocking(False)
        self.received: list[bytes] = []

    def send(self, wire: bytes) -> None:
        self.sock.sendto(b"\x02" + wire, (HOST, self.port))

    def from_robot(self) -> list[bytes]:
        while True:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                break
            assert data[0] == 2
            pos = 1
            while pos < len(data):
                size = struct.unpack_from("<H", data, pos + 1)[0]
                self.received.append(data[pos:pos + size])
                pos += size
        return [w for w in self.received if parties(w)[1] == jaus_id(ROBOT)]

    def close(self) -> None:
        self.sock.close()


def profile_data(port: int, robot: Robot, udp_options: str = "",
                 routing: dict[str, Any] | None = None) -> dict[str, Any]:
    data: dict[str, Any] = {
        "relay": {"jaus_id": str(RELAY)},
        "links": {
            "lan": {"url": f"udp://{HOST}:{port}?multicast=off&peers={OCU_IP}:{port}"
                           + udp_options},
            "radio": {"url": f"serial://{robot.path}?baud=115200"},
        },
        "translators": {"enabled": ["core"]},
        "access": {"any_operator": True},
    }
    if routing is not None:
        data["routing"] = routing
    return data


def run(coro: Awaitable[T], timeout: float = 20.0) -> T:
    async def guarded() -> T:
        return await asyncio.wait_for(coro, timeout)

    return sharedloop.run(guarded())  # the loop link threads need


QUERY = b"\x02\x2b"  # QueryStatus, a 2-byte message id and no body


async def round_trip(ocu: Ocu, robot: Robot, seq: int) -> None:
    """OCU -> robot, then the robot's answer -> OCU, each checked byte for byte."""
    ask = message(ROBOT, OCU, QUERY, seq)
    before_robot, before_ocu = len(robot.from_ocu()), len(ocu.from_robot())
    ocu.send(ask)
    await until(lambda: len(robot.from_ocu()) > before_robot)
    assert robot.from_ocu()[-1] == ask  # passed on unchanged
    answer = message(OCU, ROBOT, b"\x02\x44\x02\x00\x00\x00", seq)  # ReportStatus
    robot.send(answer)
    await until(lambda: len(ocu.from_robot()) > before_ocu)
    assert ocu.from_robot()[-1] == answer


# -- the tests -------------------------------------------------------------------------------
def test_forwarding_carries_a_peer_on_udp_to_a_robot_on_serial_and_back() -> None:
    """``forward = [["lan", "radio"]]`` with the UDP link's ``cycle=0.02&thread=1``: a
    query from an OCU on the LAN reaches the robot on the radio, the robot's answer comes
    back, and a stream that follows (both ends known now: the pass-through path, which
    the runtime offers its links) arrives whole and in order."""
    robot = Robot()
    port = free_port((HOST, OCU_IP))
    ocu = Ocu(port)
    profile = from_mapping(profile_data(port, robot, "&cycle=0.02&thread=1",
                                        {"forward": [["lan", "radio"]]}), file="fwd.toml")

    async def scenario() -> None:
        runtime = Runtime(profile, publisher_factory=None)
        await runtime.start()
        taken: list[int] = []
        forward = runtime.router.forward

        def counted(*args: Any) -> Any:
            result = forward(*args)
            taken.append(result[0])
            return result

        runtime.router.forward = counted  # type: ignore[method-assign]
        try:
            await round_trip(ocu, robot, 1)
            stream = [message(ROBOT, OCU, QUERY + bytes((i,)), 100 + i) for i in range(50)]
            for wire in stream:
                ocu.send(wire)
            await until(lambda: len(robot.from_ocu()) >= 51)
            assert robot.from_ocu()[1:] == stream
            assert runtime.router.counters["forwarded"] >= 52
            assert sum(taken) >= 40  # the stream went the pass-through path
        finally:
            await runtime.stop()

    try:
        run(scenario())
    finally:
        ocu.close()
        robot.close()


def test_nothing_crosses_by_default_and_a_reload_switches_forwarding() -> None:
    """Without ``[routing]`` the relay passes nothing between its links (counted as
    dropped); a reload that adds ``forward`` applies at once, one that removes it stops
    it again."""
    robot = Robot()
    port = free_port((HOST, OCU_IP))
    ocu = Ocu(port)
    off = from_mapping(profile_data(port, robot), file="site.toml")
    on = from_mapping(profile_data(port, robot, routing={"forward": [["radio", "lan"]]}),
                      file="site.toml")

    async def scenario() -> None:
        runtime = Runtime(off, publisher_factory=None)
        await runtime.start()
        try:
            ocu.send(message(ROBOT, OCU, QUERY, 1))
            robot.send(message(OCU, ROBOT, b"\x02\x44\x02\x00\x00\x00", 1))
            await until(lambda: runtime.router.counters["dropped: relay off"] >= 1)
            await asyncio.sleep(0.3)
            assert robot.from_ocu() == [] and ocu.from_robot() == []
            assert runtime.forwarding == frozenset()

            profiles = iter([on, off])
            reloader = Reloader(runtime, lambda: next(profiles))
            result = reloader.reload()
            assert result is not None and result.restart_needed == ()
            assert [c.key for c in result.changes] == ["routing.forward"]
            await round_trip(ocu, robot, 2)

            reloader.reload()
            ocu.send(message(ROBOT, OCU, QUERY, 3))
            robot.send(message(OCU, ROBOT, b"\x02\x44\x02\x00\x00\x00", 3))
            await asyncio.sleep(0.4)
            assert len(robot.from_ocu()) == 1 and len(ocu.from_robot()) == 1
        finally:
            await runtime.stop()

    try:
        run(scenario())
    finally:
        ocu.close()
        robot.close()


def test_check_names_each_bad_forwarding_setting(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "site.toml"
    path.write_text("""
[relay]
jaus_id = "200.1.1"
[links.lan]
url = "udp://127.0.0.1:3794"
[links.radio]
url = "serial:///dev/ttyUSB0?baud=57600"
[routing]
forward = [["lan", "radio"], ["lan", "lan"], ["radio", "sat"], ["lan"]]
[access]
any_operator = true
""")
    assert main(["check", str(path)]) != 0
    out = capsys.readouterr()
    lines = sorted(line.strip() for line in (out.out + out.err).splitlines()
                   if line.startswith("  "))
    assert lines == sorted([
        f"{path}: routing.forward[1]: link 'lan' is forwarded to itself (named twice in "
        "one group)",
        f"{path}: routing.forward[2]: unknown link 'sat' (links: lan, radio)",
        f"{path}: routing.forward[3]: name at least two links to forward between, "
        'e.g. ["lan", "radio"]',
    ])
    good = path.read_text().replace(', ["lan", "lan"], ["radio", "sat"], ["lan"]', "")
    path.write_text(good)
    assert main(["check", str(path)]) == 0
    assert ", forwarding between lan and radio" in capsys.readouterr().out
    path.write_text(path.read_text().replace("forward = [", 'forward = ["lan", '))
    assert main(["check", str(path)]) != 0
    out = capsys.readouterr()
    assert "routing.forward[0]: expected an array of str, got str 'lan'" in out.out + out.err


def test_a_reload_forwarding_to_a_link_not_yet_open_says_it_needs_a_restart(
        caplog: pytest.LogCaptureFixture) -> None:
    """A reload that adds a link and forwards to it: links open at start, so the relay
    forwards only between the open ones and logs that the rest waits for a restart."""
    robot = Robot()
    port = free_port((HOST, OCU_IP))
    data = profile_data(port, robot, routing={"forward": [["lan", "radio"]]})
    before = from_mapping(data, file="site.toml")
    data["links"]["sat"] = {"url": f"udp://{HOST}:{free_port((HOST,))}?multicast=off"}
    data["routing"] = {"forward": [["lan", "radio", "sat"]]}
    after = from_mapping(data, file="site.toml")

    async def scenario() -> None:
        runtime = Runtime(before, publisher_factory=None)
        await runtime.start()
        try:
            result = Reloader(runtime, lambda: after).reload()
            assert result is not None and "links" in result.restart_needed
            assert runtime.forwarding == {("lan", "radio"), ("radio", "lan")}
            assert "routing.forward: link 'sat' is not open (links are opened at start)" \
                in caplog.text
        finally:
            await runtime.stop()

    try:
        with caplog.at_level("WARNING"):
            run(scenario())
    finally:
        robot.close()
