"""The relay's allocator tuning: large blocks are mapped on their own, so freeing them
gives the memory back and the heap does not creep (see edge_vis.shell.memory)."""

from __future__ import annotations

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
