"""The rows the decision reads: every window the decision is trained on (the corpus and the
named scenarios) analysed as the gateway would (``stiction.diagnosis.analyze_details``) and
turned into the decision's features (``stiction.diagnosis.features``); cached in the lab's
cache, keyed by the code of stiction/ and the windows' keys, so a change to either analyses
again and nothing else does."""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import stiction
from stiction import Verdict
from stiction.diagnosis import network
from stiction.diagnosis.analyze import analyze_details
from stiction.diagnosis.enough import movement_scales, too_short
from stiction.diagnosis.features import features

from .. import _cache
from .._types import Window
from ..labels.corpus import load_windows
from ..sources import scenarios


@dataclasses.dataclass(frozen=True)
class Row:
    """One window as the fit sees it."""

    source: str
    run: str
    cause: str
    cause_class: str
    view: str
    x: np.ndarray | None  # None: the gates decided (``verdict`` says how)
    verdict: str  # today's verdict, the "before"
    confidence: float | None
    shape: float = float("nan")  # the shape network's logit (NaN: not read)
    withdrawn: bool = False  # too short for a call of stiction (stiction.diagnosis.enough)


def code_key() -> str:
    """A hash of stiction/'s code (its CLI aside): what the rows depend on."""
    root = Path(stiction.__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        if "cli" not in p.parts:
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def training_windows() -> list[Window]:
    """The windows the decision is trained on: the built corpus and the named scenarios."""
    return load_windows() + scenarios.windows(_cache.corpus())


def _rows_path(windows: Sequence[Window]) -> Path:
    """Where :func:`rows` caches the analysed windows: by stiction/'s code and the keys."""
    keys = hashlib.sha256("".join(w.key for w in windows).encode()).hexdigest()[:16]
    return _cache.root() / f"train-{code_key()}-{keys}.pickle"


def rows(windows: Sequence[Window]) -> list[Row]:
    """Every window analysed (cached by the code of stiction/ and the windows' keys)."""
    path = _rows_path(windows)
    if path.exists():
        return [Row(*t) for t in _cache.load(path)]
    out = []
    for w in windows:
        d = analyze_details(w.op, w.pv, ts=w.ts, process=w.process)
        x, logit, withdrawn = None, float("nan"), False
        if d.findings is not None and d.cycle is not None and d.op is not None and \
                d.pv is not None:
            x = features(d.findings.evidence, d.findings.results, d.cycle, op=d.op, pv=d.pv,
                         integrating=w.process == "integrating")
            net = d.findings.results.get(network.NAME)
            if isinstance(net, network.Reading) and net.logit is not None:
                logit = net.logit
            short = too_short(d.op.size, scales=None if d.cycle.cycling else
                              movement_scales(d.op, d.pv))
            withdrawn = short is not None and short.withdraws(Verdict.STICTION)
        out.append(Row(w.source, w.run, w.cause, w.cause_class, w.view, x,
                       str(d.assessment.verdict), d.assessment.confidence, logit, withdrawn))
    _cache.dump([dataclasses.astuple(r) for r in out], path)
    return out


def cached_rows() -> list[Row] | None:
    """The rows of the built corpus if :func:`rows` has cached them for today's code, else
    None (nothing is analysed)."""
    windows = training_windows()
    if not windows:
        return None
    return rows(windows) if _rows_path(windows).exists() else None
