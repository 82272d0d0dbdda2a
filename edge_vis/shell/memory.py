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

After a burst (the router rebuilt its duplicate table: :attr:`Router.compactions`),
:func:`release_memory` gives back what the burst took. A router fed 20,000 distinct packets
grew by 3.4 MiB; once their duplicate window had passed and the table was rebuilt, it still
held 2.8 MiB: 1.0 in Python's free lists (emptied by a full collection) and 1.2 in free
pages inside glibc's heap, which glibc returns only when asked (``malloc_trim``). After
both, 0.6 MiB remained.
"""

from __future__ import annotations

import ctypes
import gc
import importlib
import logging
import os
import sys
from collections.abc import Callable
from typing import Any

log = logging.getLogger(__name__)

#: blocks from this size up get their own mapping (bytes)
MMAP_THRESHOLD = 16 * 1024
#: glibc's mallopt parameter number for the mmap threshold (malloc.h)
_M_MMAP_THRESHOLD = -3


_trim: Callable[[int], int] | None = None


def _libc_function(name: str) -> Any:
    """The C library's function ``name`` (a ctypes function), or None.

    Looked up among the symbols the process has loaded (``dlopen(NULL)``), which include
    the C library's: ``ctypes.util.find_library`` would import ``subprocess``,
    ``tempfile`` and ``shutil`` and run a compiler or ``ldconfig`` to find a file name.
    """
    try:
        function = getattr(ctypes.CDLL(None), name)
    except (OSError, AttributeError):  # not glibc (musl, macOS)
        return None
    return function


def release_memory() -> bool:
    """Return freed memory to the system: a full collection (which also empties Python's
    free lists), then glibc's ``malloc_trim``. A few milliseconds; call it after a burst,
    not per message. True when the C heap was trimmed."""
    global _trim
    gc.collect()
    if _trim is None:
        _trim = _libc_function("malloc_trim") or (lambda pad: 0)
    return bool(_trim(0))


def import_without_openssl() -> None:
    """Import :mod:`asyncio` and :mod:`hashlib` without loading OpenSSL, for a process that
    never speaks TLS.

    asyncio imports :mod:`ssl` in case a connection wants TLS, and hashlib takes its digests
    from OpenSSL's ``libcrypto`` (``_hashlib``) when it can: OpenSSL costs the relay 4.4 MiB
    resident for the one and 3.4 MiB for the other, for nothing. With ``ssl`` and
    ``_hashlib`` unavailable while they are imported, asyncio leaves its TLS support off and
    hashlib serves every digest the relay and Cyclone DDS use (md5 for XTypes type
    identifiers, sha256, blake2) from Python's own implementations, with the same results
    (a few times slower: 0.25 ms instead of 0.05 ms for a 64 KiB image's sha256). ``ssl``
    and :mod:`hmac` (a UDT link's handshake) still load OpenSSL for whoever imports them
    later. Does nothing for a module already loaded.
    """
    for module, blocked in (("asyncio", "ssl"), ("hashlib", "_hashlib")):
        if module in sys.modules or blocked in sys.modules:
            continue
        sys.modules[blocked] = None  # type: ignore[assignment]  # makes "import" fail
        try:
            importlib.import_module(module)
        finally:
            del sys.modules[blocked]


def tune_allocator(threshold: int = MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``threshold`` bytes; True when it was set."""
    if "MALLOC_MMAP_THRESHOLD_" in os.environ:
        return False  # the operator chose: glibc has already read it
    mallopt = _libc_function("mallopt")
    if mallopt is None:  # not glibc (musl, macOS): leave the allocator be
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    done = bool(mallopt(_M_MMAP_THRESHOLD, threshold))
    log.debug("malloc mmap threshold %s at %d bytes", "set" if done else "not set", threshold)
    return done
