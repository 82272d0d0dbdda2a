"""The serial link on real pseudo-terminals: framing on the line, pacing, unplug/replug."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

import pytest
from linkkit import Pty, msg, run, until

from edge_vis.errors import LinkError
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.serial_framing import SerialDeframer, SerialFrame, frame
from edge_vis.jaus.transport import Packet
from edge_vis.routing.link import Peer, create_link
from links.serial import SerialLink

pytestmark = pytest.mark.serial

ROBOT = JausAddress(126, 1, 199)
OCU = JausAddress(42, 1, 1)


class Inbox:
    """A deliver callback recording (peer, packet)."""

    def __init__(self) -> None:
        self.items: list[tuple[Peer, Packet]] = []

    def __call__(self, link: str, peer: Peer, packets: list[Packet]) -> None:
        self.items += [(peer, p) for p in packets]


def read_frames(pty: Pty, deframer: SerialDeframer) -> list[Packet]:
    return [r.packet for r in deframer.feed(pty.read()) if isinstance(r, SerialFrame)]


def test_url_options() -> None:
    link = create_link("serial:///dev/ttyUSB0?baud=57600&rtscts=1")
    assert isinstance(link, SerialLink)
    assert (link.path, link.baud, link.rtscts) == ("/dev/ttyUSB0", 57600, True)
    assert link.bandwidth_bps == 57600 * 8 / 10


def test_frames_both_ways_on_a_pty() -> None:
    async def scenario() -> None:
        radio = Pty()
        link = create_link(f"serial://{radio.path}?baud=115200")
        inbox = Inbox()
        await link.open(inbox)
        try:
            noise = b"\xff\x00noise"
            radio.write(frame(msg(ROBOT, OCU, sequence=1)) + noise
                        + frame(msg(ROBOT, OCU, sequence=2)))
            await until(lambda: len(inbox.items) == 2)
            assert [p.sequence for _, p in inbox.items] == [1, 2]
            assert inbox.items[0][0] == radio.path  # peer = the device
            await until(lambda: link.stats().malformed == 1)
            out = [msg(OCU, ROBOT, bytes([i]) * 30, sequence=i) for i in range(5)]
            link.send(out)
            deframer = SerialDeframer()
            got: list[Packet] = []

            def drained() -> bool:
                got.extend(read_frames(radio, deframer))
                return len(got) == 5

            await until(drained)
            assert got == out
        finally:
            await link.close()
            radio.close()

    run(scenario())


def test_writes_are_paced_to_the_baud_rate() -> None:
    async def scenario() -> None:
        radio = Pty()
        link = create_link(f"serial://{radio.path}?baud=9600")  # 960 bytes/s
        await link.open(Inbox())
        loop = asyncio.get_running_loop()
        try:
            packets = [msg(OCU, ROBOT, b"\x00" * 60, sequence=i) for i in range(8)]
            total = sum(len(frame(p)) for p in packets)  # about 720 bytes = 0.75 s at 9600
            start = loop.time()
            link.send(packets)
            deframer = SerialDeframer()
            got: list[Packet] = []
            # the first bytes leave at once; the rest must trickle out at the line's pace
            await asyncio.sleep(0.2)
            got.extend(read_frames(radio, deframer))
            assert len(got) < 8
            assert link.stats().queue_depth > 0

            def drained() -> bool:
                got.extend(read_frames(radio, deframer))
                return len(got) == 8

            await until(drained, timeout=5)
            assert loop.time() - start >= 0.8 * total / 960
        finally:
            await link.close()
            radio.close()

    run(scenario())


def test_unplugged_device_comes_back_without_restart(tmp_path: Path) -> None:
    async def scenario() -> None:
        first = Pty()
        device = tmp_path / "ttyRADIO"
        device.symlink_to(first.path)
        link = create_link(f"serial://{device}?baud=115200&reopen=0.1")
        inbox = Inbox()
        states: list[str] = []
        await link.open(inbox, lambda name, state, reason: states.append(state))
        second = None
        try:
            first.write(frame(msg(ROBOT, OCU, sequence=1)))
            await until(lambda: len(inbox.items) == 1)
            first.close()  # USB radio pulled out
            device.unlink()
            await until(lambda: link.state == "down")
            link.send([msg(OCU, ROBOT)])  # dropped and counted, not raised
            assert link.stats().drops.get("link down") == 1
            await asyncio.sleep(0.3)  # reopen attempts fail while it is gone
            assert link.state == "down"
            second = Pty()  # plugged back in: a new device node behind the same name
            os.symlink(second.path, str(device) + ".new")
            os.replace(str(device) + ".new", device)
            loop = asyncio.get_running_loop()
            back = loop.time()
            await until(lambda: link.state == "open", timeout=2.0)
            assert loop.time() - back < 2.0
            second.write(frame(msg(ROBOT, OCU, sequence=2)))
            await until(lambda: len(inbox.items) == 2)
            link.send([msg(OCU, ROBOT, sequence=9)])
            deframer = SerialDeframer()
            got: list[Packet] = []

            def arrived() -> bool:
                got.extend(read_frames(second, deframer))  # type: ignore[arg-type]
                return bool(got)

            await until(arrived)
            assert got[0].sequence == 9
            assert states == ["down", "open"]
            assert isinstance(link, SerialLink) and link.reopened == 1
        finally:
            await link.close()
            if second is not None:
                second.close()

    run(scenario())


def test_a_device_in_use_is_refused_not_shared() -> None:
    async def scenario() -> None:
        radio = Pty()
        first = create_link(f"serial://{radio.path}")
        second = create_link(f"serial://{radio.path}")
        await first.open(Inbox())
        try:
            with pytest.raises(LinkError, match="cannot open"):
                await second.open(Inbox())
        finally:
            await first.close()
            await second.close()
            radio.close()

    run(scenario())


def test_urgent_frame_jumps_the_write_buffer_whole() -> None:
    """A paced 9,600 baud line with 1.5 s of frames waiting: an urgent frame goes out
    right after the frame being written (never inside it), ahead of the rest, and every
    frame still arrives intact."""
    async def scenario() -> None:
        radio = Pty()
        link = create_link(f"serial://{radio.path}?baud=9600")
        await link.open(Inbox())
        loop = asyncio.get_running_loop()
        try:
            packets = [msg(OCU, ROBOT, bytes([0x10, i]) * 40, sequence=i) for i in range(18)]
            link.send(packets)  # DLE bytes: stuffed frames, 170-odd bytes each
            await asyncio.sleep(0.25)  # partway into the second frame or so
            urgent = msg(OCU, ROBOT, b"\x06\x00\x01\x00", sequence=99)
            sent_at = loop.time()
            link.send_urgent([urgent])
            deframer = SerialDeframer()
            got: list[Packet] = []
            arrived: float | None = None

            def drained() -> bool:
                nonlocal arrived
                got.extend(read_frames(radio, deframer))
                if arrived is None and urgent in got:
                    arrived = loop.time()
                return len(got) == 19

            await until(drained, timeout=8)
            assert arrived is not None and arrived - sent_at < 0.4
            position = got.index(urgent)
            assert 1 <= position <= 3, f"urgent frame at {position}"
            assert [p for p in got if p != urgent] == packets  # none cut, none lost
            assert not deframer.feed(b"", loop.time() + 10)  # no broken frame left over
        finally:
            await link.close()
            radio.close()

    run(scenario())
