"""Benchmark (issue 38 items 5 and 6): the offline CLI reading historian exports, the
baseline commit's and this tree's side by side in one run.

* ``stiction plant`` on a wide export of 25, 50 and 250 loops x 7,200 rows whose every number
  has three decimals (``57.123``: every cell reads two ways; the t column whole seconds), as
  the product's plant simulator (:func:`stiction.scenarios.plant.simulate_plants`) writes
  them rounded: wall and CPU seconds, and whether the command read the file (exit 0). The
  baseline tallied every other column again for each column (O(columns^2 x rows)): its run
  stops at ``BENCH_CAP_S`` seconds (default 300) and is printed as more than that. Target: 250
  loops in under 30 s.
* ``stiction analyze`` of one 70 MB export (``stiction simulate --scenario table4-case2
  --historian FIC101``, ~1.9 million rows at 1 s, ``;``-separated with decimal commas):
  wall and CPU seconds, peak RSS, and the peak as a multiple of the file; the verdicts, which
  must agree. The file is written once and kept in the temporary folder
  (``BENCH_CLI_DIR``).

Each command runs as its own process (``python -m stiction.cli``), the tree first on
``PYTHONPATH``, the peak RSS its own (``os.wait4``). ``BENCH_QUICK=1``: 25 and 50 loops and a
7 MB export.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.attacks._arena import baseline_tree
from stiction.scenarios.plant import simulate_plants
from stiction.scenarios.plants import PLANT_KINDS, plant_scenarios

BASELINE = "5c94178"  # main when issue 38 was filed
LOOPS = (25, 50, 250)
ROWS = 7200
TARGET_S = 30.0
EXPORT_S = 1_900_000  # ~70 MB of `--historian` export at 1 s
CAP_S = float(os.environ.get("BENCH_CAP_S", "300"))
HERE = Path(os.environ.get("BENCH_CLI_DIR", Path(tempfile.gettempdir()) / "bench-cli-reading"))


def wide_export(path: Path, loops: int, rows: int = ROWS) -> Path:
    """``loops`` simulated plant loops (every plant kind in turn) as a wide CSV export, t
    in whole seconds, every OP and PV with three decimals."""
    if path.exists():
        return path
    scenarios = []
    k = 0
    while sum(len(sc.loops) for sc in scenarios) < loops:
        scenarios.extend(plant_scenarios(PLANT_KINDS[k % len(PLANT_KINDS)], 1, seed=k))
        k += 1
    names: list[str] = []
    columns: list[np.ndarray] = []
    for p, rec in enumerate(simulate_plants(scenarios, duration=float(rows), warmup=600.0)):
        for tag in rec.op:
            names += [f"P{p}.{tag}.OP", f"P{p}.{tag}.PV"]
            columns += [rec.op[tag], rec.pv[tag]]
    data = np.column_stack(columns[:2 * loops])
    tmp = path.with_suffix(".part")
    with tmp.open("w") as fh:
        fh.write(",".join(["t", *names[:2 * loops]]) + "\n")
        for i, row in enumerate(data):
            fh.write(f"{i}," + ",".join(f"{x:.3f}" for x in row) + "\n")
    tmp.rename(path)
    return path


def historian_export(path: Path, seconds: int) -> Path:
    """A ``stiction simulate --historian FIC101`` export of ``seconds`` at 1 s."""
    if not path.exists():
        tmp = path.with_suffix(".part")
        subprocess.run([sys.executable, "-m", "stiction.cli", "simulate", "--scenario",
                        "table4-case2", "--noise", "0.05", "--duration", str(seconds),
                        "--historian", "FIC101", "-o", str(tmp)], check=True,
                       stdout=subprocess.DEVNULL)
        tmp.rename(path)
    return path


def run(tree: Path, argv: list[str], cap: float | None = None) -> dict[str, object]:
    """One ``stiction`` command of ``tree``: wall and CPU seconds, peak RSS (bytes), exit
    status and its first output line; stopped at ``cap`` seconds (status None)."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1",
           "OMP_NUM_THREADS": "1"}
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "stiction.cli", *argv], env=env,
                                cwd=tree, stdout=out, stderr=subprocess.STDOUT)
        status: int | None = None
        while True:
            pid, code, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                status = os.waitstatus_to_exitcode(code)
                break
            if cap is not None and time.perf_counter() - t0 > cap:
                proc.kill()
                _, _, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = -9 if status is None else status  # reaped here, not by Popen
        wall = time.perf_counter() - t0
        out.seek(0)
        first = out.read(4000).decode(errors="replace").splitlines()
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "rss": usage.ru_maxrss * 1024, "status": status, "said": first[0] if first else ""}


def _seconds(r: dict[str, object], cap: float | None = None) -> str:
    if r["status"] is None:
        return f"> {cap:.0f} (stopped)"
    return f"{float(r['wall']):.1f} ({float(r['cpu']):.1f} cpu)"  # type: ignore[arg-type]


def main() -> None:
    quick = bool(os.environ.get("BENCH_QUICK")) or "--quick" in sys.argv[1:]
    HERE.mkdir(parents=True, exist_ok=True)
    repo = Path(__file__).resolve().parents[2]
    worst = 0.0
    with baseline_tree(os.environ.get("BENCH_BASELINE", BASELINE)) as (commit, old):
        print(f"\nstiction plant: wide exports of three-decimal numbers ({ROWS} rows), "
              f"one process each; before: {commit} (stopped at {CAP_S:.0f} s), after: this "
              f"tree; {os.cpu_count()} cores")
        print(f"{'loops':>6} {'MB':>6} {'before s':>22} {'after s':>18} {'exit':>9}")
        for n in LOOPS[:2] if quick else LOOPS:
            path = wide_export(HERE / f"wide{n}.csv", n)
            before = run(old, ["plant", str(path)], CAP_S)
            after = run(repo, ["plant", str(path)])
            worst = max(worst, float(after["wall"]))  # type: ignore[arg-type]
            print(f"{n:>6} {path.stat().st_size / 1e6:>6.1f} {_seconds(before, CAP_S):>22} "
                  f"{_seconds(after):>18} {before['status']!s:>4} {after['status']!s:>4}",
                  flush=True)
        if not quick:
            print(f"250 loops: {worst:.1f} s (target < {TARGET_S:.0f} s): "
                  f"{'ok' if worst < TARGET_S else 'OVER'}")
        seconds = EXPORT_S // 10 if quick else EXPORT_S
        path = historian_export(HERE / f"fic101-{seconds}.csv", seconds)
        size = path.stat().st_size
        argv = ["analyze", str(path), "--op", "FIC101.OP", "--pv", "FIC101.PV"]
        print(f"\nstiction analyze of one export: {size / 1e6:.0f} MB, {seconds:,} rows; peak "
              "RSS, and above the interpreter with the packages imported (reading and "
              "analysis), also per row")
        print(f"{'':8} {'seconds':>18} {'peak RSS MB':>12} {'above MB':>9} {'x file':>7} "
              f"{'B/row':>6}  verdict")
        for label, tree in (("before", old), ("after", repo)):
            base = run(tree, ["reproduce", "--help"])  # every package imported, no data
            r = run(tree, argv)
            rss = float(r["rss"])  # type: ignore[arg-type]
            above = rss - float(base["rss"])  # type: ignore[arg-type]
            print(f"{label:8} {_seconds(r):>18} {rss / 1e6:>12.0f} {above / 1e6:>9.0f} "
                  f"{above / size:>7.1f} {above / seconds:>6.0f}  {r['said']}", flush=True)


if __name__ == "__main__":
    main()
