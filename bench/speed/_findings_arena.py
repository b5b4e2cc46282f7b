"""One gateway of 2,000 loops with a findings file of 20,000 rows, in this process, on the
tree first on ``PYTHONPATH`` (run as a script by :mod:`bench.speed.findings_scale`): how long the
event loop stalls and how many poll ticks pass while each loop gets its first verdict and
the rounds after. Imports only the tree under test, numpy, yaml and the standard library.

    python bench/speed/_findings_arena.py '{"loops": 2000, "findings": 20000, "rounds": 3}'

prints JSON lines, the last one the figures: ``stall_s`` (the longest a 10 ms timer on the
event loop was late),
``missed`` (``stiction_poll_missed_ticks_total`` of the device, polled every 0.1 s),
``rounds``, ``judged`` (loops with a verdict), ``seconds`` (the run, from the first poll);
every 2 s before, the figures so far (``partial``), for a run stopped from outside.
The analysis is a stand-in (every loop sticky, in a worker process: the analysis' own cost
is not what is measured), the plant step off.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

FAKE = '''
from stiction import Assessment, Verdict


def analyze(op, pv, *, ts, **_):
    return Assessment(Verdict.STICTION, "bench: every loop sticky", oscillating=True,
                      period_s=10.0 * ts, confidence=0.95)
'''


def _config(folder: Path, loops: int, findings: int) -> Any:
    from gateway.config import parse_config  # noqa: PLC0415 - the tree under test

    today = dt.date.today()
    kinds = ("stiction", "ok", "deadband", "other")
    rows = ["loop,date,finding,by,note"]
    rows += [f"L{k % loops},{today - dt.timedelta(days=1 + k % 300)},{kinds[k % 4]},"
             f"crew {k % 7},visit {k}" for k in range(findings)]
    (folder / "findings.csv").write_text("\n".join(rows) + "\n")
    raw = {"gateway": {"analysis_interval_s": 4.0, "analysis_workers": 1,
                       "state_file": str(folder / "gw.state")},
           "metrics": {"listen": "127.0.0.1:0"},
           "modbus_server": {"listen": "127.0.0.1:0"},
           "plant": {"enabled": False},
           "devices": [{"name": "plc", "protocol": "memory", "poll_interval_s": 0.1,
                        "timeout_s": 1.0, "repeat": True,
                        "values": [[50.0 + (5.0 if r else -5.0)] * (2 * loops)
                                   for r in range(2)]}],
           "loops": [{"name": f"L{k}", "device": "plc", "op": {"column": 2 * k},
                      "pv": {"column": 2 * k + 1}, "window_s": 3.0,
                      "result_address": 20 * (k % 3276), "result_unit_id": 1 + k // 3276}
                     for k in range(loops)],
           "findings": str(folder / "findings.csv")}
    return parse_config(raw, str(folder / "gw.yaml"))


async def _run(config: Any, rounds: int, limit_s: float) -> dict[str, Any]:
    from gateway.runtime.gateway import Gateway  # noqa: PLC0415

    gw = Gateway(config, analyze="benchfake:analyze", serve_http=False)
    loop = asyncio.get_running_loop()
    stall = 0.0
    async with gw:
        await gw.polling.wait()
        t0 = shown = time.perf_counter()

        def figures() -> dict[str, Any]:
            missed = gw.registry.get_sample_value("stiction_poll_missed_ticks_total",
                                                  {"device": "plc"}) or 0.0
            return {"stall_s": stall, "missed": int(missed), "rounds": gw.scheduler.rounds,
                    "judged": sum(1 for r in gw.store.results if r is not None),
                    "seconds": time.perf_counter() - t0,
                    "findings": len(gw.findings.findings)}

        while gw.scheduler.rounds < rounds and time.perf_counter() - t0 < limit_s:
            before = loop.time()
            await asyncio.sleep(0.01)
            stall = max(stall, loop.time() - before - 0.01)
            if time.perf_counter() - shown > 2.0:  # so far, should the run be stopped
                print(json.dumps({**figures(), "partial": True, "wall": time.time()}),
                      flush=True)
                shown = time.perf_counter()
        return figures()


def main(argv: list[str]) -> None:
    import faulthandler  # noqa: PLC0415 - kill -USR1: where a long run is
    import signal  # noqa: PLC0415

    faulthandler.register(signal.SIGUSR1)
    args = json.loads(argv[0]) if argv else {}
    loops, findings = int(args.get("loops", 2000)), int(args.get("findings", 20000))
    with tempfile.TemporaryDirectory(prefix="bench-findings-") as tmp:
        folder = Path(tmp)
        (folder / "benchfake.py").write_text(FAKE)
        sys.path.insert(0, str(folder))
        import os  # noqa: PLC0415 - the spawned analysis worker imports the stand-in too

        os.environ["PYTHONPATH"] = os.pathsep.join([str(folder),
                                                    os.environ.get("PYTHONPATH", "")])
        config = _config(folder, loops, findings)
        out = asyncio.run(_run(config, int(args.get("rounds", 3)),
                               float(args.get("limit_s", 240.0))))
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
