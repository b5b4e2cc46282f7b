"""Today's analysis beside this tree's in one process, for before/after figures in one run.

:func:`baseline_stiction` extracts the ``stiction`` package of a baseline commit
(``BENCH_BASELINE``, default :data:`BASELINE`: main when issue 28 was filed) with
:func:`bench.attacks._arena.baseline_tree` (``git archive``; nothing of the repository changes) and
imports it under the name ``stiction_baseline``. Every module of the library imports its
siblings relatively, so the two versions load side by side and a benchmark can time them
interleaved, call by call: on a shared box the load changes from one second to the next,
and two separate runs would compare two loads, not two versions.

:class:`StageClock` times the stages of one ``analyze`` of either version from inside
(the gates, the cycle, every detector of the registry, the decision, the sizing), by
wrapping those functions for as long as it is active.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import importlib.util
import os
import sys
import time
from collections.abc import Callable, Iterator
from types import ModuleType
from typing import Any

from bench.attacks._arena import baseline_tree

BASELINE = "3dfa8c7"  # main when issue 28 was filed
ALIAS = "stiction_baseline"


@contextlib.contextmanager
def baseline_stiction(ref: str | None = None) -> Iterator[tuple[str, ModuleType]]:
    """``(commit, package)``: the baseline's ``stiction``, imported as ``stiction_baseline``
    for the duration of the block."""
    ref = ref or os.environ.get("BENCH_BASELINE", BASELINE)
    with baseline_tree(ref) as (commit, tree):
        root = tree / "stiction"
        spec = importlib.util.spec_from_file_location(
            ALIAS, root / "__init__.py", submodule_search_locations=[str(root)])
        if spec is None or spec.loader is None:
            raise ImportError(f"no package at {root}")
        package = importlib.util.module_from_spec(spec)
        sys.modules[ALIAS] = package
        try:
            spec.loader.exec_module(package)
            yield commit, package
        finally:
            for name in [n for n in sys.modules if n == ALIAS or n.startswith(ALIAS + ".")]:
                del sys.modules[name]


def analyze_of(package: ModuleType) -> Callable[..., Any]:
    """The package's ``analyze`` (``stiction`` or the baseline)."""
    module = importlib.import_module(package.__name__ + ".diagnosis.analyze")
    fn: Callable[..., Any] = module.analyze
    return fn


STAGES = ("data gates", "cycle", "noise SDs")
"""The stages before the detectors; :meth:`StageClock.rows` adds the detectors, then
"decision" (features, probability, contributions), "sizing" and "the rest"."""


class StageClock:
    """CPU time of each stage of ``analyze`` (``time.process_time``), accumulated while
    active (``with clock:``); :meth:`rows` per call of ``analyze`` since :meth:`reset`."""

    def __init__(self, package: ModuleType) -> None:
        name = package.__name__
        self._analyze = importlib.import_module(name + ".diagnosis.analyze")
        self._evidence = importlib.import_module(name + ".diagnosis.evidence")
        self._registry = importlib.import_module(name + ".detectors.registry")
        self._model = importlib.import_module(name + ".diagnosis.model").Model
        self.spent: dict[str, float] = collections.defaultdict(float)
        self.calls = 0
        self._undo: list[tuple[Any, str, Any]] = []

    def _timed(self, stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[stage] += time.process_time() - t0
        return timed

    def _patch(self, owner: Any, attr: str, stage: str) -> None:
        old = getattr(owner, attr)
        self._undo.append((owner, attr, old))
        setattr(owner, attr, self._timed(stage, old))

    def __enter__(self) -> StageClock:
        a = self._analyze
        self._patch(a, "check_quality", "data gates")
        self._patch(a, "find_cycle", "cycle")
        self._patch(self._evidence, "noise_sd", "noise SDs")
        self._patch(a, "features", "decision")
        self._patch(self._model, "probability", "decision")
        self._patch(self._model, "contributions", "decision")
        self._patch(a, "size_valve", "sizing")
        if hasattr(a, "quantify"):  # forced sizing (the paper's rows) is sizing too
            self._patch(a, "quantify", "sizing")
        reg: Any = self._registry
        old = reg.DETECTORS
        self._undo.append((reg, "DETECTORS", old))
        reg.DETECTORS = tuple(type(d)(d.name, self._timed(d.name, d.run), d.reference)
                              for d in old)
        self._patch(a, "analyze", "total")
        return self

    def __exit__(self, *exc: object) -> None:
        for owner, attr, old in reversed(self._undo):
            setattr(owner, attr, old)
        self._undo.clear()

    def run(self, *args: Any, **kwargs: Any) -> Any:
        """One ``analyze`` (module attribute, so the timed one while active)."""
        self.calls += 1
        return self._analyze.analyze(*args, **kwargs)

    def reset(self) -> None:
        self.spent.clear()
        self.calls = 0

    def rows(self) -> dict[str, float]:
        """Seconds per ``analyze`` of each stage, in the order of the path of a window;
        "the rest" is validation, the evidence's bookkeeping, the reason and the result."""
        per = {k: v / max(self.calls, 1) for k, v in self.spent.items()}
        names = [d.name for d in self._registry.DETECTORS]
        order = [*STAGES, *names, "decision", "sizing"]
        out = {k: per.get(k, 0.0) for k in order}
        out["the rest"] = max(per.get("total", 0.0) - sum(out.values()), 0.0)
        out["total"] = per.get("total", 0.0)
        return out
