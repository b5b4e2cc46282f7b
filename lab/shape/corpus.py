"""The shape corpus on disk: ``python -m lab shape-corpus`` simulates what
``lab/.cache/shape/<VERSION>/`` lacks, one chunk (``PAIRS`` loops and their twins,
lab/shape/simulate.py) per seed, each written as soon as it is made (an interrupted build
resumes at the next missing seed). Seeds ``TRAIN`` train the network, ``HELD_OUT`` (never
trained on) give its simulated figures. Everything is seeded: the same code builds the
same corpus; ``VERSION`` names the generator and changes whenever its output would."""

from __future__ import annotations

import collections
import json
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from .. import _cache
from .simulate import PAIRS, Example, chunk

VERSION = "v2"
TRAIN = range(0, 250)
HELD_OUT = range(1000, 1030)


def folder() -> Path:
    return _cache.root() / "shape" / VERSION


def _path(seed: int) -> Path:
    return folder() / f"chunk-{seed:05d}.npz"


def _write(seed: int, examples: list[Example], tally: dict[str, int]) -> None:
    path = _path(seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    lengths = np.array([e.op.size for e in examples], dtype=np.int64)
    meta = {"tally": tally, "kinds": [e.kind for e in examples],
            "meta": [e.meta for e in examples]}
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, op=np.concatenate([e.op for e in examples]),
             pv=np.concatenate([e.pv for e in examples]), lengths=lengths,
             y=np.array([e.y for e in examples], dtype=np.int8),
             pair=np.array([e.pair for e in examples], dtype=np.int64),
             meta=np.array(json.dumps(meta)))
    tmp.replace(path)


def read(seed: int) -> tuple[list[Example], dict[str, int]]:
    with np.load(_path(seed)) as d:
        meta = json.loads(str(d["meta"]))
        ends = np.cumsum(d["lengths"])
        op, pv = np.split(d["op"], ends[:-1]), np.split(d["pv"], ends[:-1])
        out = [Example(o, p, int(y), int(pr), k, m) for o, p, y, pr, k, m in
               zip(op, pv, d["y"], d["pair"], meta["kinds"], meta["meta"], strict=True)]
    return out, meta["tally"]


def built(seeds: Iterable[int]) -> list[int]:
    return [s for s in seeds if _path(s).exists()]


def load(seeds: Iterable[int]) -> list[Example]:
    """The examples of the chunks of ``seeds`` that are built."""
    return [e for s in built(seeds) for e in read(s)[0]]


def build(seeds: Sequence[int], log: Callable[[str], None] = print) -> int:
    """Simulate the chunks of ``seeds`` not yet on disk; returns how many were made."""
    done = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for seed in seeds:
        if _path(seed).exists():
            continue
        examples, tally = chunk(seed, PAIRS)
        _write(seed, examples, tally)
        done += 1
        log(f"  chunk {seed}: {len(examples)} windows, sticky runs {tally} "
            f"({time.perf_counter() - t0:.0f} s, {time.process_time() - c0:.0f} s CPU)")
    return done


def summary(seeds: Iterable[int]) -> dict[str, int]:
    """Windows by kind, and the sticky runs by label, over the built chunks of ``seeds``."""
    kinds: collections.Counter[str] = collections.Counter()
    for s in built(seeds):
        examples, tally = read(s)
        kinds.update(e.kind for e in examples)
        kinds.update({f"sticky run {k}": v for k, v in tally.items()})
    return dict(sorted(kinds.items()))


def main(argv: Sequence[str] = ()) -> None:
    """``python -m lab shape-corpus [--chunks N]``: build the held-out chunks, then the
    training chunks (the first N if given), then print what is built."""
    n = int(argv[argv.index("--chunks") + 1]) if "--chunks" in argv else len(TRAIN)
    print(f"shape-corpus: building what {folder()} lacks ({PAIRS} loops and twins a chunk)",
          flush=True)

    def log(line: str) -> None:
        print(line, flush=True)

    build(list(HELD_OUT), log)
    build(list(TRAIN)[:n], log)
    for name, seeds in (("train", TRAIN), ("held out", HELD_OUT)):
        print(f"{name}: {len(built(seeds))} chunks: {summary(seeds)}")
