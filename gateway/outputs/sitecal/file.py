"""The site calibration's file: each loop's confidence on each day and the calibration in
force, kept across restarts and kills (:class:`gateway.core.sitecal.SiteBook`).

Format (version 1): UTF-8 JSON, ``{"format": "stiction-gateway-calibration", "version": 1,
"saved": <Unix time>, "fitted": <Unix time of the fit>, "calibration": <the fit,
stiction.ranking.SiteCalibration.to_dict>, "loops": {<loop>: {"days": ["2024-03-01", ...],
"conf": [0.91, ...], "t": <Unix time of the latest>, "latest": <the latest>}}}``, written
atomically like the verdict history beside it.

The file is untrusted input: its size is bounded before it is read, every field is checked
(numbers are numbers, confidences in 0..1, dates 1970..9999 strictly increasing, the fit's
scale finite and above 0 where it is in force) before anything of it is used; a file that
fails is set aside (``<file>.corrupt-<time>``, ``.foreign-`` for another format or version)
and the gateway starts its confidence history afresh and fits again from the findings.
"""

from __future__ import annotations

import errno
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO

from stiction.ranking import SiteCalibration

from ...config.reading import read_bytes
from ...core.sitecal import RETENTION_DAYS
from ..base import check_days, write_atomically

__all__ = ["FORMAT", "VERSION", "CalibrationError", "calibration_path", "read_calibration",
           "write_calibration"]

FORMAT = "stiction-gateway-calibration"
VERSION = 1
MAX_WALL = 1e11
BYTES_PER_LOOP = 40 * (RETENTION_DAYS + 2) + 2000


class CalibrationError(Exception):
    """The file cannot be used; ``kind``: ``corrupt`` or ``foreign`` (set aside), or
    ``unreadable`` (left where it is)."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


def calibration_path(state_file: str) -> Path:
    """The file beside the state file: ``gateway.state`` -> ``gateway.calibration``."""
    p = Path(state_file)
    out = p.with_suffix(".calibration") if p.suffix else p.with_name(p.name + ".calibration")
    return out if out != p else p.with_name(p.name + ".calibration")


def write_calibration(path: str | os.PathLike[str], loops: Mapping[str, Any],
                      calibration: SiteCalibration, fitted: float, saved: float) -> int:
    """Write atomically; returns the bytes written."""
    blob = json.dumps({"format": FORMAT, "version": VERSION, "saved": saved,
                       "fitted": fitted, "calibration": calibration.to_dict(),
                       "loops": loops}, separators=(",", ":")).encode()

    def write(f: BinaryIO) -> None:
        f.write(blob)

    return write_atomically(path, write)


def read_calibration(path: str | os.PathLike[str], *, max_loops: int
                     ) -> tuple[dict[str, Any], SiteCalibration, float]:
    """``(loops, calibration, fitted)`` of a file, every field checked; CalibrationError if
    it cannot be used."""
    max_bytes = 1024 * 1024 + BYTES_PER_LOOP * max_loops
    try:
        blob = read_bytes(path, max_bytes)
        if len(blob) > max_bytes:
            raise CalibrationError("corrupt", f"more than the {max_bytes:,} bytes this "
                                   "config's calibration can need")
        data = json.loads(blob.decode("utf-8"))
    except CalibrationError:
        raise
    except OSError as exc:
        kind = "unreadable" if exc.errno in (errno.EINVAL, errno.ETIMEDOUT, errno.EBUSY) \
            else "corrupt"
        raise CalibrationError(kind, f"cannot read it: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:
        raise CalibrationError("corrupt", f"not readable JSON: {type(exc).__name__}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CalibrationError("foreign", "not a stiction-gateway calibration")
    if data.get("version") != VERSION:
        raise CalibrationError("foreign", f"version {data.get('version')!r}, this gateway "
                               f"reads version {VERSION}")
    try:
        _number(data.get("saved"), "saved", 0.0, MAX_WALL)
        fitted = _number(data.get("fitted"), "fitted", 0.0, MAX_WALL)
        raw = data.get("calibration")
        if not isinstance(raw, dict):
            raise ValueError("calibration: not a mapping")
        calibration = SiteCalibration.from_dict(raw)
        loops = data.get("loops")
        if not isinstance(loops, dict) or len(loops) > max_loops:
            raise ValueError(f"loops: not a mapping of at most {max_loops:,} loops")
        for name, entry in loops.items():
            _loop(name, entry)
    except (ValueError, TypeError, KeyError) as exc:
        raise CalibrationError("corrupt", f"inconsistent content: {exc}") from None
    return loops, calibration, fitted


def _number(x: Any, where: str, lo: float, hi: float) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{where}: {type(x).__name__} where a number belongs")
    if not (math.isfinite(x) and lo <= x <= hi):
        raise ValueError(f"{where}: not a number in {lo:g} .. {hi:g}")
    return float(x)


def _loop(name: Any, entry: Any) -> None:
    if not isinstance(name, str) or not 0 < len(name) <= 1000:
        raise ValueError("a loop name that is not a text of 1 .. 1000 characters")
    where = f"loops[{name[:40]!r}]"
    if not isinstance(entry, dict) or set(entry) != {"days", "conf", "t", "latest"}:
        raise ValueError(f"{where}: fields other than days, conf, t, latest")
    days, conf = entry["days"], entry["conf"]
    if not isinstance(days, list) or not isinstance(conf, list) \
            or not 0 < len(days) == len(conf) <= RETENTION_DAYS + 1:
        raise ValueError(f"{where}: days and conf must be lists of 1 .. "
                         f"{RETENTION_DAYS + 1} entries, as many of each")
    check_days(days, where)
    for k, c in enumerate([*conf, entry["latest"]]):
        _number(c, f"{where}.conf[{k}]", 0.0, 1.0)
    _number(entry["t"], f"{where}.t", 0.0, MAX_WALL)
