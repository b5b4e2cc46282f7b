"""The export (``python -m lab shape --write``): the ensemble's weights, with the statistics
of its features on the held-out simulated windows (the source of the site alignment), the
Platt map and the thresholds chosen on simulation, as stiction/diagnosis/shape.npz; and the
fixture that holds numpy to PyTorch: ``FIXTURE_WINDOWS`` windows (held-out simulated ones cut
to 150-600 samples, stored as float16) with their cycles and PyTorch's logits and scores."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import torch

from stiction.diagnosis import shape, site

from . import confidence, data, metrics, net, train

REPO = Path(__file__).resolve().parents[2]
FIXTURE = REPO / "tests" / "stiction" / "diagnosis" / "shape_fixture.npz"
FIXTURE_WINDOWS = 100


def fixture_windows(p: train.Prepared, count: int = FIXTURE_WINDOWS
                    ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` held-out simulated windows (half sticky), cut to 150-600 samples and
    rounded to float16, deterministic."""
    _, held = train._sims()
    rng = np.random.default_rng(36)
    pos = [i for i, e in enumerate(held.examples) if e.y == 1]
    neg = [i for i, e in enumerate(held.examples) if e.y == 0]
    pick = list(rng.choice(pos, count // 2, replace=False)) + \
        list(rng.choice(neg, count - count // 2, replace=False))
    out = []
    for i in pick:
        e = held.examples[i]
        n = min(e.op.size, int(rng.integers(150, 601)))
        out.append((e.op[:n].astype(np.float16), e.pv[:n].astype(np.float16)))
    return out


def torch_scores(models: list[Any], cfg: data.Config,
                 windows: list[tuple[np.ndarray, np.ndarray]]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Each window's cycle and the ensemble's logit in PyTorch (float32)."""
    periods = np.array([q if (q := data.period(o.astype(np.float64), v.astype(np.float64)))
                        is not None else np.nan for o, v in windows])
    spans = [data.window_inputs(o.astype(np.float64), v.astype(np.float64),
                                None if np.isnan(q) else float(q), cfg)
             for (o, v), q in zip(windows, periods, strict=True)]
    z = np.mean([net.head(m, net.window_features(m, spans)) for m in models], axis=0)
    return periods, np.asarray(z, dtype=np.float64)


def write(p: train.Prepared, s: confidence.Scored, platt: tuple[float, float]) -> None:
    ys = p.labels["sim"]
    cal = site.platt(s.logits("sim"), *platt)
    meta: dict[str, object] = {
        "platt": list(platt), "threshold": metrics.threshold_for_precision(
            cal, ys, confidence.PRECISION), "band_low": confidence._low_band(cal, ys),
        "sim_prior": float(ys.mean()), "trained_windows": len(p.y),
        "trained_sticky": int(p.y.sum())}
    sources = tuple((site.SiteStats.of(f["sim"][ys == 1]), site.SiteStats.of(f["sim"][ys == 0]))
                    for f in s.feats)
    nw = dataclasses.replace(net.network(s.models, p.cfg, meta), sources=sources)
    arrays = shape.to_arrays(nw)
    save: Any = np.savez_compressed  # its stubs type **kwds against allow_pickle
    save(shape.WEIGHTS, **arrays)
    print(f"wrote {shape.WEIGHTS} ({shape.WEIGHTS.stat().st_size} bytes, {nw.n_weights} "
          f"weights; {meta})")
    windows = fixture_windows(p)
    periods, z = torch_scores(s.models, p.cfg, windows)
    lengths = np.array([o.size for o, _ in windows])
    np.savez_compressed(FIXTURE, op=np.concatenate([o for o, _ in windows]),
                        pv=np.concatenate([v for _, v in windows]), lengths=lengths,
                        periods=periods, logits=z, scores=metrics.sigmoid(z))
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes, {len(windows)} windows)")


def torch_model(member: shape.Member, arch: net.Arch) -> Any:
    """A PyTorch network holding a shipped member's weights (the lab's test recomputes the
    fixture with it)."""
    m = net.make(arch, 0)
    with torch.no_grad():
        for conv, (w, b) in zip(m["convs"], member.convs, strict=True):
            conv.weight.copy_(torch.from_numpy(w))
            conv.bias.copy_(torch.from_numpy(b))
        for name, (w, b) in (("dense", member.dense), ("last", member.last)):
            m[name].weight.copy_(torch.from_numpy(w))
            m[name].bias.copy_(torch.from_numpy(b))
    return m
