"""Reading a file from outside the gateway (the config and its tag list, the findings file,
the state file and the verdict history) bounded in time and size (issue 38 item 3).

A findings file on a network mount that hangs, or a FIFO named where a file belongs, blocked
the read forever: a reload held its lock (later SIGHUPs never applied, SIGTERM waited on it
until systemd killed the gateway and the last state write was lost), and at start ``run`` and
``check-config`` hung. So every such read:

* opens without blocking and refuses what is not a regular file (a FIFO, a device, a
  socket, a folder), naming it;
* reads at most the caller's bound of bytes (a larger file is refused unread by the caller);
* runs in a daemon thread of its own that the caller waits on for at most
  :data:`READ_TIMEOUT_S` (the state file :data:`STATE_READ_TIMEOUT_S`): after that the
  caller gets an :class:`OSError` (``ETIMEDOUT``) saying the file system did not answer,
  keeps what it had and goes on. The thread is abandoned (a daemon: it never holds up the
  process's exit); while :data:`MAX_PENDING` such reads have not returned, a new one is
  refused at once (``EBUSY``) rather than adding a thread.

The callers turn the error into their own words: a config that cannot be read (a reload
refused, the running config kept), a findings file not read (the findings read before
kept), a state file not restored (the gateway starts empty; the file is not set aside).
"""

from __future__ import annotations

import concurrent.futures
import errno
import os
import stat
import threading
from collections.abc import Callable
from typing import BinaryIO, TypeVar

__all__ = ["MAX_PENDING", "READ_TIMEOUT_S", "STATE_READ_TIMEOUT_S", "bounded",
           "open_regular", "read_bytes"]

T = TypeVar("T")
READ_TIMEOUT_S = 10.0
"""The longest the gateway waits for the config, a tag list, the findings file or the
verdict history."""
STATE_READ_TIMEOUT_S = 60.0
"""The longest it waits for the state file (up to a GiB of windows from a slow card)."""
MAX_PENDING = 8
"""Reads that have not returned (a hung file system) before new ones are refused at once."""

_lock = threading.Lock()
_pending = 0


def bounded(fn: Callable[..., T], *args: object, timeout_s: float | None = None) -> T:
    """``fn(*args)`` in a daemon thread, waited on for at most ``timeout_s`` (default
    :data:`READ_TIMEOUT_S`): its result, the exception it raised, or OSError(ETIMEDOUT)
    (see the module docstring)."""
    global _pending  # noqa: PLW0603 - one count for the process
    timeout_s = READ_TIMEOUT_S if timeout_s is None else timeout_s
    with _lock:
        if _pending >= MAX_PENDING:
            raise OSError(errno.EBUSY, f"{_pending} earlier reads have not returned: the "
                          "file system does not answer (a hung network mount?)")
        _pending += 1
    done: concurrent.futures.Future[T] = concurrent.futures.Future()

    def work() -> None:
        global _pending  # noqa: PLW0603
        try:
            done.set_result(fn(*args))
        except BaseException as exc:  # handed to the caller, whatever it is
            done.set_exception(exc)
        finally:
            with _lock:
                _pending -= 1

    threading.Thread(target=work, name="bounded read", daemon=True).start()
    try:
        return done.result(timeout_s)
    except concurrent.futures.TimeoutError:
        raise OSError(errno.ETIMEDOUT, f"no answer from the file system in {timeout_s:g} s "
                      "(a hung network mount?); not read") from None


def open_regular(path: str | os.PathLike[str]) -> BinaryIO:
    """``path`` opened for reading, never blocking on the open; OSError if it is not a
    regular file (a FIFO would block the first read until someone writes to it)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a folder"
                    if stat.S_ISDIR(mode) else "a socket" if stat.S_ISSOCK(mode)
                    else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                    else "no regular file")
            raise OSError(errno.EINVAL, f"is {kind}, not a file: name a file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _read(path: str | os.PathLike[str], limit: int) -> bytes:
    with open_regular(path) as fh:
        return fh.read(limit + 1)


def read_bytes(path: str | os.PathLike[str], limit: int, *,
               timeout_s: float | None = None) -> bytes:
    """At most ``limit + 1`` bytes of the regular file ``path`` (more than ``limit``: the
    caller refuses it as too large), bounded in time (:func:`bounded`)."""
    return bounded(_read, path, limit, timeout_s=timeout_s)
