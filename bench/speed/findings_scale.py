"""Benchmark (issue 38 items 2 and 3): the findings file does not hold up the polls.

A gateway of 2,000 loops polled every 0.1 s, with a findings file of 20,000 rows (1 MB,
under its 8 MiB bound), each loop getting its first verdict in the first analysis round
(every loop sticky: a stand-in analysis in a worker process), then two more rounds: the
longest the event loop stalled and the poll ticks missed, for the baseline commit
(``BENCH_BASELINE``, default :data:`BASELINE`: main when issue 38 was filed; its packages
extracted from git, :func:`bench.attacks._arena.baseline_tree`) and for this tree, side by side in
one run (each in a process of its own: ``bench/speed/_findings_arena.py``). On 5c94178 the
findings view was rebuilt whole, in the event loop, for each loop's first verdict: 6,000
findings stalled it 10 s, 20,000 past ``WatchdogSec=30``. Target: no stall beyond a poll
interval (0.1 s), no missed tick. ``BENCH_QUICK=1``: 6,000 findings.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from bench.attacks._arena import REPO, baseline_tree

BASELINE = "5c94178"  # main when issue 38 was filed
LOOPS = 2000
ARENA = Path(__file__).resolve().parent / "_findings_arena.py"
POLL_S = 0.1  # the arena's poll interval
LIMIT_S = 240.0
"""The longest a gateway runs (the baseline's first round takes longer than that on a busy
2-core box: its row then says "stopped", with how many loops it had judged)."""


def run_tree(tree: Path, loops: int, findings: int) -> dict[str, Any]:
    """The arena on ``tree``: its JSON line, or why there is none."""
    args = json.dumps({"loops": loops, "findings": findings, "rounds": 3,
                       "limit_s": LIMIT_S - 30})
    env = {**os.environ, "PYTHONPATH": str(tree)}
    try:
        out = subprocess.run([sys.executable, str(ARENA), args], capture_output=True,
                             text=True, env=env, cwd=tree, timeout=LIMIT_S, check=False)
        stdout, stderr = out.stdout, out.stderr
    except subprocess.TimeoutExpired as exc:  # stopped: its figures so far
        stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        stderr = f"stopped after {LIMIT_S:.0f} s"
    lines = [ln for ln in stdout.splitlines() if ln.startswith("{")]
    if not lines:
        return {"failed": (stderr.strip().splitlines() or ["(nothing)"])[-1][:200]}
    result: dict[str, Any] = json.loads(lines[-1])
    if result.get("partial"):  # stopped while its event loop was held: since its last line
        held = time.time() - float(result["wall"])
        result["stall_s"] = max(float(result["stall_s"]), held)
        result["missed"] = max(int(result["missed"]), int(held / POLL_S) - 1)
    return result


def main() -> None:
    findings = 6000 if os.environ.get("BENCH_QUICK") else 20000
    ref = os.environ.get("BENCH_BASELINE", BASELINE)
    print(f"== findings: {LOOPS:,} loops polled every 0.1 s, {findings:,} findings, each "
          "loop's first verdict and two rounds more ==")
    with baseline_tree(ref) as (commit, old):
        rows = [(f"{commit} (baseline)", run_tree(old, LOOPS, findings)),
                ("this tree", run_tree(REPO, LOOPS, findings))]
    print(f"{'gateway':<20} {'longest stall s':>15} {'missed ticks':>12} {'rounds':>6} "
          f"{'judged':>6} {'findings':>8} {'run s':>7}")
    for name, r in rows:
        if "failed" in r:
            print(f"{name:<20} failed: {r['failed']}")
            continue
        at_least = ">=" if r.get("partial") else ""
        print(f"{name:<20} {at_least + format(float(r['stall_s']), '.2f'):>15} "
              f"{at_least + format(int(r['missed']), ','):>12} {int(r['rounds']):>6} "
              f"{int(r['judged']):>6,} {int(r['findings']):>8,} {float(r['seconds']):>7.1f}"
              + (f"  (stopped after {LIMIT_S:.0f} s: the figures so far; the stall since its "
                 "last line counted, the ticks it held)" if r.get("partial") else ""))
    print("target: no stall beyond a poll interval (0.1 s), no missed tick")


if __name__ == "__main__":
    main()
