"""Heap statistics from inside a relay started by ``bench/soak.py --heap-stats FILE``.

Python imports ``sitecustomize`` at start-up from ``PYTHONPATH``; the soak puts this folder
there for the relay process only. A thread appends one line every 30 s: resident memory,
glibc's ``mallinfo2()`` (heap arenas, bytes in use, free bytes inside the heap), memory
mappings, Python's allocated blocks and pymalloc arenas; every 5 minutes also the 15 most
common object types. glibc and Linux only.
"""

from __future__ import annotations

import ctypes
import gc
import os
import sys
import tempfile
import threading
import time
from collections import Counter

PERIOD = 30.0
CENSUS_EVERY = 10  # samples


class _MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def _pymalloc_arenas() -> int:
    """``# arenas allocated current`` from ``sys._debugmallocstats()`` (it writes to fd 2)."""
    saved = os.dup(2)
    with tempfile.TemporaryFile("w+") as out:
        os.dup2(out.fileno(), 2)
        try:
            sys._debugmallocstats()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        out.seek(0)
        for line in out:
            if line.startswith("# arenas allocated current"):
                return int(line.split("=")[1].replace(",", ""))
    return -1


def _sample(path: str) -> None:
    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = _MallInfo2
    start = time.monotonic()
    n = 0
    with open(path, "w", encoding="utf-8") as out:
        while True:
            time.sleep(PERIOD)
            n += 1
            info = libc.mallinfo2()
            with open("/proc/self/status", encoding="ascii") as status:
                rss = next(int(x.split()[1]) for x in status if x.startswith("VmRSS:"))
            with open("/proc/self/maps", encoding="ascii") as maps:
                mappings = sum(1 for _ in maps)
            out.write(f"t={time.monotonic() - start:.0f}s rss={rss}KiB "
                      f"heap={info.arena // 1024}KiB in_use={info.uordblks // 1024}KiB "
                      f"free={info.fordblks // 1024}KiB mappings={mappings} "
                      f"py_blocks={sys.getallocatedblocks()} "
                      f"pymalloc_arenas={_pymalloc_arenas()}\n")
            if n % CENSUS_EVERY == 0:
                census = Counter(type(o).__name__ for o in gc.get_objects())
                out.write("  objects: " + ", ".join(
                    f"{name} {count}" for name, count in census.most_common(15)) + "\n")
            out.flush()


_path = os.environ.get("EDGE_VIS_HEAP_STATS")
if _path:
    threading.Thread(target=_sample, args=(_path,), daemon=True, name="heap-stats").start()
