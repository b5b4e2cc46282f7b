"""The Tennessee Eastman runs cut into the windows the corpus keeps: each run simulated once
(lab/sources/tep.py) and reduced to its views (two gateway windows at 1.8 s, the recorded
part at 36 s and at 180 s), what its loops and sticky valves did, cached per run;
:func:`views` lists a reduced run's windows. lab/labels/tep.py labels them against the
mode's normal runs."""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from .. import _cache
from ..sources import tep
from ..sources.tep import LOOPS, lagged, valve_command
from ..sources.tep_plan import TepRun

TEP_VERSION = "0.2.0"  # pyproject's bench extra pins it; the cache is keyed on it

CACHE_VERSION = 1  # bump when the simulation or the reduction changes (not the labels)
TS = 1.8  # s: the controller period, the gateway view's sample time
ONSET_H = 0.5  # disturbances and sticky valves on, h after the mode's settled state
RECORD_H = (4.5, 28.5)  # kept: 24 h, from 4 h after the onset
GATEWAY_N = 4000  # 2 h at 1.8 s
GATEWAY_AT = (2.0, 14.0)  # h into the recorded part: two non-overlapping gateway windows
HISTORIAN = 20  # 36 s: every 20th sample (a snapshot, as most historians return)
STUDY = 100  # 180 s: the mean of every 100 samples (a historian's average mode)
NPERSEG = 4096  # Welch segments of 2 h for the spectra
F_MAX = 1.0 / 30.0  # Hz: spectra kept up to periods of 30 s
VALVE_TAU = 5.0  # s: the model's valve lag for XMV 7, 8, 10 and 11 (vtau)
MIN_RECORD = 6.0  # h: a tripped run keeps its historian and study views if this long


@dataclasses.dataclass(frozen=True)
class LoopSummary:
    """One loop over a run's recorded part: OP and PV SDs and spectra."""

    op_sd: float
    pv_sd: float
    freqs: np.ndarray
    op_psd: np.ndarray
    pv_psd: np.ndarray


def cache_key(run: TepRun) -> str:
    text = repr((dataclasses.astuple(run), CACHE_VERSION, TEP_VERSION, RECORD_H, ONSET_H))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def _spectrum(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f, p = signal.welch(x, fs=1.0 / TS, nperseg=min(NPERSEG, x.size), detrend="linear")
    keep = f <= F_MAX
    return f[keep], p[keep].astype(np.float32)


def _valve(op: np.ndarray, pos: np.ndarray, band: float) -> dict[str, Any]:
    """What the corpus keeps of a sticky valve: its OP (from which :func:`valve_stats`
    rebuilds the valve), the command behind its first move, the rebuilt position's largest
    distance from the simulated one (the check that the rule is the model's), its cycle
    and its position at the gateway and historian views' samples."""
    a = float(np.exp(-TS / VALVE_TAU))
    start = float(pos[1] - a * pos[0]) / (1.0 - a)  # the command behind the first move
    cmd = valve_command(op, band, start=start)
    err = np.abs(lagged(cmd, TS, VALVE_TAU, float(pos[0])) - pos)[200:]
    f, p = _spectrum(pos)
    band_ok = f >= 1.0 / 7200.0
    # the cycle: the peak of the position's rate spectrum (f^2 p), flat for a random walk
    # and for slow swings, sharp at a stick-slip cycle's square wave
    w = p[band_ok] * f[band_ok] ** 2
    f0 = float(f[band_ok][np.argmax(w)]) if band_ok.any() else float("nan")
    snap = slice(HISTORIAN - 1, pos.size - pos.size % HISTORIAN, HISTORIAN)
    return {"band": band, "f0": f0, "model_error": float(err.max(initial=0.0)),
            "op": op.astype(np.float32), "start": start,
            "pos_historian": pos[snap].astype(np.float32),
            "pos_gateway": {k: pos[round(at * 3600 / TS) :][:GATEWAY_N].astype(np.float32)
                            for k, at in enumerate(GATEWAY_AT)}}


def reduce(run: TepRun, arrays: Any) -> dict[str, Any]:
    """What the corpus keeps of one run (float32): two gateway windows at 1.8 s, the
    recorded part at 36 s (snapshots, with setpoints and every XMEAS) and at 180 s (means),
    per loop the SDs and spectra of OP and PV, per sticky valve what it did."""
    op, pv = arrays.op.T, arrays.pv.T  # (loops, samples)
    n = op.shape[1]
    out: dict[str, Any] = {"run": run, "tripped": arrays.tripped, "hours": n * TS / 3600,
                           "gateway": {}}
    for k, at in enumerate(GATEWAY_AT):
        i = round(at * 3600 / TS)
        if i + GATEWAY_N <= n:
            out["gateway"][k] = (op[:, i : i + GATEWAY_N].astype(np.float32),
                                 pv[:, i : i + GATEWAY_N].astype(np.float32))
    if n * TS / 3600 >= MIN_RECORD:
        snap = slice(HISTORIAN - 1, n - n % HISTORIAN, HISTORIAN)
        out["historian"] = {"op": op[:, snap].astype(np.float32),
                            "pv": pv[:, snap].astype(np.float32),
                            "sp": arrays.sp.T[:, snap].astype(np.float32),
                            "xmeas": arrays.xmeas.T[:, snap].astype(np.float32)}
        m = n - n % STUDY
        out["study"] = {k: v[:, :m].reshape(v.shape[0], -1, STUDY).mean(axis=2)
                        .astype(np.float32) for k, v in (("op", op), ("pv", pv))}
    out["summary"] = []
    for j in range(op.shape[0]):
        f, p_op = _spectrum(op[j])
        _, p_pv = _spectrum(pv[j])
        out["summary"].append(LoopSummary(float(op[j].std()), float(pv[j].std()), f,
                                              p_op, p_pv))
    bands = run.bands
    out["valves"] = {j: _valve(op[j], arrays.pos[:, j], bands[lp.xmv])
                     for j, lp in enumerate(LOOPS) if lp.xmv in bands}
    return out


def build(runs: Iterable[TepRun], cache: Path, log: Callable[[str], None]) -> int:
    """Simulate and reduce every run of ``runs`` whose reduction is not cached yet, one at
    a time (settled modes cached too); returns how many were simulated."""
    from importlib.metadata import version  # noqa: PLC0415

    if version("tep-studio") != TEP_VERSION:
        raise RuntimeError(f"the corpus is made with tep-studio {TEP_VERSION}, "
                           f"{version('tep-studio')} is installed (make corpus installs it)")
    cache.mkdir(parents=True, exist_ok=True)
    starts: dict[str, tep.Settled] = {}
    done = 0
    for run in runs:
        path = cache / f"{run.id}-{cache_key(run)}.pickle"
        if path.exists():
            continue
        if run.mode not in starts:
            starts[run.mode] = settled(run.mode, cache)
        arrays = tep.run(starts[run.mode], run.seed, run.idvs, run.bands,
                         onset_h=ONSET_H, record_h=RECORD_H)
        _cache.dump(reduce(run, arrays), path)
        done += 1
        log(f"  {run.id}: {arrays.t.size} samples{'; ' + arrays.tripped if arrays.tripped else ''}")
    return done


def settled(mode: str, cache: Path | None = None) -> tep.Settled:
    """``mode`` after its settling run (lab/sources/tep.py), cached in ``cache`` (the built
    corpus's TEP folder if None)."""
    cache = _cache.corpus() / "tep" if cache is None else cache
    key = hashlib.sha256(repr((mode, tep.SETTLE_H, CACHE_VERSION, TEP_VERSION)).encode())
    path = cache / f"settled-{mode}-{key.hexdigest()[:12]}.pickle"
    if path.exists():
        out: tep.Settled = _cache.load(path)
        return out
    start = tep.settle(mode)
    _cache.dump(start, path)
    return start


def load(runs: Iterable[TepRun], cache: Path) -> list[dict[str, Any]]:
    """The cached reductions of ``runs`` that exist (no tep-studio needed)."""
    out = []
    for run in runs:
        path = cache / f"{run.id}-{cache_key(run)}.pickle"
        if path.exists():
            out.append(_cache.load(path))
    return out


def views(d: dict[str, Any]) -> list[tuple[str, str, float, float, np.ndarray, np.ndarray]]:
    """(view, stats key, ts, t0, op rows, pv rows) of every view the run kept."""
    out = [("gateway", f"gateway{k}", TS, RECORD_H[0] + GATEWAY_AT[k], op, pv)
           for k, (op, pv) in d["gateway"].items()]
    if "historian" in d:
        h, s = d["historian"], d["study"]
        out.append(("historian", "whole", TS * HISTORIAN, RECORD_H[0], h["op"], h["pv"]))
        out.append(("study", "whole", TS * STUDY, RECORD_H[0], s["op"], s["pv"]))
    return out
