"""The verdict history's file: which verdict each loop had on each day, kept across restarts
and kills so the findings are compared with the verdicts of their day
(:class:`gateway.core.findings.VerdictHistory`).

Format (version 1): UTF-8 JSON, ``{"format": "stiction-gateway-verdicts", "version": 1,
"saved": <Unix time>, "loops": {<loop>: {"days": ["2024-03-01", ...], "verdicts":
["stiction", ...], "t": <Unix time of the latest>, "verdict": <the latest>}}}``. Written
atomically (a temporary file in the same folder, ``fsync``, ``rename``, ``fsync`` of the
folder): a kill leaves the previous file or the new one.

The file is untrusted input, like the state file (:mod:`gateway.outputs.statefile.validate`):
its size is bounded before it is read, and every field is checked (types: a number is an
``int``/``float``, never a string or a boolean; ranges: a Unix time in 0 .. 1e11, dates
1970 .. 9999 strictly increasing; sizes: loop names, loops, days per loop; verdicts: the
analysis's names) before anything of it is used. A file that fails is set aside
(``<file>.corrupt-<time>``, or ``.foreign-`` for another format or version) and the gateway
starts its history afresh; it never stops on it.
"""

from __future__ import annotations

import errno
import json
import math
import os
from collections.abc import Mapping
from typing import Any, BinaryIO

from stiction import Verdict

from ...config.reading import read_bytes
from ...core.findings import MAX_ENTRIES, NOT_CALLS
from ..base import check_days, set_aside, write_atomically

__all__ = ["FORMAT", "VERSION", "HistoryError", "read_history", "set_aside", "write_history"]

FORMAT = "stiction-gateway-verdicts"
VERSION = 1
MAX_WALL = 1e11
MAX_NAME = 1000
BYTES_PER_LOOP = 64 * (MAX_ENTRIES + 4)  # a loop's whole retention, generously
_VERDICTS = frozenset(str(v) for v in Verdict) - NOT_CALLS


class HistoryError(Exception):
    """The file cannot be used; ``kind`` is ``corrupt`` or ``foreign`` (set aside), or
    ``unreadable`` (not a regular file, no answer in time: left where it is)."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


def write_history(path: str | os.PathLike[str], loops: Mapping[str, Any], saved: float
                  ) -> int:
    """Write atomically (:func:`gateway.outputs.base.write_atomically`); returns the bytes
    written."""
    blob = json.dumps({"format": FORMAT, "version": VERSION, "saved": saved,
                       "loops": loops}, separators=(",", ":")).encode()

    def write(f: BinaryIO) -> None:
        f.write(blob)

    return write_atomically(path, write)


def read_history(path: str | os.PathLike[str], *, max_loops: int) -> dict[str, Any]:
    """The ``loops`` of a history file, every field checked; HistoryError if unusable."""
    max_bytes = 1024 * 1024 + BYTES_PER_LOOP * max_loops
    try:
        blob = read_bytes(path, max_bytes)  # a regular file, within a time limit
        if len(blob) > max_bytes:
            raise HistoryError("corrupt", f"more than the {max_bytes:,} bytes a history of "
                               "this config can need")
        data = json.loads(blob.decode("utf-8"))
    except HistoryError:
        raise
    except OSError as exc:  # not a regular file, no answer in time: left where it is
        kind = "unreadable" if exc.errno in (errno.EINVAL, errno.ETIMEDOUT, errno.EBUSY) \
            else "corrupt"
        raise HistoryError(kind, f"cannot read it: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:  # not UTF-8, not JSON, nested too deep
        raise HistoryError("corrupt", f"not readable JSON: {type(exc).__name__}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise HistoryError("foreign", "not a stiction-gateway verdict history")
    if data.get("version") != VERSION:
        raise HistoryError("foreign", f"version {data.get('version')!r}, this gateway reads "
                           f"version {VERSION}")
    try:
        _number(data.get("saved"), "saved")
        loops = data.get("loops")
        if not isinstance(loops, dict):
            raise ValueError("loops: not a mapping")
        if len(loops) > max_loops:
            raise ValueError(f"loops: {len(loops):,}, more than {max_loops:,}")
        for name, entry in loops.items():
            _loop(name, entry)
    except ValueError as exc:
        raise HistoryError("corrupt", f"inconsistent content: {exc}") from None
    return loops


def _number(x: Any, where: str) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{where}: {type(x).__name__} where a number belongs")
    if not (math.isfinite(x) and 0.0 <= x <= MAX_WALL):
        raise ValueError(f"{where}: not a Unix time in 0 .. {MAX_WALL:g}")
    return float(x)


def _loop(name: Any, entry: Any) -> None:
    if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME:
        raise ValueError("a loop name that is not a text of 1 .. 1000 characters")
    where = f"loops[{name[:40]!r}]"
    if not isinstance(entry, dict) or set(entry) != {"days", "verdicts", "t", "verdict"}:
        raise ValueError(f"{where}: fields other than days, verdicts, t, verdict")
    days, verdicts = entry["days"], entry["verdicts"]
    if not isinstance(days, list) or not isinstance(verdicts, list):
        raise ValueError(f"{where}: days and verdicts must be lists")
    if not 0 < len(days) <= MAX_ENTRIES or len(verdicts) != len(days):
        raise ValueError(f"{where}: {len(days)} days and {len(verdicts)} verdicts (1 .. "
                         f"{MAX_ENTRIES}, as many of each)")
    check_days(days, where)
    for k, v in enumerate([*verdicts, entry["verdict"]]):
        if v not in _VERDICTS:
            raise ValueError(f"{where}: verdict {k}: not one of {', '.join(sorted(_VERDICTS))}")
    _number(entry["t"], f"{where}.t")

