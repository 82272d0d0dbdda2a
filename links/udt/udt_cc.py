"""The congestion control of the connections whose rate the lanes' coordinator sets: UDT's
own rules, or none but ``UDT_MAXBW``. Does I/O (ctypes into a library of ours).

The lanes of an adaptive transfer are paced together at a rate the rate probe finds from
the radio's queue, each at a share of it (:class:`~links.udt.lane_run.SharedRate`). UDT's
own control also reads every radio loss as congestion: it slows the lane that saw one
below its share and speeds it up again by about 1 Mbit/s a second, so a lane cut near the
end of a file, or handed a larger share there as the others finished, went on alone while
the radio idled. ``udt_cc.cpp`` (built against libudt's headers by ``scripts/setup.sh``
into the virtual environment, and by ``deploy/build-bundle.sh`` into the bundle beside
this module) is a control with a switch: UDT's rules until
:func:`pace` turns them off for a connection, which then sends what it lost again without
slowing down and keeps to its ``UDT_MAXBW``.

Where the library is not built (or ``EDGE_VIS_UDT_CC=off``), every function here reports
False and the connections keep libudt's own control, as before.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import sys
from pathlib import Path
from typing import Any

from links.udt.udt_calls import socket_id

log = logging.getLogger(__name__)

LIBRARY = "libedge_udt_cc.so"
ENV = "EDGE_VIS_UDT_CC"
"""``off``: keep libudt's own control; a path: the library to load instead."""


def library_path() -> Path:
    """The library to load: beside this module in a bundle, else where
    ``scripts/setup.sh`` builds it (the virtual environment's ``lib``)."""
    bundled = Path(__file__).with_name(LIBRARY)
    return bundled if bundled.is_file() else Path(sys.prefix) / "lib" / "edge-vis" / LIBRARY


@functools.cache
def _library() -> Any:
    choice = os.environ.get(ENV, "")
    if choice.lower() in ("off", "0", "no"):
        log.info("UDT connections keep libudt's own congestion control (%s=%s)", ENV, choice)
        return None
    path = Path(choice) if choice else library_path()
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as exc:
        log.info("UDT connections keep libudt's own congestion control: %s (built by "
                 "scripts/setup.sh)", exc)
        return None
    for name in ("edge_udt_cc_install", "edge_udt_cc_pace", "edge_udt_cc_paced"):
        fn = getattr(lib, name)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_int] * (1 if name == "edge_udt_cc_paced" else 2)
    return lib


def available() -> bool:
    """Whether the library is loaded (connections can be paced by ``UDT_MAXBW`` alone)."""
    return _library() is not None


def install(sock: Any, paced: bool = False) -> bool:
    """Give a udt4py socket not yet bound or connected this control (a listener's
    connections inherit it): paced by its ``UDT_MAXBW`` alone from its first packet, or on
    UDT's rules until :func:`pace`. False: not installed."""
    lib, handle = _library(), socket_id(sock)
    return lib is not None and handle is not None \
        and lib.edge_udt_cc_install(handle, int(paced)) == 0


def pace(sock: Any, on: bool = True) -> bool:
    """Pace a connected socket by its ``UDT_MAXBW`` alone (``on``) or by UDT's rules again;
    False when the socket is closed or does not have this control."""
    lib, handle = _library(), socket_id(sock)
    return lib is not None and handle is not None and lib.edge_udt_cc_pace(handle, int(on)) == 0


def paced(sock: Any) -> bool | None:
    """Whether a connected socket is paced by ``UDT_MAXBW`` alone; None when it does not
    have this control (or is closed)."""
    lib, handle = _library(), socket_id(sock)
    if lib is None or handle is None:
        return None
    state = lib.edge_udt_cc_paced(handle)
    return None if state < 0 else bool(state)
