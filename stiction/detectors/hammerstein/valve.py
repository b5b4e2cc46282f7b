"""OP's turning points and the sticky valve's position for many candidates at once."""

from __future__ import annotations

import numpy as np

from ..._validate import FloatArray
from ...signal.arrays import median

__all__ = ["decimate", "median_swing", "sticky_valve", "turning_points"]


def turning_points(u: FloatArray, h: float) -> np.ndarray:
    """Indices of OP's alternating extremes with reversals of at least ``h`` (zigzag), the
    first and last sample included."""
    n = u.size
    d = np.sign(u[1:] - u[:-1])
    nz = d.nonzero()[0]
    if nz.size == 0:
        return np.array([0, n - 1])
    turn = nz[1:][d[nz[1:]] != d[nz[:-1]]]  # diff index where the direction changes
    cand = np.concatenate(([0], turn, [n - 1]))
    vals = u[cand].tolist()
    idx = cand.tolist()
    piv = [0]
    last = vals[0]
    trend = 0
    ext_i, ext_v = 0, vals[0]
    for i, v in zip(idx[1:], vals[1:], strict=True):
        if (trend >= 0 and v > ext_v) or (trend <= 0 and v < ext_v):
            ext_i, ext_v = i, v
            if trend == 0 and abs(v - last) >= h:
                trend = 1 if v > last else -1
        if (trend == 1 and ext_v - v >= h) or (trend == -1 and v - ext_v >= h):
            piv.append(ext_i)
            last, trend = ext_v, -trend
            ext_i, ext_v = i, v
    if ext_i != piv[-1]:
        piv.append(ext_i)
    if piv[-1] != n - 1:
        piv.append(n - 1)
    return np.array(piv)


def sticky_valve(u: FloatArray, piv: np.ndarray, s_band: FloatArray,
                 jump: FloatArray) -> FloatArray:
    """Valve position (rows: candidates ``s_band[i]``, ``jump[i]``) for OP ``u`` with turning
    points ``piv`` (``piv[0] == 0``), up to a constant. The window is taken to start at an
    OP turning point where the valve has just slipped (its state before is unknown)."""
    m = u.size
    ext = u[piv[1:]]
    s = np.sign(ext - u[piv[:-1]])
    s[s == 0] = 1.0
    # reversal 0 is the start, a slip the other way; reversal k + 1 ends run k
    ext_x = np.concatenate(([u[0]], ext))
    s_x = np.concatenate(([-s[0]], s))
    seg = np.zeros(m, dtype=np.intp)
    seg[piv[1:-1] + 1] = 1
    seg = seg.cumsum()
    st = s[seg]
    big = 4.0 * (float(np.maximum.reduce(np.abs(u))) + 1.0)
    run_ext = st * (np.maximum.accumulate(st * u + big * seg) - big * seg)
    nc, nk = s_band.size, s.size
    col = np.arange(1, nk + 1)
    sb, jb = s_band[:, None], jump[:, None]

    def refs(slip: np.ndarray) -> tuple[np.ndarray, FloatArray]:
        last = np.maximum.accumulate(np.where(slip, col, 0), axis=1)
        ref = np.concatenate((np.zeros((slip.shape[0], 1), dtype=np.intp), last[:, :-1]),
                             axis=1)
        return ref, ext_x[ref]

    slip = (s * (ext - ext_x[:-1]))[None, :] > sb
    # fixed point of the slip decisions; a row that repeats itself is final (each pass
    # settles at least one more reversal), so only the others are iterated
    todo = np.arange(nc)
    for _ in range(nk + 1):
        ref, e_ref = refs(slip[todo])
        thr = np.where(s_x[ref] == s[None, :], jb[todo], sb[todo])
        new = s[None, :] * (ext[None, :] - e_ref) > thr
        changed = np.logical_or.reduce(new != slip[todo], axis=1)
        slip[todo] = new
        todo = todo[changed]
        if todo.size == 0:
            break
    ref, e_ref = refs(slip)
    thr = np.where(s_x[ref] == s[None, :], jb, sb)
    beyond = np.maximum(0.0, s * (ext - e_ref) - thr - jb)
    step = np.where(slip, s * (jb + beyond), 0.0)
    level = np.concatenate((np.zeros((nc, 1)), step.cumsum(axis=1)[:, :-1]), axis=1)
    d = st * (run_ext - e_ref[:, seg]) - thr[:, seg]
    vp = level[:, seg] + np.where(d > 0, st * (jb + np.maximum(0.0, d - jb)), 0.0)
    return np.asarray(vp)


def median_swing(u: FloatArray, piv: np.ndarray) -> float:
    """Median OP swing between turning points (the partial first and last runs left out
    when there are enough)."""
    ext = u[piv]
    swings = np.abs(ext[1:] - ext[:-1])
    return median(swings[1:-1] if swings.size > 3 else swings)


def decimate(x: FloatArray, q: int) -> FloatArray:
    k = x.size // q
    return np.asarray(np.add.reduce(x[x.size - k * q :].reshape(k, q), axis=1) / q)
