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
An ensemble's members each score, and their logits are averaged. The numpy output equals the
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

__all__ = ["WEIGHTS", "Member", "Network", "ShapeScore", "at_site", "calibrated", "features",
           "head", "inputs", "load", "orientation", "score", "spans"]

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
    columns: tuple[FloatArray, ...] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # each convolution's weight as (kernel x in, out): one product per layer
        object.__setattr__(self, "columns", tuple(
            np.ascontiguousarray(np.transpose(w, (2, 1, 0)).reshape(-1, w.shape[0]))
            for w, _ in self.convs))


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
    """``x`` less its mean at ``length`` points: the means of equal bins when longer, linear
    interpolation when shorter."""
    n = x.size
    x = x - x.mean()  # the mean goes at standardisation; off here, the sums keep precision
    if n >= length:
        c = np.concatenate(([0.0], np.cumsum(x)))
        edges = np.linspace(0.0, n, length + 1)
        cum = np.interp(edges, np.arange(n + 1), c)
        return np.asarray(np.diff(cum) / (n / length), dtype=np.float64)
    return np.asarray(np.interp(np.linspace(0.0, n - 1.0, length), np.arange(n), x),
                      dtype=np.float64)


def _standardise(x: FloatArray) -> FloatArray:
    """``x`` without its least-squares line, divided by its standard deviation (zeros when
    it is flat)."""
    t = np.linspace(-1.0, 1.0, x.size)
    y = x - x.mean()
    y = y - t * (float(t @ y) / float(t @ t))
    sd = float(np.std(y))
    return y / sd if sd > 1e-12 * max(1.0, float(np.max(np.abs(x)))) else np.zeros_like(y)


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
    op_ = np.asarray(op, dtype=np.float64)
    pv_ = np.asarray(pv, dtype=np.float64) * (-1.0 if sign < 0 else 1.0)
    out = [np.stack([_standardise(_resample(x[a:b], length)) for x in (op_, pv_)])
           for a, b in spans(op_.size, period, cycles=cycles, crops=crops,
                             span_without_cycle=span_without_cycle)]
    return np.stack(out)


def _conv(x: FloatArray, wk: FloatArray, b: FloatArray) -> FloatArray:
    """Zero-padded ('same') 1-D convolution as PyTorch computes it (a cross-correlation):
    ``x`` (batch, time, in), ``wk`` (kernel x in, out: :attr:`Member.columns`) -> (batch,
    time, out)."""
    b_, t, c = x.shape
    k = wk.shape[0] // c
    xp = np.zeros((b_, t + k - 1, c))
    xp[:, k // 2 : k // 2 + t] = x
    cols = np.concatenate([xp[:, j : j + t] for j in range(k)], axis=2)  # (batch, time, k x in)
    return np.asarray(cols @ wk + b, dtype=np.float64)


def _member_features(m: Member, x: FloatArray) -> FloatArray:
    """Penultimate features of ``x`` (batch, 2, length) -> (batch, hidden)."""
    h = np.transpose(x, (0, 2, 1))
    for i, (wk, (_, b)) in enumerate(zip(m.columns, m.convs, strict=True)):
        h = np.maximum(_conv(h, wk, b), 0.0)
        if i < len(m.convs) - 1:
            t = h.shape[1] // 2 * 2
            h = h[:, :t].reshape(h.shape[0], t // 2, 2, h.shape[2]).max(axis=2)
    pooled = np.concatenate([h.mean(axis=1), h.max(axis=1)], axis=1)
    w, b = m.dense
    return np.asarray(np.maximum(pooled @ w.T + b, 0.0), dtype=np.float64)


def features(net: Network, x: FloatArray, *, told: bool = True, average: bool = True
             ) -> FloatArray:
    """The penultimate features of spans ``x`` (spans, 2, length), each read as it is and
    mirrored (and with PV's sign flipped unless the controller's sign was ``told``):
    (members, hidden) averaged over spans and readings, or (members, spans x readings,
    hidden) with ``average=False``."""
    signs = np.array(MIRROR if told else SIGNS)[:, :, None]
    batch = (x[:, None] * signs[None]).reshape(-1, 2, x.shape[2])
    f = np.stack([_member_features(m, batch) for m in net.members])
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
