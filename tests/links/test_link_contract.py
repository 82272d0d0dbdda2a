"""The Link contract: URL selection, options, counters, the loop:// link, the mirror, CLI."""

from __future__ import annotations

import asyncio
import json
import socket
import threading
import time
from pathlib import Path

import pytest
from linkkit import Pty, collect, free_port, msg, run, until

from edge_vis.cli import main
from edge_vis.errors import ConfigError, PluginNotFoundError
from edge_vis.jaus.address import BROADCAST, JausAddress
from edge_vis.jaus.pcap import read_udp
from edge_vis.jaus.serial_framing import frame
from edge_vis.jaus.transport import pack_datagram, unpack_datagram
from edge_vis.routing.link import LinkUrl, create_link
from edge_vis.routing.router import Router
from edge_vis.shell.mirror import Mirror
from edge_vis.tools.testing import MemoryLink, RouterNode

A = JausAddress(1, 1, 1)
B = JausAddress(2, 1, 1)
C = JausAddress(3, 1, 1)


def test_url_parsing() -> None:
    url = LinkUrl.parse("udp://0.0.0.0:3794?multicast=239.255.0.1&peers=10.0.0.5:3794")
    assert (url.scheme, url.host, url.port) == ("udp", "0.0.0.0", 3794)
    assert url.options["peers"] == "10.0.0.5:3794"
    assert LinkUrl.parse("serial:///dev/ttyUSB0?baud=57600").path == "/dev/ttyUSB0"
    assert LinkUrl.parse("loop://Bench").host == "Bench"


def test_bad_urls_and_options_name_the_problem() -> None:
    with pytest.raises(ConfigError, match="not a link URL"):
        LinkUrl.parse("/dev/ttyUSB0")
    with pytest.raises(PluginNotFoundError, match=r"udpp.*installed: .*udp"):
        create_link("udpp://0.0.0.0:3794")
    with pytest.raises(ConfigError, match=r"url\.bsud: .*unknown option \(known: .*baud"):
        create_link("serial:///dev/ttyUSB0?bsud=57600")
    with pytest.raises(ConfigError, match=r"mtu=.abc. is not an integer"):
        create_link("udp://127.0.0.2:3794?mtu=abc")
    with pytest.raises(ConfigError, match="not a multicast group"):
        create_link("udp://0.0.0.0:3794?multicast=10.0.0.1")


def test_loop_links_join_a_bus_and_count() -> None:
    async def scenario() -> None:
        links = [create_link(f"loop://bus?addr={n}", name=n) for n in "abc"]
        inbox: dict[str, list[tuple[object, int]]] = {n: [] for n in "abc"}
        for link in links:
            await link.open(lambda name, peer, pkts: inbox[name].extend(
                (peer, p.sequence) for p in pkts))
        a, b, _ = links
        a.send([msg(A, BROADCAST, sequence=1)])
        a.send([msg(A, B, sequence=2)], "b")
        assert isinstance(b, MemoryLink)
        b.inject(b"\x02\x00garbage", "x")
        await asyncio.sleep(0.01)
        assert inbox == {"a": [], "b": [("a", 1), ("a", 2)], "c": [("a", 1)]}
        stats = b.stats()
        assert stats.messages_in == 2 and stats.malformed == 1
        assert stats.peers["a"].messages_in == 2 and stats.peers["x"].malformed == 1
        assert a.stats().as_dict()["messages_out"] == 2
        for link in links:
            await link.close()

    run(scenario())


def test_router_nodes_over_loop_links_relay_between_two_buses() -> None:
    async def scenario() -> None:
        relay = RouterNode(Router([JausAddress(9, 1, 1)]), [
            create_link("loop://left?addr=relay", name="left"),
            create_link("loop://right?addr=relay", name="right")])
        relay.router.set_relay("left", "right")
        a = RouterNode(Router([A]), [create_link("loop://left?addr=a", name="l")])
        c = RouterNode(Router([C]), [create_link("loop://right?addr=c", name="r")])
        for n in (relay, a, c):
            await n.start()
        a.send(msg(A, C, b"\x07"))
        (got,) = await collect(c.delivered, 1)
        assert got.packet.payload[-1] == 7 and got.peer == "relay"
        await until(lambda: a.router.stats().pending_acks == 0)
        for n in (relay, a, c):
            await n.stop()

    run(scenario())


@pytest.mark.serial
def test_mirror_writes_serial_traffic_as_pcap_that_decode_reads(tmp_path: Path) -> None:
    pcap = tmp_path / "radio.pcap"

    async def scenario() -> None:
        radio = Pty()
        link = create_link(f"serial://{radio.path}?baud=115200", name="radio")
        mirror = Mirror(pcap=pcap)
        mirror.attach(link)
        got: list[int] = []
        await link.open(lambda n, p, pkts: got.extend(x.sequence for x in pkts))
        radio.write(frame(msg(B, A, sequence=5)) + frame(msg(B, A, sequence=6)))
        await until(lambda: len(got) == 2)
        link.send([msg(A, B, sequence=1)])
        await link.close()
        mirror.close()
        radio.close()

    run(scenario())
    datagrams = list(read_udp(pcap.read_bytes()))
    assert [unpack_datagram(d.payload)[0].sequence for d in datagrams] == [5, 6, 1]
    assert datagrams[0].destination == ("127.0.0.1", 3794)
    assert datagrams[2].source == ("127.0.0.1", 3794)
    assert main(["decode", str(pcap)]) == 0


def test_links_command_reports_traffic_and_mirrors_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(("127.0.0.2", "127.0.0.3"))
    pcap = tmp_path / "heard.pcap"
    data = pack_datagram([msg(B, A, sequence=3)])

    def talk() -> None:
        time.sleep(0.3)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.3", 0))
            for _ in range(3):
                s.sendto(data, ("127.0.0.2", port))
            s.sendto(b"\x07junk", ("127.0.0.2", port))

    thread = threading.Thread(target=talk)
    thread.start()
    status = main(["links", "--link", f"udp://127.0.0.2:{port}", "--listen", "0.8",
                   "--mirror-pcap", str(pcap)])
    thread.join()
    out = capsys.readouterr().out
    assert status == 0
    assert "in:  3 messages" in out and "malformed: 1" in out
    assert len(list(read_udp(pcap.read_bytes(), port=None))) == 3
    assert main(["links", "--link", "serial:///dev/does-not-exist", "--listen", "0"]) == 1
    assert "state: error" in capsys.readouterr().out


def test_mirror_copies_to_a_loopback_udp_port() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as listener:
        listener.bind(("127.0.0.1", 0))
        listener.settimeout(2)
        mirror = Mirror(udp_port=listener.getsockname()[1])
        packets = [msg(A, B, sequence=4), msg(A, B, sequence=5)]
        mirror.tap("radio", "out", "/dev/ttyUSB0", packets)
        data = listener.recv(65535)
        mirror.close()
        mirror.close()
    assert unpack_datagram(data) == packets
    assert mirror.copied == 1 and mirror.dropped == 0


def test_links_command_json_output(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(("127.0.0.2",))
    assert main(["links", "--link", f"udp://127.0.0.2:{port}?name=lan", "--listen", "0",
                 "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)
    assert entry["state"] == "open" and entry["mtu"] == 4079 and entry["malformed"] == 0
