"""The OP-PV shape network: a small 1-D convolutional network that reads the shape of a
window's OP and PV over a few of its cycles and scores how much it looks like a sticky valve
(0-1). Trained on simulated loops only (lab/shape/: domain-randomised closed loops, each
beside a linear-valve twin that says whether stiction visibly shaped them); its weights ship
as data beside this module (``shape.npz``) and run here in numpy alone.

The input (:func:`inputs`): the window is cut into up to ``crops`` spans of ``cycles`` of
its cycle (the period from :func:`stiction.signal.cycle.find_cycle`, in samples; the whole
window when it holds fewer cycles, at most ``span_without_cycle`` samples when it has no
cycle), each span resampled to ``length`` points (means over equal bins when it is longer,
linear interpolation when shorter), each of OP and PV with its straight line removed and
divided by its standard deviation. PV is first turned so the loop reads as direct acting:
multiplied by the sign of the controller's action estimated from its integral term
(:func:`stiction.detectors.hammerstein.controller_sign`; a reverse-acting loop, a negative
process gain, an OP in % closed all read alike). Each span is read twice, as it is and
mirrored (OP and PV negated: the same loop upside down), four times when the controller's
sign cannot be told (PV's sign flipped too), and the network's penultimate features are
averaged over the spans and the readings, so the score does not depend on the signs and
uses the whole window.

The network (:class:`Network`): convolutions with ReLU, each but the last followed by a
max-pool, then the mean and the maximum of every channel over time, a dense layer with ReLU
(the *features*, :func:`features`: what the site alignment of
:mod:`stiction.diagnosis.site` works on) and a last dense layer to one logit (:func:`head`).
An ensemble's members each score, and their logits are averaged; they run as one network
(:func:`fuse`: one product a layer for all members and readings, the window's OP and PV
resampled and standardised together), about 0.4-0.7 ms a window. The numpy output equals the
training library's (PyTorch) to 1e-6 (tests/stiction/diagnosis/test_shape.py checks it on
fixed windows written at export).
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._validate import FloatArray
from ..detectors.hammerstein import controller_sign
from ..signal.cycle import find_cycle
from .site import PRIOR_WEIGHT, SiteStats, label_shift, platt

__all__ = ["WEIGHTS", "Fused", "Member", "Network", "ShapeScore", "at_site", "calibrated",
           "features", "fuse", "head", "inputs", "load", "orientation", "score", "spans"]

WEIGHTS = Path(__file__).with_name("shape.npz")
"""The shipped weights (written by ``python -m lab shape --write``)."""

MIRROR = ((1.0, 1.0), (-1.0, -1.0))
"""The readings of a span once PV is turned direct acting: (sign of OP, sign of PV)."""
SIGNS = ((1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0))
"""The readings when the controller's sign cannot be told."""
MIN_PERIOD = 8.0
"""A cycle of fewer samples is a zigzag of a few points: no shape to read. The network was
trained with such sticky windows left out (lab/shape/data.py), so its score there says
nothing either way (:attr:`ShapeScore.readable` is False)."""


@dataclasses.dataclass(frozen=True)
class Member:
    """One network of an ensemble: ``convs`` are (weight (out, in, kernel), bias) pairs,
    ``dense`` (weight (hidden, 2 x channels), bias) the features' layer, ``last`` (weight
    (1, hidden), bias) the logit's."""

    convs: tuple[tuple[FloatArray, FloatArray], ...]
    dense: tuple[FloatArray, FloatArray]
    last: tuple[FloatArray, FloatArray]


@dataclasses.dataclass(frozen=True)
class Fused:
    """An ensemble's members as one network (:func:`fuse`): the first convolution as (kernel
    x in, members x out) columns, each later one as (members, kernel x in, out), each with
    its bias (members x out); the features' layer as (in, hidden) and its bias; every
    member's channels side by side."""

    first: tuple[FloatArray, FloatArray]
    convs: tuple[tuple[FloatArray, FloatArray], ...]
    dense: tuple[FloatArray, FloatArray]


def _columns(w: FloatArray) -> FloatArray:
    """A convolution's weight (out, in, kernel) as (kernel x in, out): one product a layer."""
    return np.ascontiguousarray(np.transpose(w, (2, 1, 0)).reshape(-1, w.shape[0]))


def fuse(members: Sequence[Member]) -> Fused:
    """The members as one network: the first convolution's weights side by side (every
    member reads the same input), each later one a batch of the members' own products
    (each reads its own channels), the features' layer block-diagonal: one call a layer for
    the whole ensemble, the same sums."""
    count = len(members)
    first = (_columns(np.concatenate([m.convs[0][0] for m in members], axis=0)),
             np.concatenate([m.convs[0][1] for m in members]))
    convs = tuple((np.stack([_columns(m.convs[j][0]) for m in members]),
                   np.concatenate([m.convs[j][1] for m in members]))
                  for j in range(1, len(members[0].convs)))
    c, h = members[0].convs[-1][0].shape[0], members[0].dense[0].shape[0]
    dense = np.zeros((count * h, 2 * count * c))
    for i, m in enumerate(members):  # pooled: every member's means, then every member's maxima
        dense[i * h:(i + 1) * h, i * c:(i + 1) * c] = m.dense[0][:, :c]
        dense[i * h:(i + 1) * h, (count + i) * c:(count + i + 1) * c] = m.dense[0][:, c:]
    return Fused(first, convs, (np.ascontiguousarray(dense.T),
                                np.concatenate([m.dense[1] for m in members])))


@dataclasses.dataclass(frozen=True)
class Network:
    """The ensemble and how its input is made (module doc)."""

    members: tuple[Member, ...]
    length: int = 256
    cycles: float = 6.0
    crops: int = 4
    span_without_cycle: int = 1024
    meta: dict[str, object] = dataclasses.field(default_factory=dict)
    sources: tuple[tuple[SiteStats, SiteStats], ...] = ()
    """Per member, the statistics of its features on held-out simulated windows, sticky and
    good apart: the source of the site alignment (:mod:`.site`)."""
    fused: Fused = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "fused", fuse(self.members))

    @property
    def n_weights(self) -> int:
        return sum(int(a.size + b.size) for m in self.members
                   for a, b in (*m.convs, m.dense, m.last))


@dataclasses.dataclass(frozen=True)
class ShapeScore:
    """``score`` in [0, 1] (the sigmoid of ``logit``); ``features`` the penultimate layer
    averaged over spans and readings, one row per ensemble member; ``spans`` how many spans
    were read, ``period`` the cycle used (samples; None: no cycle), ``sign`` the controller's
    action PV was multiplied by (0: not told, both signs read)."""

    score: float
    logit: float
    features: FloatArray
    spans: int
    period: float | None
    sign: float

    @property
    def readable(self) -> bool:
        """False when the cycle is shorter than :data:`MIN_PERIOD` samples."""
        return self.period is None or self.period >= MIN_PERIOD


def spans(n: int, period: float | None, *, cycles: float, crops: int,
          span_without_cycle: int) -> list[tuple[int, int]]:
    """(start, stop) of the spans read from a window of ``n`` samples (module doc)."""
    if period is not None and period > 0 and cycles * period < n:
        span = max(round(cycles * period), 8)
    elif period is None or period <= 0:
        span = min(n, span_without_cycle)
    else:
        span = n
    count = max(1, min(crops, n // span))
    starts = np.linspace(0, n - span, count).round().astype(int) if count > 1 else \
        np.array([(n - span) // 2])
    return [(int(a), int(a) + span) for a in starts]


def _resample(x: FloatArray, length: int) -> FloatArray:
    """The rows of ``x`` (rows, n) less their means at ``length`` points: the means of equal
    bins when longer (the running sum read at the bins' edges, linear between samples),
    linear interpolation when shorter."""
    n = x.shape[1]
    x = x - x.mean(axis=1, keepdims=True)  # the mean goes at standardisation; the sums
    if n >= length:                       # keep their precision without it
        c = np.concatenate([np.zeros((x.shape[0], 1)), np.cumsum(x, axis=1)], axis=1)
        edges = np.linspace(0.0, n, length + 1)
        i = np.minimum(edges.astype(np.intp), n - 1)
        cum = c[:, i] + (edges - i) * x[:, i]
        return np.asarray(np.diff(cum, axis=1) / (n / length), dtype=np.float64)
    at = np.linspace(0.0, n - 1.0, length)
    return np.stack([np.interp(at, np.arange(n), row) for row in x])


def _standardise(x: FloatArray) -> FloatArray:
    """The rows of ``x`` (..., length) without their least-squares lines, divided by their
    standard deviations (zeros where a row is flat)."""
    t = np.linspace(-1.0, 1.0, x.shape[-1])
    y = x - x.mean(axis=-1, keepdims=True)
    y = y - t * ((y @ t) / float(t @ t))[..., None]
    sd = np.std(y, axis=-1, keepdims=True)
    flat = sd <= 1e-12 * np.maximum(1.0, np.max(np.abs(x), axis=-1, keepdims=True))
    return np.asarray(np.where(flat, 0.0, y / np.where(flat, 1.0, sd)), dtype=np.float64)


def orientation(op: FloatArray, pv: FloatArray, period: float | None) -> float:
    """The sign of the controller's action (+1 direct, -1 reverse, 0 not told), over an
    eighth of the cycle, or of a quarter of the window when it has none."""
    n = len(op)
    scale = period if period is not None and period > 0 else n / 4.0
    return controller_sign(np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64),
                           scale)


def inputs(op: FloatArray, pv: FloatArray, period: float | None, *, length: int = 256,
           cycles: float = 6.0, crops: int = 4, span_without_cycle: int = 1024,
           sign: float = 1.0) -> FloatArray:
    """The network's input for a window: (spans, 2, ``length``), OP then PV times ``sign``
    (module doc); the readings are made by :func:`features`."""
    xy = np.stack([np.asarray(op, dtype=np.float64),
                   np.asarray(pv, dtype=np.float64) * (-1.0 if sign < 0 else 1.0)])
    out = [_resample(xy[:, a:b], length)
           for a, b in spans(xy.shape[1], period, cycles=cycles, crops=crops,
                             span_without_cycle=span_without_cycle)]
    return _standardise(np.stack(out))


def _padded(x: FloatArray, k: int) -> FloatArray:
    """``x`` (batch, time, ...) zero-padded for a 'same' convolution of kernel ``k`` (as
    PyTorch pads: ``k // 2`` before)."""
    xp = np.zeros((x.shape[0], x.shape[1] + k - 1, *x.shape[2:]))
    xp[:, k // 2 : k // 2 + x.shape[1]] = x
    return xp


def _conv(x: FloatArray, wk: FloatArray, b: FloatArray) -> FloatArray:
    """The first convolution (a cross-correlation, as PyTorch computes it): ``x`` (batch,
    time, in), ``wk`` (kernel x in, out) -> (batch, time, out)."""
    t, c = x.shape[1], x.shape[2]
    k = wk.shape[0] // c
    xp = _padded(x, k)
    cols = np.concatenate([xp[:, j : j + t] for j in range(k)], axis=2)  # (batch, time, k x in)
    return np.asarray(cols @ wk + b, dtype=np.float64)


def _convs(x: FloatArray, wk: FloatArray, b: FloatArray) -> FloatArray:
    """A later convolution of every member at once: ``x`` (batch, time, members x in),
    ``wk`` (members, kernel x in, out) -> (batch, time, members x out)."""
    b_, t, _ = x.shape
    m, kc, out = wk.shape
    c = x.shape[2] // m
    k = kc // c
    xp = _padded(x.reshape(b_, t, m, c), k)
    cols = np.stack([xp[:, j : j + t] for j in range(k)], axis=3)  # (batch, time, m, k, in)
    cols = np.transpose(cols, (2, 0, 1, 3, 4)).reshape(m, b_ * t, kc)
    y = np.transpose((cols @ wk).reshape(m, b_, t, out), (1, 2, 0, 3)).reshape(b_, t, m * out)
    return np.asarray(y + b, dtype=np.float64)


def _pool(h: FloatArray) -> FloatArray:
    """Max over pairs of time steps (a trailing odd step dropped)."""
    t = h.shape[1] // 2 * 2
    return np.asarray(h[:, :t].reshape(h.shape[0], t // 2, 2, h.shape[2]).max(axis=2))


def _trunk(f: Fused, x: FloatArray) -> FloatArray:
    """Penultimate features of ``x`` (batch, 2, length) -> (batch, members x hidden)."""
    h = np.maximum(_conv(np.transpose(x, (0, 2, 1)), *f.first), 0.0)
    for wk, b in f.convs:
        h = np.maximum(_convs(_pool(h), wk, b), 0.0)
    pooled = np.concatenate([h.mean(axis=1), h.max(axis=1)], axis=1)
    w, b = f.dense
    return np.asarray(np.maximum(pooled @ w + b, 0.0), dtype=np.float64)


def features(net: Network, x: FloatArray, *, told: bool = True, average: bool = True
             ) -> FloatArray:
    """The penultimate features of spans ``x`` (spans, 2, length), each read as it is and
    mirrored (and with PV's sign flipped unless the controller's sign was ``told``):
    (members, hidden) averaged over spans and readings, or (members, spans x readings,
    hidden) with ``average=False``."""
    signs = np.array(MIRROR if told else SIGNS)[:, :, None]
    batch = (x[:, None] * signs[None]).reshape(-1, 2, x.shape[2])
    f = _trunk(net.fused, batch)
    f = np.transpose(f.reshape(batch.shape[0], len(net.members), -1), (1, 0, 2))
    return f.mean(axis=1) if average else f


def head(net: Network, feats: FloatArray) -> FloatArray:
    """Logits of features (members, ..., hidden): the ensemble's mean over members."""
    out = [feats[i] @ m.last[0][0] + m.last[1][0] for i, m in enumerate(net.members)]
    return np.asarray(np.mean(out, axis=0), dtype=np.float64)


def _sigmoid(z: float) -> float:
    return float(1.0 / (1.0 + np.exp(-np.clip(z, -60.0, 60.0))))


def score(op: FloatArray, pv: FloatArray, *, period: float | None = None,
          integrating: bool = False, find: bool = True, net: Network | None = None
          ) -> ShapeScore:
    """Score a window (finite OP and PV of equal length, at least 8 samples). ``period`` is
    its cycle in samples; None with ``find`` looks it up (:func:`find_cycle`, OP's cycle
    first unless ``integrating``), None without ``find`` reads it as having no cycle."""
    net = load() if net is None else net
    if period is None and find:
        period = find_cycle(np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64),
                            integrating=integrating).period
    sign = orientation(op, pv, period)
    x = inputs(op, pv, period, length=net.length, cycles=net.cycles, crops=net.crops,
               span_without_cycle=net.span_without_cycle, sign=sign)
    f = features(net, x, told=sign != 0)
    z = float(head(net, f))
    return ShapeScore(_sigmoid(z), z, f, x.shape[0], period, sign)


def calibrated(net: Network, logits: FloatArray | float) -> FloatArray:
    """The probability that a window is sticky where sticky windows are as common as in
    the held-out simulation (``meta["sim_prior"]``): the logit through the Platt map fitted
    there (``meta["platt"]``)."""
    ab = net.meta["platt"]
    if not isinstance(ab, list | tuple) or len(ab) != 2:
        raise ValueError(f"the weights' meta has no Platt map: {ab!r}")
    return platt(logits, float(ab[0]), float(ab[1]))


def at_site(net: Network, logits: Sequence[float] | FloatArray) -> tuple[FloatArray, float]:
    """The probabilities of a site's windows (the files of one batch, a gateway's loops'
    latest windows) at the share of sticky windows they imply, and that share (label-shift
    EM, :func:`stiction.diagnosis.site.label_shift`, the simulation's share counted as
    :data:`~stiction.diagnosis.site.PRIOR_WEIGHT` windows). Call stiction at
    ``meta["threshold"]`` (90 % of calls right on held-out simulation). One window alone
    moves the share little: score it with :func:`calibrated` and say so."""
    prior = net.meta["sim_prior"]
    if not isinstance(prior, float):
        raise ValueError(f"the weights' meta has no simulated share: {prior!r}")
    return label_shift(calibrated(net, np.asarray(logits, dtype=np.float64)), prior,
                       prior_weight=PRIOR_WEIGHT)


def _arrays(d: dict[str, np.ndarray], prefix: str) -> tuple[FloatArray, FloatArray]:
    return (np.asarray(d[f"{prefix}.weight"], dtype=np.float64),
            np.asarray(d[f"{prefix}.bias"], dtype=np.float64))


def from_arrays(arrays: dict[str, np.ndarray]) -> Network:
    """A network from the arrays of its weights file: ``config`` (JSON: ``length``,
    ``cycles``, ``crops``, ``span_without_cycle``, ``members``, ``convs``, ``meta``),
    ``m{i}.conv{j}.weight``/``.bias``, ``m{i}.dense.*``, ``m{i}.last.*`` and the source
    statistics ``m{i}.sticky.n``/``.mean``/``.scatter``, ``m{i}.good.*``."""
    cfg = json.loads(str(arrays["config"]))
    count = int(cfg["members"])
    members = tuple(
        Member(tuple(_arrays(arrays, f"m{i}.conv{j}") for j in range(int(cfg["convs"]))),
               _arrays(arrays, f"m{i}.dense"), _arrays(arrays, f"m{i}.last"))
        for i in range(count))
    sources = tuple(
        tuple(SiteStats(int(arrays[f"m{i}.{k}.n"]),
                        np.asarray(arrays[f"m{i}.{k}.mean"], dtype=np.float64),
                        np.asarray(arrays[f"m{i}.{k}.scatter"], dtype=np.float64))
              for k in ("sticky", "good"))
        for i in range(count) if f"m{i}.sticky.n" in arrays)
    return Network(members, int(cfg["length"]), float(cfg["cycles"]), int(cfg["crops"]),
                   int(cfg["span_without_cycle"]), dict(cfg.get("meta", {})),
                   tuple((a, b) for a, b in sources))


def to_arrays(net: Network) -> dict[str, np.ndarray]:
    """The inverse of :func:`from_arrays` (float32 weights)."""
    cfg = {"length": net.length, "cycles": net.cycles, "crops": net.crops,
           "span_without_cycle": net.span_without_cycle, "members": len(net.members),
           "convs": len(net.members[0].convs), "meta": net.meta}
    out: dict[str, np.ndarray] = {"config": np.array(json.dumps(cfg))}
    for i, m in enumerate(net.members):
        named: Sequence[tuple[str, tuple[FloatArray, FloatArray]]] = [
            *((f"conv{j}", c) for j, c in enumerate(m.convs)), ("dense", m.dense),
            ("last", m.last)]
        for name, (w, b) in named:
            out[f"m{i}.{name}.weight"] = np.asarray(w, dtype=np.float32)
            out[f"m{i}.{name}.bias"] = np.asarray(b, dtype=np.float32)
    for i, pair in enumerate(net.sources):
        for k, st in zip(("sticky", "good"), pair, strict=True):
            out[f"m{i}.{k}.n"] = np.array(st.n)
            out[f"m{i}.{k}.mean"] = st.mean
            out[f"m{i}.{k}.scatter"] = st.scatter
    return out


@functools.cache
def load(path: Path = WEIGHTS) -> Network:
    """The network in ``path`` (the shipped weights by default), read once."""
    with np.load(path, allow_pickle=False) as d:
        return from_arrays({k: d[k] for k in d.files})
