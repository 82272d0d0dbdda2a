"""Keep a long-running relay's resident memory flat: how the C allocator is told to behave.

The relay handles buffers of very different sizes side by side: datagrams of a few hundred
bytes, large JAUS data sets reassembled to tens of kilobytes (still images), DDS samples
serialised into buffers that double as they grow. With glibc's defaults, blocks below 128 KiB
(a threshold that even rises by itself once a large block is freed) come from the heap, and
the short-lived large ones leave holes between long-lived small objects that later requests
do not fit: the heap - and the resident memory - creeps up by a few hundred KiB a minute
under a busy fleet, for as long as the relay runs (``bench/soak.py`` measured it).

Serving blocks from :data:`MMAP_THRESHOLD` up with their own ``mmap`` returns each to the
system as soon as it is freed; the heap then only holds small objects and stays the same
size. Large blocks are rare on the relay's hot path (a few per image), so the extra system
calls cost nothing measurable.

Only glibc has ``mallopt``; elsewhere nothing is changed. A ``MALLOC_MMAP_THRESHOLD_`` in
the environment (glibc's own tunable) wins over this module.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os

log = logging.getLogger(__name__)

#: blocks from this size up get their own mapping (bytes)
MMAP_THRESHOLD = 16 * 1024
#: glibc's mallopt parameter number for the mmap threshold (malloc.h)
_M_MMAP_THRESHOLD = -3


def tune_allocator(threshold: int = MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``threshold`` bytes; True when it was set."""
    if "MALLOC_MMAP_THRESHOLD_" in os.environ:
        return False  # the operator chose: glibc has already read it
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (musl, macOS): leave the allocator be
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    done = bool(mallopt(_M_MMAP_THRESHOLD, threshold))
    log.debug("malloc mmap threshold %s at %d bytes", "set" if done else "not set", threshold)
    return done
