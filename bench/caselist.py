"""The case lists of the fourth round (issues 35 and 38): every finding as a case, run on the
baseline commit (before) and on this tree (after), side by side in one run.

    python -m bench caselist                        # every case
    BENCH_CASES=analysis python -m bench caselist   # the files named (bench/_caselist/*.py)
    BENCH_CASELIST_BASELINE=abc123 python -m bench caselist

Each case is a function in a file of ``bench/_caselist/`` decorated with ``_case.case``; the
file runs as a script (``python FILE NAME``) with the tree under test first on
``PYTHONPATH``, so ``stiction``, ``gateway`` and ``plcsim`` are that tree's (the baseline's
extracted by ``git archive``, :func:`bench.attacks._arena.baseline_tree`). A case prints one
JSON line:
``said`` (what the tree answered, in a few words) and ``ok`` (whether that answer is the one
the finding asks for). A case that raises is reported with the exception's last line and is
not ok. Cases run one at a time; each has ``TIMEOUT_S`` seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from bench.attacks._arena import REPO, baseline_tree

BASELINE = "5c94178"  # main when issues 35 and 38 were filed
HERE = Path(__file__).resolve().parent / "_caselist"
TIMEOUT_S = 300.0


def _path(tree: Path) -> str:
    """The case files' ``PYTHONPATH``: the tree under test first, then the cases' folder (for
    ``_case``). The files run with ``-P``: their own folder is not put first, where a case
    file's name (``gateway.py``) would stand for the package under test."""
    return f"{tree}{os.pathsep}{HERE}"


def _names(path: Path) -> list[tuple[str, str, str]]:
    """``(name, issue, finding)`` of every case in one file, in file order."""
    out = subprocess.run([sys.executable, "-P", str(path), "--list"], capture_output=True,
                         text=True, check=True, env={**os.environ, "PYTHONPATH": _path(REPO)})
    return [tuple(json.loads(line)) for line in out.stdout.splitlines() if line.strip()]


def run_case(path: Path, name: str, tree: Path) -> dict[str, object]:
    """One case on one tree: its JSON line, or what went wrong."""
    env = {**os.environ, "PYTHONPATH": _path(tree), "BENCH_CASE_TREE": str(tree)}
    t0 = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-P", str(path), name], check=False,
                             capture_output=True, text=True, env=env, cwd=tree, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return {"said": f"no answer in {TIMEOUT_S:.0f} s", "ok": False, "s": TIMEOUT_S}
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if not lines:
        err = (out.stderr.strip().splitlines() or ["(nothing)"])[-1]
        return {"said": f"raised: {err[:120]}", "ok": False, "s": time.perf_counter() - t0}
    result: dict[str, object] = json.loads(lines[-1])
    result["s"] = time.perf_counter() - t0
    return result


def main() -> None:
    files = sorted(p for p in HERE.glob("*.py") if not p.name.startswith("_"))
    chosen = os.environ.get("BENCH_CASES", "").replace(",", " ").split()
    if chosen:
        files = [p for p in files if p.stem in chosen]
    ref = os.environ.get("BENCH_CASELIST_BASELINE", BASELINE)
    with baseline_tree(ref) as (commit, old):
        print(f"== case list: before = {commit} (baseline), after = this tree ==")
        ok_before = ok_after = total = 0
        for path in files:
            print(f"\n-- {path.stem} --")
            for name, issue, finding in _names(path):
                before = run_case(path, name, old)
                after = run_case(path, name, REPO)
                total += 1
                ok_before += bool(before["ok"])
                ok_after += bool(after["ok"])
                print(f"[{issue}] {finding}")
                for label, r in (("before", before), ("after ", after)):
                    mark = "ok " if r["ok"] else "BAD"
                    said = textwrap.shorten(str(r["said"]), 150)
                    print(f"    {label} {mark} {said}  ({float(r['s']):.1f} s)")
        print(f"\n== {ok_after} of {total} cases as the finding asks on this tree; "
              f"{ok_before} of {total} on {commit} ==")


if __name__ == "__main__":
    main()
