"""Restoring the state file into fresh windows and a fresh store, loop by loop.

A loop's window comes back when its *window signature* (device connection and sample time,
OP/PV point definitions; its length aside: the newest samples the window holds now) is
unchanged, and its latest assessment when the
whole loop config is also unchanged; other loops start fresh. The time the gateway was down
becomes a gap (quality MISSING) in the restored windows. A file that cannot be read or is not
ours is set aside with a warning; the gateway starts fresh and never crashes on it.

The downtime is the wall time from the file's last write to now. A wall clock that is
*behind* the last write stepped back across the restart (an NTP correction after a reboot,
a hand-set clock): the downtime is then unknown, not zero. It becomes a gap of
:data:`UNKNOWN_DOWNTIME_ROWS` samples, longer than any gap the analysis bridges, and after a
kill the sequence numbers move on by the most analysis rounds the kill can have lost (a
persist interval and the writes around it: :func:`seq_bump`); one WARNING line says so, and
the report keeps how far back the clock was (``stiction_state_clock_back_seconds``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment

from ...config import reading
from ...config.model import Config
from ...config.reading import bounded
from ...core.points import MAX_MAGNITUDE, Quality
from ...core.store import LoopResult, ResultStore
from ...core.ticks import STALE_POLLS
from ...core.windows import LoopGroup, load_columns, loop_signature, result_signature
from ...wire.results import moved_indices, moved_line
from .format import StateError, read_state, set_aside, state_bounds

__all__ = ["UNKNOWN_DOWNTIME_ROWS", "Read", "RestoreReport", "apply_state",
           "read_for_restore", "restore_state", "seq_bump"]

log = logging.getLogger("gateway.state")

UNKNOWN_DOWNTIME_ROWS = STALE_POLLS + 1
"""Gap rows for a downtime that is unknown (the wall clock stepped back across the
restart): more than the stale limit, so the analysis (which fills gaps of up to that many
samples) never joins the samples before it to those after."""


@dataclasses.dataclass
class RestoreReport:
    restored_windows: int = 0
    restored_results: int = 0
    fresh: list[str] = dataclasses.field(default_factory=list)
    gap_rows: int = 0
    set_aside: Path | None = None
    problem: str | None = None
    kind: str | None = None  # why it was not restored: corrupt, foreign (set aside),
    # unreadable (left where it is)
    clock_back_s: float = 0.0  # how far the wall clock was behind the file's last write


Read = tuple[dict[str, Any], dict[str, NDArray[Any]]] | StateError | None
"""What :func:`read_for_restore` found: the header and arrays, why the file is unusable, or
None (no file)."""


def read_for_restore(path: str | os.PathLike[str], banks: Sequence[LoopGroup],
                     timeout_s: float | None = None) -> Read:
    """The state file read and checked for ``banks`` (temporary files of a killed write
    removed), in a thread of its own bounded by ``timeout_s`` (default
    :data:`gateway.config.reading.STATE_READ_TIMEOUT_S`)
    (:func:`gateway.config.reading.bounded`); never raises. Thread-safe: it touches nothing
    of the running gateway, so the gateway may call it off its event loop."""
    max_bytes, max_loops = state_bounds(banks)
    keep = {cfg.name: g.bank.size for g in banks for cfg in g.configs}
    try:
        return bounded(_read_file, Path(path), max_bytes, max_loops, keep,
                       timeout_s=reading.STATE_READ_TIMEOUT_S if timeout_s is None
                       else timeout_s)
    except StateError as exc:
        return exc
    except OSError as exc:  # the file system did not answer in time
        return StateError("unreadable", exc.strerror or str(exc))
    except Exception as exc:  # untrusted bytes: whatever the checks let through
        return StateError("corrupt", f"cannot be read: {type(exc).__name__}: {exc}")


def _read_file(p: Path, max_bytes: int, max_loops: int, keep: dict[str, int]) -> Read:
    for tmp in p.parent.glob(f".{p.name}.tmp-*"):  # left by a kill in the middle of a write
        with contextlib.suppress(OSError):
            tmp.unlink()
    if not p.exists():
        return None
    return read_state(p, max_bytes=max_bytes, max_loops=max_loops, keep=keep)


def restore_state(path: str | os.PathLike[str], config: Config, banks: Sequence[LoopGroup],
                  store: ResultStore, *, wall: float, time_scale: float) -> RestoreReport:
    """Read the state file (:func:`read_for_restore`) and restore what matches ``config``
    into fresh ``banks`` and ``store`` (:func:`apply_state`)."""
    return apply_state(read_for_restore(path, banks), path, config, banks, store, wall=wall,
                       time_scale=time_scale)


def apply_state(got: Read, path: str | os.PathLike[str], config: Config,
                banks: Sequence[LoopGroup], store: ResultStore, *, wall: float,
                time_scale: float) -> RestoreReport:
    """Restore what :func:`read_for_restore` read and matches ``config`` into fresh
    ``banks`` and ``store`` (on the event loop: the store's subscribers hear of it). Never
    raises for a bad file: it is set aside (one log line) and the report says why; the
    gateway starts empty."""
    report = RestoreReport()
    p = Path(path)
    if got is None:
        return report
    try:
        if isinstance(got, StateError):
            raise got
        header, arrays = got
        _apply(report, p, header, arrays, config=config, banks=banks, store=store,
               wall=wall, time_scale=time_scale)
    except StateError as exc:
        _refuse(report, p, exc)
    except Exception as exc:  # a file the checks let through that still breaks: start empty
        log.error("state file %s: restoring failed", p, exc_info=exc)
        _start_empty(banks, store)
        report.restored_windows = report.restored_results = 0
        _refuse(report, p, StateError("corrupt", f"cannot be restored: "
                                      f"{type(exc).__name__}: {exc}"))
    return report


def _refuse(report: RestoreReport, p: Path, exc: StateError) -> None:
    report.problem, report.kind = str(exc), exc.kind
    if exc.kind == "unreadable":  # a FIFO, a hung mount: nothing to move, or no answer
        log.error("state file %s: %s; starting fresh (the next write replaces it)", p, exc)
        return
    try:
        report.set_aside = set_aside(p, exc.kind)
    except OSError as err:
        log.warning("state file %s: %s; cannot set it aside (%s); starting fresh",
                    p, exc, err)
        return
    log.warning("state file %s: %s; moved to %s, starting fresh", p, exc, report.set_aside)


def _start_empty(banks: Sequence[LoopGroup], store: ResultStore) -> None:
    """Undo a restore that failed half-way: empty windows, no results."""
    for ref in banks:
        ref.bank.count = ref.bank.head = 0
        ref.bank.t[:] = np.nan
        ref.bank.quality[:] = Quality.MISSING
        if ref.bank.position is not None:
            ref.bank.position[:] = np.nan
    store.seq_floor[:] = 0
    for i in range(len(store.results)):
        if store.results[i] is not None:
            store.clear_result(i)


def _position(arrays: dict[str, NDArray[Any]], k: int, c: int) -> NDArray[Any] | None:
    """A restored column's positions (version 2, a bank that holds them): a value beyond
    :data:`MAX_MAGNITUDE` is no sample (NaN), as polling would not have stored it."""
    pos = arrays.get(f"b{k}_pos")
    if pos is None:
        return None
    col = pos[:, c]  # a view: the array read is the restore's own (no copy per column)
    with np.errstate(invalid="ignore"):
        col[~(np.abs(col) <= MAX_MAGNITUDE)] = np.nan
    return col


def _plausible(op: NDArray[Any], pv: NDArray[Any], q: NDArray[Any]
               ) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any]]:
    """A restored column as polling would have stored it: a GOOD sample that is not
    finite or beyond :data:`MAX_MAGNITUDE` is BAD (NaN)."""
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(op) & np.isfinite(pv) & (np.abs(op) <= MAX_MAGNITUDE) \
            & (np.abs(pv) <= MAX_MAGNITUDE)
    bad = (q == Quality.GOOD) & ~ok
    if not bad.any():
        return op, pv, q
    return (np.where(bad, np.float32(np.nan), op), np.where(bad, np.float32(np.nan), pv),
            np.where(bad, np.uint8(Quality.BAD), q))


def _apply(report: RestoreReport, p: Path, header: dict[str, Any],
           arrays: dict[str, NDArray[Any]], *, config: Config, banks: Sequence[LoopGroup],
           store: ResultStore, wall: float, time_scale: float) -> None:
    saved: dict[str, tuple[int, int, dict[str, Any]]] = {}  # name -> (bank, column, entry)
    for k, b in enumerate(header["banks"]):
        for c, entry in enumerate(b["loops"]):
            if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                saved[entry["name"]] = (k, c, entry)
    down_wall = wall - float(header["saved_wall"])
    report.clock_back_s = max(0.0, -down_wall)
    down_proc = None if down_wall < 0 else down_wall * time_scale  # None: unknown
    bump = seq_bump(header, wall, config.gateway.analysis_interval_s / time_scale,
                    config.gateway.persist_interval_s, written=p.stat().st_mtime)
    for name, (_k, _c, entry) in saved.items():
        i = store.index.get(name)
        seq = entry.get("seq", (entry.get("result") or {}).get("seq", 0))
        if i is not None and isinstance(seq, int) and seq > 0:
            store.seq_floor[i] = seq + bump
    for ref in banks:
        columns: dict[int, tuple[NDArray[Any] | None, ...]] = {}
        t_best: NDArray[np.float64] = np.empty(0)
        last_t = None
        for col, cfg in enumerate(ref.configs):
            hit = saved.get(cfg.name)
            saved_size = header["banks"][hit[0]]["size"] if hit is not None else None
            if hit is None or hit[2].get("signature") != loop_signature(config, cfg,
                                                                        samples=saved_size):
                report.fresh.append(cfg.name)  # (a window of another length: its newest)
                continue
            k, c, entry = hit
            t = arrays[f"b{k}_t"]
            columns[col] = (*_plausible(arrays[f"b{k}_op"][:, c], arrays[f"b{k}_pv"][:, c],
                                        arrays[f"b{k}_q"][:, c]), _position(arrays, k, c))
            if len(t) > len(t_best):
                t_best = t
            if len(t):
                last_t = float(t[-1])
            report.restored_windows += 1
            res = entry.get("result")
            if res is not None and entry.get("result_signature") == result_signature(config,
                                                                                       cfg):
                try:
                    judged = float(res.get("judged", res["t"]))  # a held verdict's age
                    lr = LoopResult(Assessment.from_dict(res["assessment"]),
                                    int(res["seq"]) + bump,
                                    float(res["t"]), float(res["window_fill"]),
                                    int(res["samples"]),
                                    None if judged == float(res["t"]) else judged,
                                    int(res.get("hold", 0)), _optional(res, "pv_swing"),
                                    _optional(res, "since"))
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
            missed = (float(header["saved_proc"]) - last_t + (down_proc or 0.0)) / ref.ts - 1
            rows = int(max(0.0, np.floor(missed + 1e-6)))  # 1e-6: float noise
            if down_proc is None:
                rows = max(rows, UNKNOWN_DOWNTIME_ROWS)
            rows = min(rows, ref.bank.size)
            nan = np.full(len(ref.configs), np.nan, dtype=np.float32)
            miss = np.full(len(ref.configs), Quality.MISSING, dtype=np.uint8)
            for r in range(rows):
                ref.bank.append(last_t + (r + 1) * ref.ts, nan, nan, miss)
            report.gap_rows = max(report.gap_rows, rows)
    if down_proc is None:
        log.warning("state file %s: the wall clock is %.0f s behind the file's last write "
                    "(it stepped back across the restart: an NTP correction, a clock set by "
                    "hand?); the downtime is unknown: a gap of at least %d samples in every "
                    "window%s", p, report.clock_back_s, UNKNOWN_DOWNTIME_ROWS,
                    "" if not bump else f", sequence numbers moved on by {bump}")
    moved = moved_indices(header.get("order", ()), store.loops)
    if moved:
        log.warning("state file %s: %s", p, moved_line(moved))
    log.info("state file %s: restored %d windows and %d assessments; %d loops start fresh; "
             "downtime gap %d samples", p, report.restored_windows, report.restored_results,
             len(report.fresh), report.gap_rows)


def _optional(res: dict[str, Any], key: str) -> float | None:
    """A result's optional number (issue 39: the list's; absent in older files)."""
    value = res.get(key)
    return None if value is None else float(value)


def seq_bump(header: dict[str, Any], wall: float, interval_wall_s: float,
             persist_wall_s: float, *, written: float | None = None) -> int:
    """How much to add to the saved sequence numbers so that they never go backwards: 0
    after a clean exit (the file was written last); after a kill, one more than the analysis
    rounds that could have run between the save and now (``wall``), as the file lags the
    registers SCADA read by up to one ``persist_interval_s``. With the wall clock behind the
    save (it stepped back) the time since is unknown: the rounds of the longest a kill can
    have lost, ``persist_wall_s`` and twice the write the file took (``written``, its
    modification time, less its save time: both by the clock that wrote it), and two more."""
    if header.get("clean") is True:
        return 0
    try:
        interval = max(float(header.get("analysis_interval_wall_s") or interval_wall_s), 1e-3)
        saved = float(header["saved_wall"])
        if wall < saved:
            write_s = min(max(0.0, (written or saved) - saved), persist_wall_s + 60.0)
            return int((persist_wall_s + 2 * write_s) // interval) + 2
        return int((wall - saved) // interval) + 1
    except (TypeError, ValueError):
        return 1
