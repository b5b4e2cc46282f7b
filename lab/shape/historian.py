"""What a plant historian does to a loop's signals before anyone reads them: samples them
every ``interval`` simulation steps (a snapshot, or the interval's mean as an averaging
historian or a PLC's aggregate does), quantises them (a 12-bit card, a 0.1 % output, a PV
shown to a few digits) and compresses them (a deadband, exception reporting, or the
swinging door of Bristol 1990 as PI and its kin keep data), then replays the kept points by
linear interpolation at the sample times, as an export from such a historian does."""

from __future__ import annotations

import numpy as np

from stiction._validate import FloatArray

from .draws import Loop


def sample(x: FloatArray, interval: int, averaged: bool) -> FloatArray:
    """Every ``interval``-th step of ``x`` (the last of each interval) or each interval's
    mean; ``x`` holds a whole number of intervals."""
    if interval == 1:
        return np.asarray(x, dtype=np.float64)
    blocks = np.asarray(x, dtype=np.float64).reshape(-1, interval)
    return blocks.mean(axis=1) if averaged else blocks[:, -1].copy()


def quantise(x: FloatArray, quantum: float) -> FloatArray:
    return np.round(x / quantum) * quantum if quantum > 0 else x


def deadband(x: FloatArray, dev: float) -> np.ndarray:
    """Indices kept by exception reporting: a value is kept when it differs from the last
    kept one by more than ``dev`` (the first and the last always)."""
    keep = [0]
    last = x[0]
    for i in range(1, x.size):
        if abs(x[i] - last) > dev:
            keep.append(i)
            last = x[i]
    if keep[-1] != x.size - 1:
        keep.append(x.size - 1)
    return np.asarray(keep)


def swinging_door(x: FloatArray, dev: float) -> np.ndarray:
    """Indices kept by the swinging-door algorithm (Bristol 1990): from the last kept
    point the doors (slopes to each new point +- ``dev``) close as points arrive; when they
    cross, the point before is kept and the doors reopen from it."""
    keep = [0]
    a = 0
    up, lo = np.inf, -np.inf
    for i in range(1, x.size):
        dt = i - a
        up = min(up, (x[i] + dev - x[a]) / dt)
        lo = max(lo, (x[i] - dev - x[a]) / dt)
        if lo > up:
            a = i - 1
            keep.append(a)
            dt = i - a
            up = (x[i] + dev - x[a]) / dt
            lo = (x[i] - dev - x[a]) / dt
    if keep[-1] != x.size - 1:
        keep.append(x.size - 1)
    return np.asarray(keep)


def compress(x: FloatArray, kind: str, dev: float) -> FloatArray:
    """``x`` as a compressing historian replays it: the kept points, linearly interpolated
    at every sample time."""
    if not kind or dev <= 0:
        return x
    keep = deadband(x, dev) if kind == "deadband" else swinging_door(x, dev)
    t = np.arange(x.size, dtype=np.float64)
    return np.asarray(np.interp(t, t[keep], x[keep]), dtype=np.float64)


def record(loop: Loop, op: FloatArray, pv: FloatArray, ref_op: FloatArray,
           ref_pv: FloatArray) -> tuple[FloatArray, FloatArray]:
    """OP (%) and PV as the historian of ``loop`` gives them. Quantum and compression
    deviation are taken from ``ref_op``/``ref_pv`` (the twin's sampled signals), so a
    sticky run and its twin go through the same historian."""
    out = []
    for x, ref, is_pv in ((op, ref_op, False), (pv, ref_pv, True)):
        y = sample(x, loop.interval, loop.averaged)
        p5, p95 = np.percentile(ref, [5, 95])
        span = max(float(p95 - p5), 1e-6)
        if is_pv and loop.pv_levels:
            y = quantise(y, span / loop.pv_levels)
        elif not is_pv and loop.op_quantum:
            y = quantise(y, 100.0 * loop.op_quantum)
        y = compress(y, loop.compression, loop.compression_dev * span)
        out.append(y)
    return out[0], out[1]
