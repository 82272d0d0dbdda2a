"""Footprint in one run: CPU per relayed message, memory through a burst, the idle relay.

    .venv/bin/python bench/footprint.py                   # everything (about 3 minutes)
    .venv/bin/python bench/footprint.py --settle 20 --seconds 3   # shorter
    .venv/bin/python bench/footprint.py --bundle dist/edge-vis.pyz --no-dds
    .venv/bin/python bench/footprint.py --only forwarder --callgrind   # + instructions/msg
    .venv/bin/python bench/footprint.py --only forwarder --burst 0 --cycles 2 --paths serial:2
    .venv/bin/python bench/footprint.py --only forwarder --burst 0 --cycles 10 \
        --paths serial:10,thread:10,bare:10,tbare:10          # the link thread beside the loop
    .venv/bin/python bench/footprint.py --only run            # edge-vis run forwarding

Parts, each in its own process so that one does not colour another's memory:

1. **Forwarder** (the router between two links, as in ``bench/router.py``: a
   :class:`~links.udp.UdpLink` in, a :class:`~links.serial.SerialLink` on a pty with JAUS
   serial framing and CRC, or another ``UdpLink``, out; relay switch on, static route).
   This process offers one small JAUS message per UDP datagram at 1,000 and 2,000 msg/s
   and reads what comes out (pty master / UDP socket). The forwarder's CPU comes from its
   own ``getrusage`` (user + system, microsecond resolution), asked for over a pipe
   before and after each window: CPU time, not wall-clock time, so other work on the
   machine changes it far less (it still rises when they compete for caches and cores);
   us/message = CPU seconds of the window / messages delivered. ``--callgrind`` adds
   user-space instructions per message, which do not depend on the load at all. The
   *floor* row is a bare loop on the same event loop with the same system calls (read
   every datagram waiting, write it to the pty) and none of the logic: what Python and
   the kernel cost before edge-vis does anything. Then, udp->serial only: a burst of
   ``--burst`` messages as fast as this process can send them (at most 1,024 in flight,
   so the kernel drops none), the peak resident memory during it (``VmHWM`` after
   ``clear_refs``), and the resident memory over ``--settle`` seconds after it
   (``VmRSS``), against the idle figure before. udp->serial and the floor are measured
   again with each UDP receive cycle of ``--cycles`` (the link's ``cycle`` option; the
   floor reads on the same timer), and so is udp->serial with the UDP link's ``thread=1``
   (reading, routing and writing on the link's own thread, which sleeps the cycle) beside
   its floor, a plain thread doing the same system calls; every path reports the time
   from send to arrival at the sink (p50 / p99) at each rate. ``--paths
   serial:5,thread:10,bare:0,tbare:10`` picks forwarders.
2. **JAUS report -> DDS sample**: ``bench/engine.py``'s pipeline (router, catalogue,
   engine, mobility translator, ``DdsBridge.publish`` to a real Cyclone writer) fed
   ReportGlobalPose at a paced 1,000 reports/s; CPU = ``time.process_time`` (all threads,
   Cyclone's included) per report.
3. **The relay** ``edge-vis run`` with DDS and every translator: start-up to its first
   discovery query, idle CPU (``/proc/PID/stat``, 10 ms ticks) and resident memory, then
   with three simulated UGVs (``edge-vis sim``) sending three reports each at 10 Hz. The
   *floor* rows: the interpreter alone, and a fresh interpreter that imports exactly the
   modules a second, idle relay has loaded (asked for with SIGUSR1): what ``edge-vis run``
   costs before it holds any data of its own (not with ``--bundle``).

4. **edge-vis run forwarding** (``--only run``, or after the relay part): ``edge-vis run``
   itself (DDS on unless ``--no-dds``, every translator) with a profile whose ``[routing]
   forward = [["lan", "radio"]]`` joins a UDP link (``cycle=0.02&thread=1``) and a serial
   link on a pty, beside part 1's forwarder with the same links, in the same run: idle CPU,
   then 1,000 msg/s offered from a JAUS source on UDP to a component on the serial side
   (which spoke once first, so its route is learned, as a robot's is). Both processes are
   pinned to one core; the relay's CPU is its own ``getrusage`` (all threads), written to
   a file when it gets SIGUSR2; us/message = CPU seconds of the window / messages
   delivered (idle included: the relay's discovery, link status and DDS heartbeats).

Figures, not pass/fail; the targets are printed beside them.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import resource
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
import tty
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path

from forwarded import SOURCE, TARGET, Sink, message  # bench/forwarded.py

from edge_vis.catalogue import default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import unpack_datagram

RELAY_IP = "127.0.62.1"
LISTENER_IP = "127.0.62.9"
VEHICLE_IPS = ("127.0.62.11", "127.0.62.12", "127.0.62.13")
PORT = 3794
RATE = 10.0
#: reports the relay asks for at RATE (those a UGV simulator offers)
REPORTS = ("ReportGlobalPose", "ReportLocalPose", "ReportVelocityState")
CLK_TCK = os.sysconf("SC_CLK_TCK")


def relay_profile(domain: int, partition: str) -> str:
    peers = ",".join(f"{ip}:{PORT}" for ip in (LISTENER_IP, *VEHICLE_IPS))
    rates = "\n".join(f"{name} = {RATE}" for name in REPORTS)
    return f"""
[relay]
jaus_id = "200.1.1"
name = "footprint"

[links.lan]
url = "udp://{RELAY_IP}:{PORT}?peers={peers}&multicast=off"

[dds]
domain = {domain}
partitions = ["{partition}"]

[discovery]
period = 2.0

[report_rates]
{rates}
"""


def sim_profile() -> str:
    vehicles = []
    for i, ip in enumerate(VEHICLE_IPS):
        vehicles.append(f"""
[[vehicles]]
name = "ugv-{i + 1}"
kind = "ugv"
subsystem = {101 + i}
link = "udp://{ip}:{PORT}"
origin = {{ latitude = 36.60, longitude = -121.89 }}
""")
    return "seed = 1\n" + "".join(vehicles)


def cpu_seconds(pid: int) -> float:
    """utime + stime of every thread of ``pid``."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def memory(pid: int) -> dict[str, int]:
    """VmRSS and VmHWM in KiB."""
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = int(value.split()[0])
    return out


def cpu_share(pid: int, seconds: float, meanwhile: Callable[[], None] | None = None) -> float:
    """Fraction of one core used by ``pid`` over ``seconds`` of wall time.

    ``meanwhile`` is called every 50 ms (e.g. to drain a DDS reader whose history keeps
    only the latest sample).
    """
    c0, t0 = cpu_seconds(pid), time.monotonic()
    end = t0 + seconds
    while (left := end - time.monotonic()) > 0:
        time.sleep(min(left, 0.05) if meanwhile else left)
        if meanwhile is not None:
            meanwhile()
    return (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


def first_discovery(sock: socket.socket, timeout: float) -> float | None:
    """Wall-clock time of the first QueryIdentification received, or None."""
    catalogue = default_catalogue()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sock.settimeout(max(deadline - time.monotonic(), 0.01))
        try:
            data, _ = sock.recvfrom(65536)
        except TimeoutError:
            return None
        arrived = time.monotonic()
        for packet in unpack_datagram(data):
            if packet.message_code is not None and \
                    catalogue.decode(packet.payload).name == "QueryIdentification":
                return arrived
    return None




# -- part 1: the forwarder ----------------------------------------------------------------
FWD_IP = "127.0.63.1"
SENDER_IP = "127.0.63.2"
SINK_IP = "127.0.63.3"
FWD_RELAY = JausAddress(200, 1, 1)
BURST_WINDOW = 1024


def drain_to_pty(sock: socket.socket, buffer: memoryview, fd: int) -> int:
    """The floors' work: read every datagram waiting, one pty write for all behind frame
    starts (as the serial link); return how many were read."""
    frames: list[bytes] = []
    while True:
        try:
            size, _ = sock.recvfrom_into(buffer)
        except BlockingIOError:
            break
        frames.append(b"\x10\x01\x02" + buffer[:size].tobytes())
    if frames:
        os.write(fd, b"".join(frames))
    return len(frames)


def forwarder_main(in_port: int, out: str, cycle: float = 0.0, thread: bool = False) -> None:
    """The process under test: a router between a UDP link and ``out``; ``cycle`` is
    the UDP link's option of that name (and the bare loop's equivalent), ``thread`` its
    ``thread`` option.

    Reads commands from stdin: ``usage`` answers ``utime stime`` (seconds) on stdout;
    ``reset`` clears the peak resident memory; end of file stops it.
    """
    from edge_vis.routing.link import create_link
    from edge_vis.routing.router import Router
    from edge_vis.shell import sharedloop
    from edge_vis.tools.testing import RouterNode

    if (os.cpu_count() or 1) > 1:
        os.sched_setaffinity(0, {0})

    async def run() -> None:
        loop = asyncio.get_running_loop()
        done = loop.create_future()

        def command() -> None:
            line = sys.stdin.readline().strip()
            if not line:
                loop.remove_reader(sys.stdin.fileno())
                done.set_result(None)
            elif line == "usage":
                ru = resource.getrusage(resource.RUSAGE_SELF)
                print(f"{ru.ru_utime!r} {ru.ru_stime!r}", flush=True)

        loop.add_reader(sys.stdin.fileno(), command)
        if out.startswith("bare+"):
            await bare(loop, done)
            return
        if out.startswith("tbare+"):
            await bare_thread(done)
            return
        node = RouterNode(Router([FWD_RELAY]), [
            create_link(f"udp://{FWD_IP}:{in_port}?multicast=off"
                        + (f"&cycle={cycle:g}" if cycle else "")
                        + ("&thread=1" if thread else ""), name="in"),
            create_link(out, name="out"),
        ])
        await node.start()
        node.router.set_relay("in", "out")
        peer: object = out.split("//", 1)[1].split("?")[0]
        if out.startswith("udp"):
            host, port = out.split("peers=")[1].split(":")
            peer = (host, int(port))
        node.router.add_route(TARGET, "out", peer)  # type: ignore[arg-type]
        print("ready", flush=True)
        await done
        await node.stop()

    def floor_ends() -> tuple[socket.socket, int, memoryview]:
        """The floors' receiving socket, pty and read buffer (non-blocking)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind((FWD_IP, in_port))
        sock.setblocking(False)
        fd = os.open(out.split("//", 1)[1].split("?")[0], os.O_RDWR | os.O_NOCTTY)
        os.set_blocking(fd, False)
        return sock, fd, memoryview(bytearray(65535))

    async def bare(loop: asyncio.AbstractEventLoop, done: asyncio.Future[None]) -> None:
        """The floor: the same system calls on the same event loop, none of the logic
        (read every datagram waiting, write it to the pty behind a frame start)."""
        sock, fd, buffer = floor_ends()

        def drain() -> int:
            return drain_to_pty(sock, buffer, fd)

        def readable() -> None:  # with a cycle: as UdpLink, read on a timer while busy
            if drain() and cycle:
                loop.remove_reader(sock.fileno())
                loop.call_later(cycle, tick)

        def tick() -> None:
            if drain():
                loop.call_later(cycle, tick)
            else:
                loop.add_reader(sock.fileno(), readable)

        loop.add_reader(sock.fileno(), readable)
        print("ready", flush=True)
        await done
        sock.close()
        os.close(fd)

    async def bare_thread(done: asyncio.Future[None]) -> None:
        """The floor of ``thread=1``: the same system calls on a plain thread that waits
        in ``poll`` for the first datagram and sleeps the cycle between reads."""
        import threading

        sock, fd, buffer = floor_ends()
        stop = False

        def serve() -> None:
            poller = select.poll()
            poller.register(sock.fileno(), select.POLLIN)
            while not stop:
                if not poller.poll(200):
                    continue
                while drain_to_pty(sock, buffer, fd):
                    if cycle:
                        time.sleep(cycle)

        worker = threading.Thread(target=serve, daemon=True)
        worker.start()
        print("ready", flush=True)
        await done
        stop = True
        worker.join()
        sock.close()
        os.close(fd)

    sharedloop.run(run())


class Forwarder:
    """A forwarder process, its sink and the traffic this process sends it."""

    def _open_sender(self) -> None:
        """A free port for the forwarder's UDP link, and the socket that feeds it."""
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((FWD_IP, 0))
            self.in_port = s.getsockname()[1]
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.tx.bind((SENDER_IP, 0))
        self.tx.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)

    def __init__(self, kind: str, wrapper: Sequence[str] = (), cycle: float = 0.0) -> None:
        self.kind = kind
        self._open_sender()
        udp: socket.socket | None = None
        master: int | None = None
        if kind in ("serial", "bare", "thread", "tbare"):
            master, slave = os.openpty()
            tty.setraw(slave)
            out = f"serial://{os.ttyname(slave)}?baud=20000000&pace=0"
            if kind in ("bare", "tbare"):
                out = f"{kind}+" + out
            os.set_blocking(master, False)
            self._slave = slave
        else:
            udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            udp.bind((SINK_IP, 0))
            udp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
            udp.setblocking(False)
            out = f"udp://{FWD_IP}:0?multicast=off&peers={SINK_IP}:{udp.getsockname()[1]}"
        self.sink = Sink(udp, master)
        self.proc = subprocess.Popen(
            [*wrapper, sys.executable, __file__, "--forwarder", str(self.in_port), out,
             str(cycle), "thread" if kind == "thread" else ""],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None and self.proc.stdin is not None
        assert self.proc.stdout.readline().strip() == "ready"
        self.run = 0

    def cpu(self) -> float:
        """The forwarder's user + system CPU seconds so far."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write("usage\n")
        self.proc.stdin.flush()
        user, system = self.proc.stdout.readline().split()
        return float(user) + float(system)

    def offer(self, rate: float, seconds: float) -> tuple[int, float]:
        """Send at ``rate`` for ``seconds``; return (delivered, forwarder CPU seconds)."""
        got, cpu, _ = self.offer_timed(rate, seconds)
        return got, cpu

    def offer_timed(self, rate: float, seconds: float) -> tuple[int, float, list[int]]:
        """Send at ``rate`` for ``seconds``; return (delivered, forwarder CPU seconds,
        each message's time from send to arrival at the sink in ns; none for the bare
        loop, whose frames carry no CRC). The send time in each payload also keeps the
        runs distinct for the duplicate filter."""
        total = int(rate * seconds)
        if self.kind in ("bare", "tbare"):
            self.run += 1
            self.sink.count()
        else:
            self.sink.drain()
        cpu0 = self.cpu()
        start = time.monotonic()
        sent = counted = 0
        latencies: list[int] = []
        while sent < total:
            due = start + sent / rate
            wait = due - time.monotonic()
            if wait > 0:
                ready, _, _ = select.select([self.sink], [], [], wait)
                if ready:
                    counted += self._collect(latencies)
                continue
            self.tx.sendto(message(sent, time.perf_counter_ns()), (FWD_IP, self.in_port))
            sent += 1
        while counted < total:  # what is still in flight (up to 1 s of silence)
            ready, _, _ = select.select([self.sink], [], [], 1.0)
            if not ready:
                break
            counted += self._collect(latencies)
        return counted, self.cpu() - cpu0, latencies

    def _collect(self, latencies: list[int]) -> int:
        if self.kind in ("bare", "tbare"):
            return self.sink.count()
        arrived = time.perf_counter_ns()
        stamps = self.sink.drain()
        latencies += [arrived - s for s in stamps]
        return len(stamps)

    def burst(self, total: int) -> tuple[int, float]:
        """Send ``total`` messages as fast as possible (<= BURST_WINDOW in flight);
        return (delivered, seconds). What is in flight after 1 s without progress counts
        as lost, and sending goes on."""
        self.run += 1
        self.sink.count()
        start = last = time.monotonic()
        sent = received = lost = 0
        while sent < total:
            while sent - received - lost < BURST_WINDOW and sent < total:
                self.tx.sendto(message(sent, self.run), (FWD_IP, self.in_port))
                sent += 1
            ready, _, _ = select.select([self.sink], [], [], 0.2)
            got = self.sink.count() if ready else 0
            received += got
            if got:
                last = time.monotonic()
            elif time.monotonic() - last > 1.0:
                lost = sent - received
                last = time.monotonic()
        received += self._settle(total - received)
        return received, time.monotonic() - start

    def _settle(self, missing: int) -> int:
        """Collect what is still in flight (up to 1 s of silence)."""
        got = 0
        while got < missing:
            ready, _, _ = select.select([self.sink], [], [], 1.0)
            if not ready:
                break
            got += self.sink.count()
        return got

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(10)
        self.tx.close()
        if self.sink.udp is not None:
            self.sink.udp.close()
        if self.sink.fd is not None:
            os.close(self.sink.fd)
            os.close(self._slave)


def percentile(values: list[int], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(len(ordered) * q))]


def rss(pid: int) -> float:
    """Resident memory of ``pid`` in MiB."""
    return memory(pid)["VmRSS"] / 1024


KINDS = {"serial": "udp->serial", "udp": "udp->udp",
         "bare": "floor: bare asyncio udp->pty loop",
         "thread": "udp->serial, thread=1",
         "tbare": "floor: bare thread udp->pty loop"}
#: what is measured without a cycle, and with each cycle
NO_CYCLE = ("serial", "udp", "bare")
WITH_CYCLE = ("serial", "thread", "bare", "tbare")


def paths(args: argparse.Namespace) -> list[tuple[str, float, str]]:
    """(kind, cycle in s, label) of every forwarder measured: each path without a cycle,
    then udp->serial and the floor with each of ``--cycles``."""
    out = [(kind, 0.0, KINDS[kind]) for kind in NO_CYCLE]
    for ms in (c for c in args.cycles if c > 0):
        out += [(kind, ms / 1000, f"{KINDS[kind]}, cycle={ms:g} ms") for kind in WITH_CYCLE]
    return [p for p in out if not args.paths or p[2] in args.paths
            or f"{p[0]}:{p[1] * 1000:g}" in args.paths]


def forwarder_part(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    rows: list[tuple[str, str, str]] = []
    for kind, cycle, label in paths(args):
        fwd = Forwarder(kind, cycle=cycle)
        try:
            time.sleep(1.0)
            cpu0, t0 = fwd.cpu(), time.monotonic()
            time.sleep(args.seconds)
            idle = (fwd.cpu() - cpu0) / (time.monotonic() - t0)
            idle_rss = rss(fwd.proc.pid)
            rows.append((f"{label}: CPU idle", f"{idle * 100:.2f} % of a core", ""))
            for rate in (1000, 2000):
                got, cpu, latencies = fwd.offer_timed(rate, args.seconds)
                share = cpu / args.seconds
                note = f"{got}/{int(rate * args.seconds)} delivered"
                rows.append((f"{label}: CPU at {rate:,} msg/s",
                             f"{share * 100:.2f} % of a core, {cpu / max(got, 1) * 1e6:.1f} "
                             f"us/msg", note))
                if latencies:
                    rows.append((f"{label}: send to sink at {rate:,} msg/s, p50 / p99",
                                 f"{percentile(latencies, 0.5) / 1e6:.3f} / "
                                 f"{percentile(latencies, 0.99) / 1e6:.3f} ms", ""))
            if kind != "serial" or cycle or args.burst <= 0:
                continue
            rows.append((f"{label}: resident memory idle", f"{idle_rss:.1f} MiB", ""))
            Path(f"/proc/{fwd.proc.pid}/clear_refs").write_text("5")  # resets VmHWM
            got, took = fwd.burst(args.burst)
            peak = memory(fwd.proc.pid)["VmHWM"] / 1024
            rows.append((f"{label}: burst of {args.burst:,}",
                         f"{got:,} delivered in {took:.2f} s ({got / took:,.0f} msg/s)", ""))
            rows.append((f"{label}: peak during the burst",
                         f"{peak:.1f} MiB (idle + {peak - idle_rss:.1f})", "<= idle + 15"))
            after = time.monotonic()
            samples = []
            back = None
            marks = sorted({1.0, 5.0, 10.0, 30.0, args.settle})
            for mark in (m for m in marks if m <= args.settle):
                time.sleep(max(0.0, after + mark - time.monotonic()))
                now_rss = rss(fwd.proc.pid)
                samples.append(f"{now_rss:.1f} at {mark:g} s")
                if back is None and now_rss - idle_rss <= 5.0:
                    back = mark
            rows.append((f"{label}: resident memory after it", ", ".join(samples),
                         "idle + 5 within 60 s"))
            rows.append((f"{label}: back within 5 MiB of idle",
                         f"after {back:g} s" if back is not None else "not yet", ""))
        finally:
            fwd.close()
    return rows


def instructions_part(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """Instructions per relayed message, counted by callgrind: independent of the load.

    The forwarder runs under ``valgrind --tool=callgrind``; its counters are zeroed, 500
    messages are offered at 50 msg/s (slow enough that each arrives alone, as at a
    moderate rate on real hardware) and the counters are dumped. A path with a cycle runs
    with twenty times its cycle, so that each cycle reads as many datagrams as at 1,000
    msg/s (valgrind could not keep up with 1,000 msg/s itself; the cycle option's upper
    bound, 0.1 s, limits this to cycles up to 5 ms). User-space instructions
    only: the kernel's share (system calls) is not counted.
    """
    rows: list[tuple[str, str, str]] = []
    for kind, cycle, label in paths(args):
        rate = 50
        if cycle * 20 > 0.1:
            continue
        with tempfile.TemporaryDirectory(prefix="edge-vis-callgrind-") as tmp:
            out = Path(tmp, "callgrind.out")
            fwd = Forwarder(kind, ("valgrind", "--tool=callgrind", "--quiet",
                                   f"--callgrind-out-file={out}.%p"), cycle=cycle * 20)
            try:
                fwd.offer(rate, 2)  # warm up
                subprocess.run(["callgrind_control", "-z", str(fwd.proc.pid)], check=True,
                               capture_output=True)
                got, _ = fwd.offer(rate, 500 / rate)
                subprocess.run(["callgrind_control", "-d", str(fwd.proc.pid)], check=True,
                               capture_output=True)
                dumps = sorted(Path(tmp).glob(f"callgrind.out.{fwd.proc.pid}.*"))
                text = dumps[-1].read_text()
            finally:
                fwd.close()
        total = next(int(line.split()[1]) for line in text.splitlines()
                     if line.startswith(("summary:", "totals:")))
        rows.append((f"{label}: instructions per message (callgrind)",
                     f"{total / max(got, 1):,.0f}", f"{got} messages at {rate} msg/s"
                     + (f", cycle {cycle * 20000:g} ms" if cycle else "")))
    return rows


# -- part 4: edge-vis run forwarding -------------------------------------------------------

#: runs ``edge-vis`` pinned to core 0; on SIGUSR2 writes ``utime stime`` (its getrusage,
#: every thread) to argv[1]
RELAY_REPORTING_USAGE = """
import os, resource, signal, sys
out = sys.argv.pop(1)
if (os.cpu_count() or 1) > 1:
    os.sched_setaffinity(0, {0})
def usage(*_):
    ru = resource.getrusage(resource.RUSAGE_SELF)
    with open(out + ".part", "w") as f:
        f.write(f"{ru.ru_utime!r} {ru.ru_stime!r}")
    os.replace(out + ".part", out)  # whole or not at all for the reader
signal.signal(signal.SIGUSR2, usage)
from edge_vis.cli import main
sys.argv[0] = "edge-vis"
sys.exit(main())
"""


class RelayRun(Forwarder):
    """``edge-vis run`` forwarding UDP -> serial, measured as a :class:`Forwarder`."""

    def __init__(self, dds: bool, tmp: str) -> None:
        self.kind = "serial"
        self.run = 0
        self._open_sender()
        master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(master, False)
        self.sink = Sink(None, master, only_from=SOURCE)  # not the relay's own queries
        self._usage = Path(tmp, "usage.txt")
        profile = Path(tmp, "forwarding.toml")
        profile.write_text(f"""
[relay]
jaus_id = "{FWD_RELAY}"
name = "footprint-forwarding"

[links.lan]
url = "udp://{FWD_IP}:{self.in_port}?multicast=off&cycle=0.02&thread=1"

[links.radio]
url = "serial://{os.ttyname(self._slave)}?baud=20000000&pace=0"

[routing]
forward = [["lan", "radio"]]

[dds]
domain = {200 + os.getpid() % 30}
partitions = ["footprint-forwarding-{os.getpid()}"]
""")
        env = {k: v for k, v in os.environ.items()
               if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC")}
        if dds:
            from edge_vis.dds import loopback_config

            env["CYCLONEDDS_URI"] = loopback_config()
        self.proc = subprocess.Popen(  # type: ignore[assignment]
            [sys.executable, "-c", RELAY_REPORTING_USAGE, str(self._usage), "--log-level",
             "WARNING", "run", "--profile", str(profile), *([] if dds else ["--no-dds"])],
            env=env, stdin=subprocess.DEVNULL, stderr=subprocess.PIPE)
        self._learn_routes()

    def _learn_routes(self) -> None:
        """The source speaks until the relay passes it to the radio (links open); then
        the component behind the radio answers once, so both routes are learned."""
        from edge_vis.jaus.serial_framing import frame
        from edge_vis.jaus.transport import Packet

        deadline = time.monotonic() + 30.0
        seq = 0
        while not self.sink.drain():
            if time.monotonic() > deadline or self.proc.poll() is not None:
                raise RuntimeError("edge-vis run did not forward: "
                                   + (self.proc.stderr.read().decode()[-2000:]  # type: ignore[union-attr]
                                      if self.proc.poll() is not None else "timeout"))
            self.tx.sendto(message(seq, seq), (FWD_IP, self.in_port))
            seq += 1
            time.sleep(0.2)
        os.write(self.sink.fd, frame(Packet(SOURCE, TARGET, b"\x02\x44", sequence=1)))  # type: ignore[arg-type]
        time.sleep(0.5)
        self.sink.drain()

    def cpu(self) -> float:
        """The relay's user + system CPU seconds so far (its getrusage, on SIGUSR2)."""
        self._usage.unlink(missing_ok=True)
        self.proc.send_signal(signal.SIGUSR2)
        deadline = time.monotonic() + 5.0
        while not self._usage.exists():
            if time.monotonic() > deadline:
                raise RuntimeError("edge-vis run did not report its usage")
            time.sleep(0.001)
        user, system = self._usage.read_text().split()
        return float(user) + float(system)

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.communicate()
        self.tx.close()
        os.close(self.sink.fd)  # type: ignore[arg-type]
        os.close(self._slave)


def run_forwarding_part(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """edge-vis run forwarding UDP -> serial beside the bench forwarder (part 4)."""
    dds = not args.no_dds
    if dds:
        try:
            import edge_vis.dds  # noqa: F401
        except ImportError:
            dds = False
    rows: list[tuple[str, str, str]] = []
    load = "/".join(f"{x:.2f}" for x in os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="edge-vis-footprint-run-") as tmp:
        for label in ("bench forwarder, udp->serial, cycle=20 ms, thread=1",
                      f"edge-vis run (DDS {'on' if dds else 'off'}), [routing] forward, "
                      "udp->serial, cycle=20 ms, thread=1"):
            fwd = Forwarder("thread", cycle=0.02) if label.startswith("bench") \
                else RelayRun(dds, tmp)
            try:
                time.sleep(1.0)
                cpu0, t0 = fwd.cpu(), time.monotonic()
                time.sleep(args.seconds)
                idle = (fwd.cpu() - cpu0) / (time.monotonic() - t0)
                rows.append((f"{label}: CPU idle", f"{idle * 100:.2f} % of a core", ""))
                got, cpu, latencies = fwd.offer_timed(1000, args.seconds)
                above = (cpu - idle * args.seconds) / max(got, 1)
                rows.append((f"{label}: CPU at 1,000 msg/s",
                             f"{cpu / args.seconds * 100:.2f} % of a core, "
                             f"{cpu / max(got, 1) * 1e6:.1f} us/msg ({above * 1e6:.1f} "
                             "above idle)",
                             f"{got}/{int(1000 * args.seconds)} delivered; <= 2.7 %"))
                rows.append((f"{label}: send to sink at 1,000 msg/s, p50 / p99",
                             f"{percentile(latencies, 0.5) / 1e6:.3f} / "
                             f"{percentile(latencies, 0.99) / 1e6:.3f} ms", ""))
            finally:
                fwd.close()
    load_after = "/".join(f"{x:.2f}" for x in os.getloadavg())
    rows.append(("load average (1/5/15 min) before / after", f"{load} / {load_after}", ""))
    return rows


# -- part 2: JAUS report -> DDS sample ------------------------------------------------------
def engine_part(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """Runs bench/engine.py's pipeline in a child process; returns its row."""
    out = subprocess.run([sys.executable, __file__, "--engine", str(args.seconds)],
                         capture_output=True, text=True, check=False)
    if out.returncode:
        return [("report->DDS", "failed: " + out.stderr.strip()[-300:], "")]
    return [tuple(line.split("\t")) for line in out.stdout.splitlines()  # type: ignore[misc]
            if line.count("\t") == 2]


def engine_main(seconds: float) -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    from engine import VEHICLES, Pipeline, pose  # bench/engine.py

    from edge_vis.dds.bridge import DdsBridge

    bridge = DdsBridge(domain_id=7, partitions=(f"bench-footprint-{os.getpid()}",))
    pipeline = Pipeline(bridge)
    vehicles = [JausAddress(1000 + i, 1, 1) for i in range(VEHICLES)]
    for v in vehicles:
        pipeline.discover(v, 0.0)
    rate = 1000.0
    n = int(rate * seconds)
    data = [pipeline.datagram(vehicles[i % VEHICLES], "ReportGlobalPose", pose(i),
                              (10 + i // VEHICLES) & 0xFFFF) for i in range(n)]
    before = pipeline.published
    cpu0 = time.process_time()
    start = time.monotonic()
    for i, datagram in enumerate(data):
        wait = start + i / rate - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        pipeline.feed(datagram, 1.0 + i / rate)
    cpu = time.process_time() - cpu0
    published = pipeline.published - before
    bridge.close()
    print(f"report->DDS: CPU at 1,000 reports/s\t{cpu / seconds * 100:.2f} % of a core, "
          f"{cpu / max(published, 1) * 1e6:.1f} us/report\t{published}/{n} published")


# -- part 3: the relay ----------------------------------------------------------------------

#: runs ``edge-vis`` as usual; on SIGUSR1 writes the modules it has loaded to argv[1]
RELAY_DUMPING_MODULES = """
import os, signal, sys
out = sys.argv.pop(1)
def dump(*_):
    names = [name for name, module in list(sys.modules.items()) if module is not None]
    with open(out + ".part", "w") as f:
        f.write("\\n".join(names))
    os.replace(out + ".part", out)  # whole or not at all for the reader
signal.signal(signal.SIGUSR1, dump)
from edge_vis.cli import main
sys.argv[0] = "edge-vis"
sys.exit(main())
"""

#: a fresh interpreter, then every module in the file argv[1] imported as ``edge-vis run``
#: imports them (asyncio and hashlib without OpenSSL); prints VmRSS in KiB before and after
FLOOR = """
import importlib, sys
def rss():
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) for l in f if l.startswith("VmRSS:"))
alone = rss()
from edge_vis.shell.memory import import_without_openssl
import_without_openssl()
for name in open(sys.argv[1]).read().split():
    if not name.startswith("__"):
        try:
            importlib.import_module(name)
        except ImportError:  # another platform's module (nt, winreg...) tried and missed
            pass
print(alone, rss())
"""


def relay_floor(relay_cmd: Sequence[str], env: dict[str, str], listener: socket.socket,
                tmp: str) -> tuple[float, float] | None:
    """(interpreter alone, interpreter plus every module the idle relay has loaded), MiB.

    A second relay, started as the measured one was, reports its loaded modules once it
    is idle (first discovery query + 1 s); a fresh interpreter then imports those and
    nothing else: what the relay would cost if it held no data of its own.
    """
    modules = Path(tmp, "modules.txt")
    listener.setblocking(False)  # the measured relay's queries must not pass for this one's
    while True:
        try:
            listener.recv(65536)
        except BlockingIOError:
            break
    listener.setblocking(True)
    relay = subprocess.Popen([sys.executable, "-c", RELAY_DUMPING_MODULES, str(modules),
                              *relay_cmd[3:]], env=env, stderr=subprocess.DEVNULL)
    try:
        if first_discovery(listener, 10.0) is None:
            return None
        time.sleep(1.0)
        relay.send_signal(signal.SIGUSR1)
        deadline = time.monotonic() + 5.0
        while not modules.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        relay.terminate()
        try:
            relay.wait(15)
        except subprocess.TimeoutExpired:
            relay.kill()
            relay.wait()
    if not modules.exists():
        return None
    out = subprocess.run([sys.executable, "-c", FLOOR, str(modules)], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return int(out[0]) / 1024, int(out[1]) / 1024


def relay_part(args: argparse.Namespace) -> tuple[list[tuple[str, str, str]], bool]:
    dds = not args.no_dds
    if dds:
        try:
            from edge_vis.dds import DdsBridge, loopback_config
        except ImportError:
            print("cyclonedds is not installed: measuring without DDS", file=sys.stderr)
            dds = False
    domain, partition = 200 + os.getpid() % 30, f"footprint-{os.getpid()}"
    env = {k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC")}
    if dds:
        env["CYCLONEDDS_URI"] = os.environ["CYCLONEDDS_URI"] = loopback_config()

    with tempfile.TemporaryDirectory(prefix="edge-vis-footprint-") as tmp:
        profile, sim = Path(tmp, "relay.toml"), Path(tmp, "sim.toml")
        profile.write_text(relay_profile(domain, partition))
        sim.write_text(sim_profile())
        command = ([sys.executable, str(args.bundle)] if args.bundle
                   else [sys.executable, "-m", "edge_vis"])
        if args.bundle:  # unpack once, so start-up is what every later start costs
            subprocess.run([*command, "--version"], env=env, check=True,
                           stdout=subprocess.DEVNULL)
        listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        listener.bind((LISTENER_IP, PORT))
        relay_cmd = [*command, "--log-level", "WARNING", "run", "--profile", str(profile)]
        if not dds:
            relay_cmd.append("--no-dds")
        started = time.monotonic()
        relay = subprocess.Popen(relay_cmd, env=env, stderr=subprocess.PIPE)
        simulation: subprocess.Popen[bytes] | None = None
        reader_bridge = None
        try:
            seen = first_discovery(listener, 10.0)
            startup = seen - started if seen is not None else float("nan")
            time.sleep(1.0)  # let start-up work settle
            idle = cpu_share(relay.pid, args.seconds)
            idle_mem = memory(relay.pid)

            if dds:
                reader_bridge = DdsBridge(domain, (partition,))
                poses = reader_bridge.reader("GlobalPose")
            simulation = subprocess.Popen(
                [sys.executable, "-m", "edge_vis", "--log-level", "WARNING", "sim",
                 "--profile", str(sim)], env=env, stdout=subprocess.DEVNULL)
            time.sleep(8.0)  # discovery (2 s period), services, events
            per_vehicle: Counter[str] = Counter()

            def count() -> None:
                for sample in poses.take(max_samples=100000):
                    per_vehicle[sample["vehicle_id"]] += 1

            if dds:
                poses.take(max_samples=100000)
            busy = cpu_share(relay.pid, args.seconds, count if dds else None)
            busy_mem = memory(relay.pid)
            alive = relay.poll() is None
        finally:
            if simulation is not None:
                simulation.terminate()
                simulation.wait(10)
            relay.terminate()
            try:
                _, err = relay.communicate(timeout=15)
            except subprocess.TimeoutExpired:
                relay.kill()
                _, err = relay.communicate()
            if reader_bridge is not None:
                reader_bridge.close()
        try:
            floor = (relay_floor(relay_cmd, env, listener, tmp)
                     if alive and not args.bundle else None)
        finally:
            listener.close()
    if not alive:
        print(err.decode(errors="replace")[-2000:], file=sys.stderr)
        return [], False
    what = f"bundle {args.bundle.name}" if args.bundle else "python -m edge_vis"
    label = f"relay ({what}, DDS {'on' if dds else 'off'})"
    rows = [
        (f"{label}: start-up to first discovery query", f"{startup:.2f} s", "<= 1 s"),
        (f"{label}: CPU idle", f"{idle * 100:.2f} % of a core", "< 1 %"),
        (f"{label}: resident memory idle", f"{idle_mem['VmRSS'] / 1024:.1f} MiB",
         "< 39 MiB" if dds else ""),
        (f"{label}: CPU, 3 vehicles at 10 Hz", f"{busy * 100:.2f} % of a core", "< 10 %"),
        (f"{label}: resident memory, 3 vehicles", f"{busy_mem['VmRSS'] / 1024:.1f} MiB "
         f"(peak {busy_mem['VmHWM'] / 1024:.1f})", ""),
    ]
    if floor is not None:
        rows += [
            (f"{label}: floor: interpreter alone", f"{floor[0]:.1f} MiB", ""),
            (f"{label}: floor: interpreter plus the modules edge-vis run loads",
             f"{floor[1]:.1f} MiB (idle is {idle_mem['VmRSS'] / 1024 - floor[1]:.1f} above)",
             ""),
        ]
    if dds:
        rates = ", ".join(f"{n / args.seconds:.1f}" for _, n in sorted(per_vehicle.items()))
        rows.append((f"{label}: GlobalPose on DDS per vehicle, Hz", rates or "none",
                     f"{RATE:g} each"))
    return rows, True


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--forwarder"]:
        forwarder_main(int(argv[1]), argv[2], float(argv[3]) if len(argv) > 3 else 0.0,
                       argv[4:5] == ["thread"])
        return 0
    if argv[:1] == ["--engine"]:
        engine_main(float(argv[1]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="each measurement window")
    parser.add_argument("--burst", type=int, default=20000, help="messages in the burst")
    parser.add_argument("--settle", type=float, default=60.0,
                        help="seconds of resident memory watched after the burst")
    parser.add_argument("--no-dds", action="store_true", help="run the relay without DDS")
    parser.add_argument("--bundle", type=Path, help="measure this edge-vis.pyz as the relay")
    parser.add_argument("--only", choices=("forwarder", "engine", "relay", "run"),
                        help="run one part only")
    parser.add_argument("--cycles", type=lambda t: [float(x) for x in t.split(",") if x],
                        default=[1.0, 5.0, 10.0],
                        help="UDP link cycles to measure, ms, comma separated (0: none)")
    parser.add_argument("--paths", type=lambda t: t.split(","), default=[],
                        help="forwarder paths to measure, e.g. serial:0,serial:5,bare:0")
    parser.add_argument("--callgrind", action="store_true",
                        help="also count the forwarder's instructions per message (valgrind)")
    args = parser.parse_args(argv)
    rows: list[tuple[str, str, str]] = []
    ok = True
    if args.only in (None, "forwarder"):
        rows += forwarder_part(args)
        if args.callgrind:
            rows += instructions_part(args)
    if args.only in (None, "engine") and not args.no_dds:
        rows += engine_part(args)
    if args.only in (None, "relay"):
        relay_rows, ok = relay_part(args)
        rows += relay_rows
    if args.only in (None, "run"):
        rows += run_forwarding_part(args)
    print(f"edge-vis footprint ({args.seconds:g} s windows, burst {args.burst:,}, "
          f"{os.cpu_count()} cores, Python {sys.version.split()[0]})")
    width = max(len(r[0]) for r in rows)
    for name, value, note in rows:
        print(f"  {name:<{width}}  {value}" + (f"   [{note}]" if note else ""))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
