"""The relay's event loop, shared with link I/O threads under one lock. Performs I/O.

A link may receive on a thread of its own (``udp://...?thread=1``): it sleeps its receive
cycle with a plain blocking call, which wakes the process for far less than a turn of the
asyncio loop, and hands a whole cycle's datagrams to the runtime on that thread (router,
engine, the other links' writes) without waking the loop. The core still never sees
concurrency:

* :class:`SharedLoop` holds :attr:`SharedLoop.lock` whenever it runs anything (every
  callback, every task step) and lets go of it only while it waits in ``select``;
* a link thread takes the same lock for each cycle's work, so the router, the links'
  buffers and the shell's state are touched by one thread at a time, exactly as in a
  single-threaded relay;
* what only the loop may do (arm a timer earlier than the one it has, wait for a full
  device to drain, set an asyncio event) is handed to it with ``call_soon_threadsafe``:
  the loop wakes only when there is such work.

``run(coro)`` replaces ``asyncio.run`` for programs that may open such links.
"""

from __future__ import annotations

import asyncio
import selectors
import threading
from collections.abc import Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


class _LockedSelector(selectors.DefaultSelector):  # type: ignore[misc,valid-type]
    """The loop's selector: lets go of the shared lock while it waits."""

    def __init__(self, lock: threading.Lock) -> None:
        super().__init__()
        self._shared_lock = lock

    def select(self, timeout: float | None = None) -> list[Any]:
        self._shared_lock.release()
        try:
            return super().select(timeout)  # type: ignore[no-any-return]
        finally:
            self._shared_lock.acquire()


class SharedLoop(asyncio.SelectorEventLoop):
    """A selector event loop that holds :attr:`lock` except while it waits for I/O."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        #: the thread running the loop (None while it does not run)
        self.thread_id: int | None = None
        super().__init__(_LockedSelector(self.lock))

    def run_forever(self) -> None:
        with self.lock:
            self.thread_id = threading.get_ident()
            try:
                super().run_forever()
            finally:
                self.thread_id = None


def run(main: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run`` on a :class:`SharedLoop`."""
    with asyncio.Runner(loop_factory=SharedLoop) as runner:
        return runner.run(main)


def shared_lock(loop: asyncio.AbstractEventLoop) -> threading.Lock | None:
    """The lock a link thread must hold to touch what the loop owns; None when ``loop``
    is not a :class:`SharedLoop` (then no link may run a thread on it)."""
    return loop.lock if isinstance(loop, SharedLoop) else None


def on_loop_thread(loop: asyncio.AbstractEventLoop | None) -> bool:
    """Whether the caller is the thread running ``loop`` (always, for a plain loop)."""
    if not isinstance(loop, SharedLoop) or loop.thread_id is None:
        return True
    return threading.get_ident() == loop.thread_id
