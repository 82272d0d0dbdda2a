"""The relay's allocator tuning: large blocks are mapped on their own, so freeing them
gives the memory back and the heap does not creep (see edge_vis.shell.memory)."""

from __future__ import annotations

import hashlib
import hmac
import os
import subprocess
import sys

import pytest

PROBE = """
import ctypes, sys
from edge_vis.shell.memory import tune_allocator
class Info(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks",
                "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = Info
tuned = tune_allocator()
before = libc.mallinfo2().hblks
blocks = [bytearray(40 * 1024) for _ in range(32)]  # image-sized buffers
print(tuned, libc.mallinfo2().hblks - before)
"""

glibc = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")


def probe(env: dict[str, str]) -> tuple[str, int]:
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         env=env, check=True).stdout.split()
    return out[0], int(out[1])


@glibc
def test_large_buffers_get_their_own_mapping_once_tuned() -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    tuned, mapped = probe(env)
    assert tuned == "True"
    # once the heap's free space is used up, each 40 KiB buffer is its own mapping: the
    # heap does not grow for it
    assert mapped >= 24


@glibc
def test_an_operator_chosen_threshold_is_left_alone() -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    env["MALLOC_MMAP_THRESHOLD_"] = str(1 << 20)
    tuned, mapped = probe(env)
    assert tuned == "False"
    assert mapped == 0  # 40 KiB stays below the operator's 1 MiB threshold: from the heap


RELEASE_PROBE = """
from edge_vis.shell.memory import release_memory
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096 / 2**20
idle = rss()
blocks = [bytes(2048) + i.to_bytes(4, "little") for i in range(40_000)]  # C heap blocks
kept = blocks[::16]  # a few survive a burst, scattered through the heap
del blocks
held = rss()
release_memory()
print(idle, held, rss())
"""


@glibc
def test_memory_a_burst_freed_returns_to_the_system_when_released() -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    out = subprocess.run([sys.executable, "-c", RELEASE_PROBE], capture_output=True,
                         text=True, env=env, check=True).stdout.split()
    idle, held, released = map(float, out)
    # about 80 MiB were taken; the survivors keep glibc from shrinking the heap by itself
    assert held - idle > 40
    assert released - idle < (held - idle) / 3


def test_the_relay_command_loads_neither_other_commands_nor_openssl() -> None:
    probe = ("import sys; from edge_vis.cli import build_parser; build_parser('run'); "
             "import edge_vis.dds, hashlib; "  # Cyclone's type identifiers hash with md5
             "print(sorted(m for m in ('edge_vis.tools.sim.runner', 'edge_vis.tools.monitor_view',"
             " 'ssl', '_hashlib') if m in sys.modules), "
             "hashlib.md5(b'edge').hexdigest(), hashlib.sha256(b'edge').hexdigest(), "
             "__import__('hmac').new(b'key', b'edge', hashlib.sha256).hexdigest())")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[0] == "[]"
    # the digests are the standard ones, served without OpenSSL (HMAC as a UDT link signs)
    assert out[1:] == [hashlib.md5(b"edge").hexdigest(), hashlib.sha256(b"edge").hexdigest(),
                       hmac.new(b"key", b"edge", hashlib.sha256).hexdigest()]
    # ``ssl`` itself still works for whoever needs it later
    subprocess.run([sys.executable, "-c", "from edge_vis.cli import build_parser; "
                    "build_parser('run'); import ssl, asyncio; ssl.create_default_context()"],
                   check=True)
