"""Where the lab keeps what it computed once (the corpus, the analysed rows, the realistic
sets), and the reading of those pickles.

Everything lives under ``lab/.cache`` (ignored by git): ``corpus/`` (``python -m lab
corpus`` builds it: the Tennessee Eastman runs, the realistic sets, the named scenarios)
and, beside it, the feature rows of ``python -m lab train`` and the realistic records of
``python -m bench real_data``. A checkout that built its corpus before the lab had a
package of its own keeps it in ``bench/.cache``; it is used where it stands until
``lab/.cache/corpus`` exists (``mv bench/.cache lab/.cache`` moves it, nothing is rebuilt).

Pickles written before the move name the classes where they then lived (``bench._tep``,
``bench._corpus_plan``, ...): :func:`load` finds them at their new place (:data:`MOVED`).
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "lab" / ".cache"
BEFORE = ROOT / "bench" / ".cache"  # where the corpus was built before lab/ existed

MOVED = {
    ("bench._tep", "Settled"): "lab.sources.tep",
    ("bench._corpus_plan", "TepRun"): "lab.sources.tep_plan",
    ("bench._corpus_label", "LoopSummary"): "lab.windows.tep",
    ("bench._corpus_types", "Window"): "lab._types",
    ("bench._corpus_types", "PlantRun"): "lab._types",
    ("bench.real_data", "Case"): "lab.sources.records",
}
"""(module, class) a pickle names -> the module that holds the class today."""


def root() -> Path:
    """The lab's cache folder: ``lab/.cache``, or ``bench/.cache`` when the corpus was
    built there and ``lab/.cache/corpus`` does not exist (the module doc)."""
    if not (HERE / "corpus").exists() and (BEFORE / "corpus").exists():
        return BEFORE
    return HERE


def corpus() -> Path:
    """The built corpus's folder."""
    return root() / "corpus"


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        return super().find_class(MOVED.get((module, name), module), name)


def load(path: Path) -> Any:
    """The object pickled at ``path``, its classes found where they live today."""
    with path.open("rb") as fh:
        return _Unpickler(fh).load()


def dump(obj: Any, path: Path) -> None:
    """Pickle ``obj`` to ``path`` through a temporary file: an interrupted write leaves no
    half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with tmp.open("wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
    tmp.replace(path)
