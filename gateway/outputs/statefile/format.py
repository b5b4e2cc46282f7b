"""The state file: loop windows and latest assessments, so a restart loses (almost) nothing.

Format (version 1): a numpy ``.npz`` archive (zip of ``.npy`` arrays, loaded with
``allow_pickle=False``: no Python object is ever unpickled) holding

* ``header``: UTF-8 JSON as a uint8 array - ``format`` (``stiction-gateway-state``),
  ``version``, the wall and process time of the save, and per window bank its sample time,
  its loops (name + window signature) and per loop the latest assessment
  (:meth:`stiction.Assessment.to_dict`) with its sequence number, time and window fill;
* per bank ``bK_t`` (float64, rows), ``bK_op``/``bK_pv`` (float32, rows × loops) and
  ``bK_q`` (uint8 quality), the stored samples oldest first.

Writes are atomic: a temporary file in the same directory, ``fsync``, ``rename`` over the
old file, ``fsync`` of the directory. A crash (even SIGKILL) leaves either the previous file
or the new one, so at most one persistence interval is lost.

On start the file is restored loop by loop: a loop's window comes back when its *window
signature* (device connection and sample time, window length, OP/PV point definitions) is
unchanged, and its latest assessment when the whole loop config is also unchanged; other
loops start fresh. The time the gateway was down becomes a gap (quality MISSING) in the
restored windows. A file that cannot be read (truncated, not an archive, bad header) or
that is not ours (other format or version) is renamed aside
(``<file>.corrupt-<time>`` / ``<file>.foreign-<time>``) with a warning; the gateway starts
fresh and never crashes on it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import logging
import os
import time
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment

from ...config import Config, LoopConfig
from ...core.store import LoopResult, ResultStore
from ...core.windows import WindowBank
from ...inputs.base import Quality

__all__ = ["FORMAT", "VERSION", "BankState", "StateError", "load_columns", "loop_signature",
           "read_state", "restore_state", "result_signature", "snapshot", "write_state"]

log = logging.getLogger("gateway.state")

FORMAT = "stiction-gateway-state"
VERSION = 1


class StateError(Exception):
    """The state file cannot be used; ``kind`` is ``corrupt`` or ``foreign``."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclasses.dataclass(frozen=True)
class BankState:
    """A window bank to persist: its loops' configs (column order) and sample time."""

    bank: WindowBank
    configs: Sequence[LoopConfig]
    ts: float


def loop_signature(config: Config, loop: LoopConfig) -> str:
    """What a loop's window depends on: equal signatures mean the stored samples are the
    same quantity at the same sample time, so the window can be kept."""
    dev = config.device(loop.device)
    return repr((dev.protocol, dev.options, dev.poll_interval_s,
                 config.window_samples(loop), loop.op, loop.pv))


def result_signature(config: Config, loop: LoopConfig) -> str:
    """What a loop's assessment depends on (its block address does not count)."""
    return repr((loop_signature(config, loop),
                 dataclasses.replace(loop, result_address=0)))


# ------------------------------------------------------------------------ writing


def snapshot(config: Config, banks: Sequence[BankState], store: ResultStore, *,
             wall: float, proc: float) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Copy everything to persist (fast, on the event loop); write it with write_state."""
    header: dict[str, Any] = {"format": FORMAT, "version": VERSION, "saved_wall": wall,
                              "saved_proc": proc, "banks": []}
    arrays: dict[str, NDArray[Any]] = {}
    for k, b in enumerate(banks):
        t, op, pv, q = b.bank.series(np.arange(len(b.configs)))
        arrays[f"b{k}_t"] = t
        arrays[f"b{k}_op"] = np.ascontiguousarray(op.T)
        arrays[f"b{k}_pv"] = np.ascontiguousarray(pv.T)
        arrays[f"b{k}_q"] = np.ascontiguousarray(q.T)
        loops = []
        for cfg in b.configs:
            entry: dict[str, Any] = {"name": cfg.name,
                                     "signature": loop_signature(config, cfg),
                                     "result_signature": result_signature(config, cfg)}
            i = store.index.get(cfg.name)
            res = store.results[i] if i is not None else None
            if res is not None:
                entry["result"] = {"assessment": res.assessment.to_dict(), "seq": res.seq,
                                   "t": res.t, "window_fill": res.window_fill,
                                   "samples": res.samples}
            loops.append(entry)
        header["banks"].append({"ts": b.ts, "size": b.bank.size, "loops": loops})
    return header, arrays


def write_state(path: str | os.PathLike[str], header: Mapping[str, Any],
                arrays: Mapping[str, NDArray[Any]]) -> int:
    """Write atomically (tmp + fsync + rename + fsync dir); returns the bytes written."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}")
    blob = np.frombuffer(json.dumps(header, allow_nan=True).encode(), dtype=np.uint8)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, header=blob, **arrays)  # type: ignore[arg-type]
            f.flush()
            os.fsync(f.fileno())
            size = f.tell()
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    with contextlib.suppress(OSError):  # not every file system lets a directory be synced
        fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return size


# ------------------------------------------------------------------------ reading


def read_state(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Read and check a state file; raise StateError (corrupt/foreign) if unusable."""
    try:
        data = Path(path).read_bytes()
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise StateError("corrupt", f"not a readable state archive: {exc}") from None
    blob = arrays.pop("header", None)
    if blob is None or blob.dtype != np.uint8 or blob.ndim != 1:
        raise StateError("foreign", "no state header (not a stiction-gateway state file)")
    try:
        header = json.loads(blob.tobytes().decode())
    except (UnicodeDecodeError, ValueError) as exc:
        raise StateError("corrupt", f"unreadable header: {exc}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise StateError("foreign", "not a stiction-gateway state file")
    if header.get("version") != VERSION:
        raise StateError("foreign", f"state format version {header.get('version')!r}, "
                         f"this gateway reads version {VERSION}")
    try:
        for k, b in enumerate(header["banks"]):
            n, rows = len(b["loops"]), len(arrays[f"b{k}_t"])
            for name in ("op", "pv", "q"):
                if arrays[f"b{k}_{name}"].shape != (rows, n):
                    raise ValueError(f"bank {k} {name} has shape "
                                     f"{arrays[f'b{k}_{name}'].shape}, expected {(rows, n)}")
            float(header["saved_wall"])
            float(header["saved_proc"])
    except (KeyError, TypeError, ValueError) as exc:
        raise StateError("corrupt", f"inconsistent content: {exc}") from None
    return header, arrays


def set_aside(path: Path, kind: str) -> Path:
    dest = path.with_name(f"{path.name}.{kind}-{time.strftime('%Y%m%dT%H%M%S')}")
    os.replace(path, dest)
    return dest


def load_columns(bank: WindowBank, t: NDArray[np.float64],
                 columns: Mapping[int, tuple[NDArray[Any], NDArray[Any], NDArray[Any]]]
                 ) -> None:
    """Fill a fresh ``bank`` with chronological samples: ``t`` (rows) and per column index
    its op/pv/quality series; series are aligned at their newest sample (shorter ones get
    MISSING rows in front), at most ``bank.size`` newest rows are kept. Columns not given
    stay empty (MISSING)."""
    rows = min(len(t), bank.size)
    if rows == 0:
        return
    bank.t[:] = np.nan
    bank.t[:rows] = t[len(t) - rows:]
    for col, (op, pv, q) in columns.items():
        n = min(len(op), rows)
        if n == 0:
            continue
        bank.op[rows - n:rows, col] = op[len(op) - n:]
        bank.pv[rows - n:rows, col] = pv[len(pv) - n:]
        bank.quality[rows - n:rows, col] = q[len(q) - n:]
    bank.count = rows
    bank.head = rows % bank.size


@dataclasses.dataclass
class RestoreReport:
    restored_windows: int = 0
    restored_results: int = 0
    fresh: list[str] = dataclasses.field(default_factory=list)
    gap_rows: int = 0
    set_aside: Path | None = None
    problem: str | None = None


def restore_state(path: str | os.PathLike[str], config: Config, banks: Sequence[BankState],
                  store: ResultStore, *, wall: float, time_scale: float) -> RestoreReport:
    """Restore what matches ``config`` into fresh ``banks`` and ``store``. Never raises for
    a bad file: it is set aside and the report says why."""
    report = RestoreReport()
    p = Path(path)
    for tmp in p.parent.glob(f".{p.name}.tmp-*"):  # left by a kill in the middle of a write
        with contextlib.suppress(OSError):
            tmp.unlink()
    if not p.exists():
        return report
    try:
        header, arrays = read_state(p)
    except StateError as exc:
        report.problem = str(exc)
        try:
            report.set_aside = set_aside(p, exc.kind)
        except OSError as err:
            log.warning("state file %s: %s; cannot set it aside (%s); starting fresh",
                        p, exc, err)
            return report
        log.warning("state file %s: %s; moved to %s, starting fresh", p, exc,
                    report.set_aside)
        return report
    saved: dict[str, tuple[int, int, dict[str, Any]]] = {}  # name -> (bank, column, entry)
    for k, b in enumerate(header["banks"]):
        for c, entry in enumerate(b["loops"]):
            if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                saved[entry["name"]] = (k, c, entry)
    down_proc = max(0.0, wall - float(header["saved_wall"])) * time_scale
    for ref in banks:
        columns: dict[int, tuple[NDArray[Any], NDArray[Any], NDArray[Any]]] = {}
        t_best: NDArray[np.float64] = np.empty(0)
        last_t = None
        for col, cfg in enumerate(ref.configs):
            hit = saved.get(cfg.name)
            if hit is None or hit[2].get("signature") != loop_signature(config, cfg):
                report.fresh.append(cfg.name)
                continue
            k, c, entry = hit
            t = arrays[f"b{k}_t"]
            columns[col] = (arrays[f"b{k}_op"][:, c], arrays[f"b{k}_pv"][:, c],
                            arrays[f"b{k}_q"][:, c])
            if len(t) > len(t_best):
                t_best = t
            if len(t):
                last_t = float(t[-1])
            report.restored_windows += 1
            res = entry.get("result")
            if res is not None and entry.get("result_signature") == result_signature(config,
                                                                                       cfg):
                try:
                    lr = LoopResult(Assessment.from_dict(res["assessment"]), int(res["seq"]),
                                    float(res["t"]), float(res["window_fill"]),
                                    int(res["samples"]))
                except (KeyError, TypeError, ValueError) as exc:
                    log.warning("state file %s: loop %s: result unreadable (%s)", p,
                                cfg.name, exc)
                else:
                    store.restore_result(store.index[cfg.name], lr)
                    report.restored_results += 1
        if not columns:
            continue
        load_columns(ref.bank, t_best, columns)
        if last_t is not None:
            # samples missed while the gateway was down: since the last sample saved and
            # from the save to now; the first new poll fills the slot after these
            missed = (float(header["saved_proc"]) - last_t + down_proc) / ref.ts - 1
            rows = int(min(max(0.0, np.floor(missed)), ref.bank.size))
            nan = np.full(len(ref.configs), np.nan, dtype=np.float32)
            miss = np.full(len(ref.configs), Quality.MISSING, dtype=np.uint8)
            for r in range(rows):
                ref.bank.append(last_t + (r + 1) * ref.ts, nan, nan, miss)
            report.gap_rows = max(report.gap_rows, rows)
    log.info("state file %s: restored %d windows and %d assessments; %d loops start fresh; "
             "downtime gap %d samples", p, report.restored_windows, report.restored_results,
             len(report.fresh), report.gap_rows)
    return report
