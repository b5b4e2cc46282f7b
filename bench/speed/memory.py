"""Benchmark (issue 8, item 3): bytes per stored sample.

Per size, a fresh process builds the gateway (config of N simulated PLCs, 500 loops each,
2-hour windows at Ts 1 s; nothing started, so nothing else is allocated) and reports

* the window arrays' own bytes per sample (``WindowBank.nbytes`` / loops x window samples):
  float32 OP + float32 PV + uint8 quality per loop, plus one float64 timestamp per row;
* the process's RSS growth from building the gateway, per sample (the windows are filled
  with NaN at construction, so their pages are resident);
* the raw float32 OP/PV pair, 8 bytes, is the target.

Also listed: the transient memory of an analysis round (windows copied out in batches, at
most 2 x workers batches at once).
"""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

from bench.speed._scale import default_plcs, gateway_config, rss_bytes, sim_config
from gateway.runtime.gateway import Gateway

SIZES = (100, 1000, 10000)
WINDOW_S = 7200.0
TARGET = 8.0  # bytes per OP/PV pair in float32


async def _child(loops: int, window_s: float) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="bench-memory-") as tmp:
        plcs = default_plcs(loops)
        per = [loops // plcs + (1 if k < loops % plcs else 0) for k in range(plcs)]
        paths, first = [], 0
        for k, n in enumerate(per):
            path = Path(tmp) / f"plc{k:02d}.yaml"
            path.write_text(yaml.safe_dump(sim_config(k, first, n, window_s=window_s)))
            paths.append(str(path))
            first += n
        config = gateway_config(paths, [1] * plcs)
        rss0 = rss_bytes()[0]
        gw = Gateway(config, serve_http=False)
        rss1 = rss_bytes()[0]
        banks = [s.bank for p in gw.pollers for s in p.groups]
        samples = sum(b.size * len(b.loops) for b in banks)
        batch = gw.scheduler.batch_size
        size = max(b.size for b in banks)
        return {"loops": loops, "samples": samples, "window_bytes": sum(b.nbytes for b in banks),
                "rss_growth": rss1 - rss0, "rss": rss1, "workers": gw.scheduler.workers,
                "round_transient": 2 * gw.scheduler.workers * batch * size * 9,
                "size": size}


def measure(loops: int, window_s: float = WINDOW_S) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-m", "bench.speed.memory", "--child", str(loops),
                          str(window_s)], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[2])
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    print(f"== memory: bytes per stored sample, {WINDOW_S / 3600:g} h windows at Ts 1 s "
          f"(cores: {os.cpu_count()}) ==")
    print(f"{'loops':>6} {'samples':>11} {'windows MiB':>11} {'array B/sample':>14} "
          f"{'RSS B/sample':>12} {'x target':>8} {'gateway RSS MiB':>15} {'target B':>8}")
    last: dict[str, float] = {}
    for m in SIZES:
        r = last = measure(m)
        per = r["window_bytes"] / r["samples"]
        rss_per = r["rss_growth"] / r["samples"]
        print(f"{m:>6} {int(r['samples']):>11} {r['window_bytes'] / 2**20:>11.1f} {per:>14.3f} "
              f"{rss_per:>12.3f} {rss_per / TARGET:>8.3f} {r['rss'] / 2**20:>15.0f} "
              f"{TARGET:>8g}")
    print("(array: float32 OP + float32 PV + uint8 quality = 9 B per loop-sample, + 8 B "
          "timestamp per row shared by a bank's loops; RSS: growth from building the gateway, "
          "config objects and result server included)")
    print(f"(an analysis round holds at most {last['round_transient'] / 2**20:.0f} MiB more: "
          f"2 x {int(last['workers'])} worker(s) x 64-loop batches of "
          f"{int(last['size'])}-sample windows)")
    print()


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        print(json.dumps(asyncio.run(_child(int(sys.argv[2]), float(sys.argv[3])))))
    else:
        main()
