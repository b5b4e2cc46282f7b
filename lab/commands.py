"""The lab's commands (``python -m lab NAME``): ``corpus`` builds the development corpus and
prints it (``make corpus``), ``train [--write]`` trains and validates the decision
(``--write`` writes stiction/diagnosis/model.json), ``decide`` measures the call analyze
ships (the shape network with the decision) beside today's decision and the other
candidates, held out (issue 36), ``calibrate [--write]`` fits the
weighted vote (``--write`` writes stiction/diagnosis/weights.py), ``shape-corpus`` builds
the shape network's corpus and ``shape [--search | --write]`` trains the network and prints
its research table (lab/shape/). The benchmarks' old names
(``python -m bench corpus``, ``python -m bench.train``, ``python -m bench calibrate``) run
them too (bench/corpus.py, bench/train.py, bench/calibrate.py)."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

USAGE = ("usage: python -m lab {corpus | train [--write] | decide | calibrate [--write] | "
         "shape-corpus [--chunks N] | shape [--search | --write]}")


def corpus(argv: Sequence[str] = ()) -> None:
    """Build what the corpus lacks, then print it per source and cause class."""
    from .labels import corpus as built  # each command loads only what it needs

    built.main()


def _rows(command: str, more: str = "") -> list[Any] | None:
    """The analysed rows of the corpus (lab/features/rows.py), said; None when the corpus is
    empty."""
    from .features.rows import rows, training_windows

    t0 = time.perf_counter()
    windows = training_windows()
    if not windows:
        print(f"{command}: the corpus is empty: run python -m lab corpus first")
        return None
    rs = rows(windows)
    print(f"== {command}: {len(rs)} windows ({time.perf_counter() - t0:.0f} s to load and "
          f"analyse){more} ==")
    return rs


def train(argv: Sequence[str] = ()) -> None:
    """Train on the corpus and the named scenarios, print the held-out validation."""
    from stiction.diagnosis.features import NAMES

    from .export import model
    from .training import fit, report

    rs = _rows("train", f", {len(NAMES)} features")
    if rs is None:
        return
    fitted = fit.train(rs)
    data = model.model_data(fitted)
    report.report(rs, fitted.held_out, fitted.stiction_at)
    if "--write" in argv:
        model.write(data)
        print(f"wrote {model.MODEL} ({data['meta']})")


def decide(argv: Sequence[str] = ()) -> None:
    """The shipped call beside today's decision, the network and the other candidates, held
    out, the fold that never saw a real record first (lab/training/decide.py)."""
    from .training import decide as measured
    from .training.decide_report import report

    rs = _rows("decide")
    if rs is not None:
        report(rs, measured.score(rs))


def calibrate(argv: Sequence[str] = ()) -> None:
    """Fit the weighted vote (lab/training/calibrate.py), print its held-out folds."""
    from stiction.diagnosis.combine import STICTION_CONFIDENCE

    from .export.weights import WEIGHTS_FILE, write_weights
    from .training.calibrate import GROUP_NAMES, cross_validate, fit, load

    t0 = time.perf_counter()
    t = load()
    print(f"== calibration: {len(t.cases)} windows, test groups {', '.join(GROUP_NAMES)} "
          f"({time.perf_counter() - t0:.0f} s to gather) ==")
    cross_validate(t, STICTION_CONFIDENCE)
    beta = fit(t)
    print(f"  fit on all data: bias {beta[0]:+.2f}; per test (+vote weight / -vote weight):")
    k = len(GROUP_NAMES)
    for i, name in enumerate(GROUP_NAMES):
        print(f"    {name:<14} {beta[1 + i]:5.2f} / {beta[1 + k + i]:5.2f}")
    if "--write" in argv:
        write_weights(beta, GROUP_NAMES)
        print(f"  wrote {WEIGHTS_FILE}")


def shape_corpus(argv: Sequence[str] = ()) -> None:
    """Build the shape network's corpus (lab/shape/corpus.py), then print what is built."""
    from .shape import corpus as shape

    shape.main(argv)


def shape(argv: Sequence[str] = ()) -> None:
    """Train the shape network's seeds (or ``--search`` the configurations), print the
    research table; ``--write`` exports stiction/diagnosis/shape.npz (lab/shape/research.py)."""
    from .shape import research

    research.main(argv)


COMMANDS: dict[str, Callable[[Sequence[str]], None]] = {
    "corpus": corpus, "train": train, "decide": decide, "calibrate": calibrate,
    "shape-corpus": shape_corpus, "shape": shape}


def main(argv: Sequence[str]) -> int:
    if not argv or argv[0] not in COMMANDS:
        print(USAGE, file=sys.stderr)
        return 2
    COMMANDS[argv[0]](argv[1:])
    return 0
