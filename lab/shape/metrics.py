"""Figures of a score against labels: the area under the ROC curve (per record, and with
each group, a plant record's tag, weighing as one), what is found and falsely called at a
threshold (per record and per group), and the reliability table (score band -> share
sticky)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

THRESHOLDS = (0.5, 0.7, 0.8, 0.9)
BANDS = (0.0, 0.3, 0.5, 0.7, 0.8, 0.9, 1.0001)


def auc(score: np.ndarray, y: np.ndarray, weight: np.ndarray | None = None) -> float:
    """P(a sticky record scores above a good one), ties half (Mann-Whitney), with weights."""
    s, yy = np.asarray(score, np.float64), np.asarray(y, bool)
    w = np.ones(s.size) if weight is None else np.asarray(weight, np.float64)
    pos, neg = s[yy], s[~yy]
    wp, wn = w[yy], w[~yy]
    if pos.size == 0 or neg.size == 0:
        return float("nan")
    gt = (pos[:, None] > neg[None, :]) + 0.5 * (pos[:, None] == neg[None, :])
    return float((wp[:, None] * wn[None, :] * gt).sum() / (wp.sum() * wn.sum()))


def group_weights(groups: Sequence[str]) -> np.ndarray:
    """1 / records of the group: each group weighs as one."""
    _names, inv, counts = np.unique(np.asarray(groups), return_inverse=True, return_counts=True)
    return np.asarray(1.0 / counts[inv], dtype=np.float64)


def calls(score: np.ndarray, y: np.ndarray, t: float) -> tuple[int, int, int, int]:
    """(sticky found, sticky, others called, others) at threshold ``t``."""
    yy = np.asarray(y, bool)
    hit = np.asarray(score) >= t
    return (int((hit & yy).sum()), int(yy.sum()), int((hit & ~yy).sum()), int((~yy).sum()))


def group_calls(score: np.ndarray, y: np.ndarray, groups: Sequence[str], t: float
                ) -> tuple[int, int, int, int]:
    """The same per group: a group is called when at least half its records are."""
    g = np.asarray(groups)
    found = sticky = called = others = 0
    for name in np.unique(g):
        m = g == name
        hit = float(np.mean(np.asarray(score)[m] >= t)) >= 0.5
        if bool(np.asarray(y, bool)[m][0]):
            sticky, found = sticky + 1, found + hit
        else:
            others, called = others + 1, called + hit
    return found, sticky, called, others


def reliability(score: np.ndarray, y: np.ndarray, bands: Sequence[float] = BANDS
                ) -> list[tuple[float, float, int, float]]:
    """(low, high, windows, share sticky) per score band."""
    s, yy = np.asarray(score), np.asarray(y, bool)
    out = []
    for lo, hi in itertools.pairwise(bands):
        m = (s >= lo) & (s < hi)
        out.append((lo, min(hi, 1.0), int(m.sum()), float(yy[m].mean()) if m.any()
                    else float("nan")))
    return out


def threshold_for_precision(score: np.ndarray, y: np.ndarray, precision: float) -> float:
    """The lowest threshold at which the calls (score >= threshold) are at least
    ``precision`` right (1.0 when none is)."""
    s, yy = np.asarray(score, np.float64), np.asarray(y, bool)
    cands = np.unique(s)  # ascending
    right = np.array([yy[s >= t].mean() for t in cands])
    ok = np.flatnonzero(right >= precision)
    return float(cands[ok[0]]) if ok.size else 1.0


def sigmoid(z: np.ndarray) -> np.ndarray:
    return np.asarray(1.0 / (1.0 + np.exp(-np.clip(z, -60.0, 60.0))), dtype=np.float64)
