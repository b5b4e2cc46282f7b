"""Log lines rate-limited per cause, so that no flood of events can flood the journal; and
the journal's texts on one line, never cut inside a word (:func:`clip`).

:class:`RateLimit` is a :class:`logging.Filter` for the handlers of ``stiction-gateway
run``: a *cause* is a logger, a level, a message template and its first argument (the
device, loop or server the line is about), so "device plc1: down" and "device plc2: down"
are two causes. Each cause may log :data:`BURST` lines per :data:`PERIOD_S`; the lines
beyond are dropped and counted, and the next line of that cause says how many were. The
filter keeps at most :data:`MAX_CAUSES` causes (the least recent are forgotten).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stiction import Assessment

__all__ = ["BURST", "MAX_CAUSES", "MAX_TEXT", "PERIOD_S", "RateLimit", "clip",
           "install_rate_limit", "loop_exception_handler", "sizes_text"]

BURST = 20
PERIOD_S = 60.0
MAX_CAUSES = 10_000
MAX_TEXT = 2000
"""Characters of a text (a reason, an exception's message) in one journal line; a reason is
a few hundred, so it is never cut."""


def clip(text: object, limit: int = MAX_TEXT) -> str:
    """``text`` on one line (white space collapsed): whole when it fits in ``limit``
    characters, else cut at the last space before it and ended with `` ...``, never inside
    a word (a single word longer than ``limit``, such as a client's bytes, is cut)."""
    one = " ".join(str(text).split())
    if len(one) <= limit:
        return one
    head = one[:limit - 4]
    if " " in head:
        head = head.rsplit(" ", 1)[0]
    return f"{head} ..."


def sizes_text(a: Assessment) -> str:
    """The sizes of a verdict line as its registers hold them, their unit named once
    (``fd 26.9, fs 29.9, J 6.0 % of span``), or "" when the valve was not sized."""
    sizes = a.sizes()
    if sizes is None:
        return ""
    parts = [f"{name} {value:.1f}" for name, value in
             (("fd", sizes.fd), ("fs", sizes.fs), ("J", sizes.jump)) if value is not None]
    return f"{', '.join(parts)} {sizes.unit}"


class RateLimit(logging.Filter):
    """At most ``burst`` records per cause per ``period_s`` seconds (see the module)."""

    def __init__(self, burst: int = BURST, period_s: float = PERIOD_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.burst, self.period_s, self.clock = burst, period_s, clock
        self.causes: OrderedDict[Hashable, list[float]] = OrderedDict()  # [start, n, dropped]
        self.dropped = 0  # every record dropped so far

    @staticmethod
    def cause(record: logging.LogRecord) -> Hashable:
        args = record.args
        first = args[0] if isinstance(args, tuple) and args else None
        return (record.name, record.levelno, str(record.msg)[:200],
                first if isinstance(first, str | int) else None)

    def filter(self, record: logging.LogRecord) -> bool:
        now = self.clock()
        key = self.cause(record)
        state = self.causes.get(key)
        if state is None:
            state = self.causes[key] = [now, 0.0, 0.0]
            if len(self.causes) > MAX_CAUSES:
                self.causes.popitem(last=False)
        else:
            self.causes.move_to_end(key)
        if now - state[0] >= self.period_s:
            state[0], state[1] = now, 0.0
        if state[1] >= self.burst:
            state[2] += 1
            self.dropped += 1
            return False
        state[1] += 1
        if state[2]:
            record.msg = f"{record.getMessage()} [{int(state[2])} more like this dropped]"
            record.args = None
            state[2] = 0.0
        return True


def install_rate_limit(logger: logging.Logger | None = None) -> list[RateLimit]:
    """Give every handler of ``logger`` (default: the root) its own :class:`RateLimit`."""
    limits = []
    for handler in (logger or logging.getLogger()).handlers:
        if any(isinstance(f, RateLimit) for f in handler.filters):
            continue  # installed already
        limit = RateLimit()
        handler.addFilter(limit)
        limits.append(limit)
    return limits


def loop_exception_handler(loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
    """``loop.set_exception_handler``: asyncio's report, keyed by place and type."""
    exc = context.get("exception")
    place = "event loop"
    for key in ("protocol", "task", "future", "handle"):
        obj = context.get(key)
        if obj is None:
            continue
        if key in ("task", "future") and hasattr(obj, "get_coro"):
            obj = obj.get_coro()
        elif key == "handle":
            obj = getattr(obj, "_callback", obj)
        place = getattr(obj, "__qualname__", type(obj).__qualname__)
        break
    text = clip(context.get("message", ""), 200)
    cause = f"asyncio, {place}: {type(exc).__name__ if exc is not None else 'error'}"
    logging.getLogger("gateway.app").error("%s: %s", cause, text, exc_info=exc)
