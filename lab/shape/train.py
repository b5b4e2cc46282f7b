"""Training the shape network on the shape corpus (simulation only), and scoring the sets
it is measured on. ``Prepared`` holds one input configuration's arrays: the training
windows (random spans, ``PER_WINDOW`` a window), and every evaluation set as the product
scores it (all spans, four sign readings: stiction/diagnosis/shape.py)."""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from typing import Any

import numpy as np
import torch

from stiction.diagnosis import shape

from . import corpus, data, net
from .data import Config, Record

PER_WINDOW = 3
EPOCHS = 24
BATCH = 64
LR = 3e-3


@dataclasses.dataclass
class Prepared:
    cfg: Config
    x: np.ndarray  # (windows, PER_WINDOW, 2, length) float32
    y: np.ndarray
    sets: dict[str, list[tuple[np.ndarray, bool]]]  # set -> each window's spans, sign told
    labels: dict[str, np.ndarray]  # -1: unlabelled
    groups: dict[str, list[str]]
    names: dict[str, list[str]]


@functools.cache
def _sims() -> tuple[data.Sim, data.Sim]:
    return data.sim(list(corpus.TRAIN)), data.sim(list(corpus.HELD_OUT))


@functools.cache
def _record_periods(source: str) -> tuple[float | None, ...]:
    return tuple(data.period(r.op, r.pv) for r in _records(source))


def _records(source: str) -> tuple[Record, ...]:
    return {"plant": data.plant, "tep-shared": data.tep_shared,
            "factory": data.factory}[source]()


def prepare(cfg: Config) -> Prepared:
    train, held = _sims()
    x = data.training_inputs(train, cfg, PER_WINDOW, seed=0)
    sets = {"sim": [data.window_inputs(e.op, e.pv, None if math.isnan(p) else float(p), cfg)
                    for e, p in zip(held.examples, held.periods, strict=True)]}
    labels = {"sim": held.y}
    groups = {"sim": [str(e.pair) for e in held.examples]}
    names = {"sim": [e.kind for e in held.examples]}
    for src in ("plant", "tep-shared", "factory"):
        recs = _records(src)
        sets[src] = [data.window_inputs(r.op, r.pv, p, cfg)
                     for r, p in zip(recs, _record_periods(src), strict=True)]
        labels[src] = np.array([-1 if r.sticky is None else int(r.sticky) for r in recs])
        groups[src] = [r.group for r in recs]
        names[src] = [r.name for r in recs]
    return Prepared(cfg, x, train.y, sets, labels, groups, names)


def fit(p: Prepared, arch: net.Arch, seed: int, epochs: int = EPOCHS,
        log: Any = None) -> Any:
    """One network trained on the prepared windows: balanced BCE, Adam with a cosine
    schedule; each epoch reads one random span of every window, mirrored at random."""
    torch.set_num_threads(1)
    model = net.make(arch, seed)
    rng = np.random.default_rng(seed)
    y = torch.from_numpy(p.y.astype(np.float32))
    pos_weight = torch.tensor(float((p.y == 0).sum()) / max(float((p.y == 1).sum()), 1.0))
    opt = torch.optim.Adam(model.parameters(), lr=LR, weight_decay=1e-4)
    steps = epochs * math.ceil(len(y) / BATCH)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=LR, total_steps=steps)
    loss_fn = torch.nn.BCEWithLogitsLoss(pos_weight=pos_weight)
    signs = np.array(shape.MIRROR, np.float32)
    t0 = time.perf_counter()
    for epoch in range(epochs):
        order = rng.permutation(len(y))
        crop = rng.integers(0, p.x.shape[1], len(y))
        sgn = signs[rng.integers(0, len(signs), len(y))]
        total = 0.0
        for a in range(0, len(y), BATCH):
            idx = order[a : a + BATCH]
            xb = torch.from_numpy(p.x[idx, crop[idx]] * sgn[idx][:, :, None])
            loss = loss_fn(net.logits(model, xb), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach()) * len(idx)
        if log is not None:
            log(f"    epoch {epoch + 1}: loss {total / len(y):.4f} "
                f"({time.perf_counter() - t0:.0f} s)")
    return model


def evaluate(model: Any, p: Prepared) -> dict[str, np.ndarray]:
    """Each evaluation set's features (windows, hidden), as the product computes them."""
    return {name: net.window_features(model, spans) for name, spans in p.sets.items()}
