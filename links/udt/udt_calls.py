"""libudt's socket state and options, read and set through ctypes so that a call which
waits inside the library lets the other threads of the process run. Does I/O.

udt4py holds the GIL across ``getsockstate``, ``getsockopt`` and ``setsockopt``, and
libudt can make each of them wait: every one looks the socket up behind the library's
global control lock, which its garbage collector holds while it tears down closed
connections (their send and receive threads joined one after another) and a new
connection holds while its multiplexer is set up; ``setsockopt`` also waits for the
socket's send and receive locks, which a blocked ``send`` or ``recv`` holds until its
timeout. Through udt4py such a wait stopped every thread of the process: polling a new
lane's state while the lanes of the previous file were torn down froze a relay's
forwarder, its other lanes and the receivers beside it for about 100 ms at the start of
most forwarded files (found with a watchdog thread in the bench). ctypes releases the
GIL for the call, so only the calling thread waits.

Where libudt cannot be loaded through ctypes, each function falls back to udt4py's own
property (the old behaviour).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import socket
from typing import Any

OPTIONS = {name: number for number, name in enumerate((
    "UDT_MSS", "UDT_SNDSYN", "UDT_RCVSYN", "UDT_CC", "UDT_FC", "UDT_SNDBUF", "UDT_RCVBUF",
    "UDT_LINGER", "UDP_SNDBUF", "UDP_RCVBUF", "UDT_MAXMSG", "UDT_MSGTTL", "UDT_RENDEZVOUS",
    "UDT_SNDTIMEO", "UDT_RCVTIMEO", "UDT_REUSEADDR", "UDT_MAXBW", "UDT_STATE", "UDT_EVENT",
    "UDT_SNDDATA", "UDT_RCVDATA"))}
"""``UDTOpt`` of UDT 4's ``udt.h``: option name -> its number."""
SIGNED_32 = frozenset({"UDT_STATE", "UDT_EVENT", "UDT_SNDDATA", "UDT_RCVDATA", "UDT_MSS",
                       "UDT_SNDTIMEO", "UDT_RCVTIMEO", "UDT_LINGER", "UDT_SNDBUF",
                       "UDT_RCVBUF", "UDP_SNDBUF", "UDP_RCVBUF", "UDT_FC", "UDT_MSGTTL",
                       "UDT_MAXMSG"})
"""Options libudt writes as a C ``int`` (read back as udt4py reads them)."""

_SYMBOLS = {
    "state": ("_ZN3UDT12getsockstateEi", [ctypes.c_int], ctypes.c_int),
    "get": ("_ZN3UDT10getsockoptEii6UDTOptPvPi",
            [ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_void_p,
             ctypes.POINTER(ctypes.c_int)], ctypes.c_int),
    "set": ("_ZN3UDT10setsockoptEii6UDTOptPKvi",
            [ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_int],
            ctypes.c_int),
    "bind": ("_ZN3UDT4bindEiPK8sockaddri", [ctypes.c_int, ctypes.c_void_p, ctypes.c_int],
             ctypes.c_int),
    "name": ("_ZN3UDT11getsocknameEiP8sockaddrPi",
             [ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)], ctypes.c_int),
}
"""The calls made here: kind -> (mangled symbol in libudt, argument types, result type)."""


@functools.cache
def library() -> Any:
    """libudt (the one udt4py is linked against) as a ``ctypes.CDLL``, or None."""
    for name in ("libudt.so.0", ctypes.util.find_library("udt")):
        if name:
            try:
                return ctypes.CDLL(name)
            except OSError:
                continue
    return None


def function(symbol: str, argtypes: list[Any], restype: Any) -> Any:
    """A function of libudt by its (mangled) symbol, or None."""
    lib = library()
    try:
        fn = getattr(lib, symbol) if lib is not None else None
    except AttributeError:
        return None
    if fn is not None:
        fn.argtypes, fn.restype = argtypes, restype
    return fn


@functools.cache
def _fn(kind: str) -> Any:
    """One of :data:`_SYMBOLS`' functions, or None (looked up once)."""
    return function(*_SYMBOLS[kind])


CLOSED = 8
"""``UDTSTATUS`` of a closed socket (udt4py's ``UDTSocket.Status.CLOSED``)."""


class _SockaddrIn(ctypes.Structure):
    """``struct sockaddr_in`` (the port in network byte order)."""

    _fields_ = [("family", ctypes.c_uint16), ("port", ctypes.c_uint8 * 2),
                ("address", ctypes.c_uint8 * 4), ("zero", ctypes.c_uint8 * 8)]


def socket_id(sock: Any) -> int | None:
    """The libudt socket id of a udt4py socket; None once udt4py closed it."""
    handle = getattr(sock, "socket", None)
    return handle if isinstance(handle, int) else None


def state(sock: Any) -> int:
    """The socket's ``UDTSTATUS`` (compare with udt4py's ``UDTSocket.Status``)."""
    fn, handle = _fn("state"), socket_id(sock)
    if fn is None:
        return int(sock.status)
    return CLOSED if handle is None else int(fn(handle))


def get_option(sock: Any, name: str) -> int | None:
    """An option's value as udt4py reads it; None when libudt refuses (a closed socket)."""
    fn, handle = _fn("get"), socket_id(sock)
    if fn is None:
        return int(getattr(sock, name))
    if handle is None:
        return None
    value, size = ctypes.c_uint64(0), ctypes.c_int(8)
    if fn(handle, 0, OPTIONS[name], ctypes.byref(value), ctypes.byref(size)) != 0:
        return None
    if name in SIGNED_32:
        return ctypes.c_int32(value.value & 0xFFFFFFFF).value
    if name == "UDT_MAXBW":
        return ctypes.c_int64(value.value).value
    return int(value.value)


def set_option(sock: Any, name: str, value: int) -> bool:
    """Set an option as udt4py does (the value in eight bytes); False when libudt refuses
    (a closed or broken socket)."""
    fn, handle = _fn("set"), socket_id(sock)
    if fn is None:
        setattr(sock, name, value)
        return True
    if handle is None:
        return False
    raw = ctypes.c_uint64(int(value) & 0xFFFFFFFFFFFFFFFF)
    return bool(fn(handle, 0, OPTIONS[name], ctypes.byref(raw), 8) == 0)


def bind_any(sock: Any, port: int) -> int | None:
    """Bind the socket to ``port`` (0: one the system picks) on every IPv4 address and
    return the port it got; None when libudt refuses (the port taken, a closed socket).
    Binding sets up the socket's multiplexer behind libudt's global lock."""
    bind, name, handle = _fn("bind"), _fn("name"), socket_id(sock)
    if bind is None or name is None:
        try:
            sock.bind(("0.0.0.0", port))
            return int(sock.address[1])
        except Exception:  # udt4py's UDTException, or TypeError for a closed socket
            return None
    if handle is None:
        return None
    addr = _SockaddrIn(socket.AF_INET, (ctypes.c_uint8 * 2)(*port.to_bytes(2, "big")))
    if bind(handle, ctypes.byref(addr), ctypes.sizeof(addr)) != 0:
        return None
    got, size = _SockaddrIn(), ctypes.c_int(ctypes.sizeof(_SockaddrIn))
    if name(handle, ctypes.byref(got), ctypes.byref(size)) != 0:
        return None
    return int.from_bytes(bytes(got.port), "big")
