"""What libudt knows about a connection and udt4py does not pass on: the smoothed round
trip, the packets in flight, the pace it sends at and how many packets it sent again.
Does I/O (reads the library's state through ctypes).

udt4py's ``perfmon`` fails on every call (its TraceInfo wrapper looks for a field it does
not define), so the round trip is read with ``UDT::perfmon`` of the libudt udt4py is
linked against, into ``CPerfMon`` as ``udt.h`` of UDT 4 lays it out. UDT updates the
round trip from every ACK/ACK2 exchange (every 10 ms while data flows), and it includes
the time the ACK2 waits in the radio's queue: a dense queue signal for the rate probe,
where the answers to the lanes' manifests come a few times a second. Where the library
or the symbol is missing, :func:`round_trip` returns None and the probe keeps to the
answers alone.
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass
from typing import Any

from links.udt import udt_calls

_I64, _INT, _DBL = ctypes.c_int64, ctypes.c_int, ctypes.c_double


class _PerfMon(ctypes.Structure):
    """``CPerfMon`` of UDT 4's ``udt.h``."""

    _fields_ = [
        ("msTimeStamp", _I64), ("pktSentTotal", _I64), ("pktRecvTotal", _I64),
        ("pktSndLossTotal", _INT), ("pktRcvLossTotal", _INT), ("pktRetransTotal", _INT),
        ("pktSentACKTotal", _INT), ("pktRecvACKTotal", _INT), ("pktSentNAKTotal", _INT),
        ("pktRecvNAKTotal", _INT), ("usSndDurationTotal", _I64),
        ("pktSent", _I64), ("pktRecv", _I64), ("pktSndLoss", _INT), ("pktRcvLoss", _INT),
        ("pktRetrans", _INT), ("pktSentACK", _INT), ("pktRecvACK", _INT),
        ("pktSentNAK", _INT), ("pktRecvNAK", _INT), ("mbpsSendRate", _DBL),
        ("mbpsRecvRate", _DBL), ("usSndDuration", _I64),
        ("usPktSndPeriod", _DBL), ("pktFlowWindow", _INT), ("pktCongestionWindow", _INT),
        ("pktFlightSize", _INT), ("msRTT", _DBL), ("mbpsBandwidth", _DBL),
        ("byteAvailSndBuf", _INT), ("byteAvailRcvBuf", _INT),
    ]


SETTLED_ACKS = 40
"""ACKs a connection must have had before its round trip is read: UDT starts from a
guess of 100 ms and smooths each side's estimate by 1/8 per exchange."""
_SYMBOL = "_ZN3UDT7perfmonEiP8CPerfMonb"  # UDT::perfmon(int, CPerfMon*, bool)


@functools.cache
def _function() -> Any:
    return udt_calls.function(
        _SYMBOL, [ctypes.c_int, ctypes.POINTER(_PerfMon), ctypes.c_bool], ctypes.c_int)


@dataclass(frozen=True, slots=True)
class Stats:
    """A connection's state as libudt has it."""

    #: smoothed round trip (s), radio queue included; None while near UDT's first guess
    round_trip: float | None
    #: data packets sent and not yet acknowledged
    in_flight: int
    #: seconds between data packets UDT keeps to now: the longer of its congestion
    #: control's and the cap's (``UDT_MAXBW``); None before it has one
    pace: float | None = None
    #: data packets sent on the connection so far, and of them sent again (lost)
    sent: int = 0
    resent: int = 0


def read(sock: Any) -> Stats | None:
    """What libudt knows of ``sock`` (a udt4py socket); None when it cannot be read (no
    library, a closed socket)."""
    fn, handle = _function(), udt_calls.socket_id(sock)
    if fn is None or handle is None:
        return None
    perf = _PerfMon()
    if fn(handle, ctypes.byref(perf), False) != 0:
        return None
    settled = perf.msRTT > 0 and perf.pktRecvACKTotal >= SETTLED_ACKS
    return Stats(float(perf.msRTT) / 1000 if settled else None, max(0, perf.pktFlightSize),
                 float(perf.usPktSndPeriod) / 1e6 if perf.usPktSndPeriod > 0 else None,
                 max(0, perf.pktSentTotal), max(0, perf.pktRetransTotal))
