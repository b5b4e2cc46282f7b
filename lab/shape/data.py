"""The shape network's data: the corpus's windows as inputs (their cycles looked up once and
cached beside the chunks), and the real records it is measured on, never trained on: the
plant records (../shared/data/plant-stictiongpt, 35 sticky of 80), the shared Tennessee
Eastman records (../shared/data/tep-sticky-valves, 6 of 58) and, unlabelled, windows of
the two factory loops (../shared/data/unlabelled-factory), the target of site alignment."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import numpy as np

from stiction.diagnosis import shape
from stiction.signal.cycle import find_cycle

from ..sources import records
from . import corpus
from .loads import FACTORY
from .simulate import Example

FACTORY_WINDOW = 751  # samples of a factory window (at 1 min): as long as a plant record
MIN_PERIOD = shape.MIN_PERIOD
"""A sticky run whose stick-slip cycle (twice the window's samples over its slips) spans
fewer historian samples than this is dropped: at that sampling its cycle is a zigzag of a few
points, no shape to see (its twin stays a negative)."""


@dataclasses.dataclass(frozen=True)
class Config:
    """How a window becomes the network's input (stiction/diagnosis/shape.py)."""

    length: int = 256
    cycles: float = 6.0
    crops: int = 4
    span_without_cycle: int = 1024

    def kwargs(self) -> dict[str, float]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Record:
    """A real record to score: ``group`` its tag (plant) or run (TEP)."""

    source: str
    name: str
    group: str
    sticky: bool | None
    cause: str
    op: np.ndarray
    pv: np.ndarray


def period(op: np.ndarray, pv: np.ndarray) -> float | None:
    """The cycle the network's input is cut by: OP's first (as for a self-regulating loop:
    the loop type is not known to the network)."""
    return find_cycle(np.asarray(op, np.float64), np.asarray(pv, np.float64),
                      integrating=False).period


def periods(seed: int, examples: Sequence[Example]) -> np.ndarray:
    """The cycles of a chunk's windows (nan: none), cached."""
    path = corpus.folder() / f"periods-{seed:05d}.npy"
    if path.exists():
        return np.asarray(np.load(path), dtype=np.float64)
    out = np.array([p if (p := period(e.op, e.pv)) is not None else np.nan
                    for e in examples])
    np.save(path, out)
    return out


@dataclasses.dataclass
class Sim:
    """Simulated windows: their examples and cycles."""

    examples: list[Example]
    periods: np.ndarray

    @property
    def y(self) -> np.ndarray:
        return np.array([e.y for e in self.examples])


def visible(e: Example) -> bool:
    """A negative, or a positive whose stick-slip cycle spans ``MIN_PERIOD`` samples."""
    return e.y == 0 or 2.0 * e.op.size / max(int(e.meta["slips"]), 1) >= MIN_PERIOD


def sim(seeds: Sequence[int]) -> Sim:
    """The built chunks of ``seeds``, without positives too fast to see (:func:`visible`)."""
    ex: list[Example] = []
    per: list[np.ndarray] = []
    for s in corpus.built(seeds):
        e, _ = corpus.read(s)
        keep = [visible(x) for x in e]
        ex += [x for x, k in zip(e, keep, strict=True) if k]
        per.append(periods(s, e)[np.array(keep, dtype=bool)])
    return Sim(ex, np.concatenate(per) if per else np.empty(0))


def _nan(p: float) -> float | None:
    return None if not np.isfinite(p) else float(p)


def window_inputs(op: np.ndarray, pv: np.ndarray, p: float | None, cfg: Config
                  ) -> tuple[np.ndarray, bool]:
    """Every span of a window as scored (stiction.diagnosis.shape.inputs, PV turned direct
    acting), and whether the controller's sign was told."""
    sign = shape.orientation(op, pv, p)
    return shape.inputs(op, pv, p, length=cfg.length, cycles=cfg.cycles, crops=cfg.crops,
                        span_without_cycle=cfg.span_without_cycle, sign=sign), sign != 0


def training_inputs(data: Sim, cfg: Config, per_window: int, seed: int) -> np.ndarray:
    """(windows, per_window, 2, length): random spans of each window (a random phase of
    its cycle), PV turned direct acting as the whole window tells, float32."""
    rng = np.random.default_rng(seed)
    out = np.empty((len(data.examples), per_window, 2, cfg.length), dtype=np.float32)
    for i, e in enumerate(data.examples):
        n = e.op.size
        p = _nan(data.periods[i])
        sign = shape.orientation(e.op, e.pv, p)
        if sign == 0:  # not told: either reading, as the product reads both
            sign = float(rng.choice((-1.0, 1.0)))
        (a, b), = shape.spans(n, p, cycles=cfg.cycles, crops=1,
                               span_without_cycle=cfg.span_without_cycle)
        for j in range(per_window):
            s = int(rng.integers(0, n - (b - a) + 1))
            out[i, j] = shape.inputs(e.op[s : s + b - a], e.pv[s : s + b - a], None,
                                     length=cfg.length, cycles=cfg.cycles, crops=1,
                                     span_without_cycle=b - a, sign=sign)[0]
    return out


@functools.cache
def plant() -> tuple[Record, ...]:
    return tuple(Record("plant", c.name, c.group, c.sticky, c.cause, c.op, c.pv)
                 for c in records.plant_cases())


@functools.cache
def tep_shared() -> tuple[Record, ...]:
    return tuple(Record("tep-shared", c.name, c.group, c.sticky, c.cause, c.op, c.pv)
                 for c in records.tep_cases())


@functools.cache
def factory() -> tuple[Record, ...]:
    """The factory loops cut into windows as long as a plant record, half overlapping;
    missing samples filled by linear interpolation."""
    out = []
    for name in ("FIC-211", "LIC-106"):
        d = np.genfromtxt(FACTORY / f"{name}.csv", delimiter=",", names=True, dtype=None,
                          encoding="utf-8")
        sig = []
        for col in ("op", "pv"):
            x = np.asarray(d[col], dtype=np.float64)
            good = np.isfinite(x)
            sig.append(np.interp(np.arange(x.size), np.flatnonzero(good), x[good]))
        for a in range(0, sig[0].size - FACTORY_WINDOW + 1, FACTORY_WINDOW // 2):
            out.append(Record("factory", f"{name}@{a}", name, None, "unlabelled",
                              sig[0][a : a + FACTORY_WINDOW], sig[1][a : a + FACTORY_WINDOW]))
    return tuple(out)
