"""The shape network in PyTorch (training only; stiction/diagnosis/shape.py runs the
exported weights in numpy): convolutions with ReLU and max-pools, the mean and maximum of
each channel over time, a dense layer with ReLU (the features) and the logit. Built from
torch's own layers in a ModuleDict with a plain forward function, so nothing subclasses
torch's classes (mypy strict holds whether torch is installed or not)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import torch
from torch import nn

from stiction.diagnosis import shape

from .data import Config


@dataclasses.dataclass(frozen=True)
class Arch:
    """Channels and kernel of each convolution, and the features' width."""

    channels: tuple[int, ...] = (16, 16, 16, 16)
    kernels: tuple[int, ...] = (7, 5, 5, 3)
    hidden: int = 16


def make(arch: Arch, seed: int) -> Any:
    torch.manual_seed(seed)
    convs = []
    c_in = 2
    for c, k in zip(arch.channels, arch.kernels, strict=True):
        convs.append(nn.Conv1d(c_in, c, k, padding=k // 2))
        c_in = c
    return nn.ModuleDict({"convs": nn.ModuleList(convs),
                          "dense": nn.Linear(2 * c_in, arch.hidden),
                          "last": nn.Linear(arch.hidden, 1)})


def features(model: Any, x: torch.Tensor) -> torch.Tensor:
    """(batch, 2, length) -> (batch, hidden)."""
    h = x
    convs = model["convs"]
    for i, conv in enumerate(convs):
        h = torch.relu(conv(h))
        if i < len(convs) - 1:
            h = nn.functional.max_pool1d(h, 2)
    pooled = torch.cat([h.mean(dim=2), h.amax(dim=2)], dim=1)
    out: torch.Tensor = torch.relu(model["dense"](pooled))
    return out


def logits(model: Any, x: torch.Tensor) -> torch.Tensor:
    out: torch.Tensor = model["last"](features(model, x)).squeeze(1)
    return out


def n_weights(model: Any) -> int:
    return int(sum(p.numel() for p in model.parameters()))


def member(model: Any) -> shape.Member:
    """The numpy form of a trained network."""
    def pair(layer: Any) -> tuple[np.ndarray, np.ndarray]:
        return (layer.weight.detach().numpy().astype(np.float64),
                layer.bias.detach().numpy().astype(np.float64))

    return shape.Member(tuple(pair(c) for c in model["convs"]), pair(model["dense"]),
                        pair(model["last"]))


def network(models: list[Any], cfg: Config, meta: dict[str, object]) -> shape.Network:
    return shape.Network(tuple(member(m) for m in models), cfg.length, cfg.cycles,
                         cfg.crops, cfg.span_without_cycle, meta)


def window_features(model: Any, windows: list[tuple[np.ndarray, bool]]) -> np.ndarray:
    """Each window's features as stiction/diagnosis/shape.py averages them: its spans
    (spans, 2, length) read as they are and mirrored, with PV's sign flipped too when the
    controller's sign was not told."""
    parts, sizes = [], []
    for x, told in windows:
        signs = np.array(shape.MIRROR if told else shape.SIGNS, dtype=np.float32)
        parts.append((x.astype(np.float32)[:, None] * signs[None, :, :, None])
                     .reshape(-1, 2, x.shape[2]))
        sizes.append(parts[-1].shape[0])
    batch = torch.from_numpy(np.concatenate(parts))
    with torch.no_grad():
        f = torch.cat([features(model, b) for b in torch.split(batch, 4096)])
    return np.stack([g.mean(dim=0).numpy() for g in torch.split(f, sizes)]).astype(np.float64)


def head(model: Any, feats: np.ndarray) -> np.ndarray:
    w = model["last"].weight.detach().numpy().astype(np.float64)[0]
    b = float(model["last"].bias.detach().numpy()[0])
    return np.asarray(feats @ w + b, dtype=np.float64)
