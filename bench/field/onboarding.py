"""When each loop of the onboarding page reads what, at real time (docs/onboarding.md, step 7).

The page's own files (its simulated PLC, tag list and config, as the page leaves them) run
here at ``TIME_SCALE`` x real time for ``HOURS`` process hours: the simulated PLC and the
gateway both count process seconds, and an analysis round comes every
``analysis_interval_s`` of them, so round k is at k x ``analysis_interval_s`` at real time
too. The table gives, per loop, the verdicts it reads round by round (with the rounds'
times) and the first round that sizes it (fd in its registers).

    python -m bench onboarding
"""

from __future__ import annotations

import asyncio
import math
import os
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from gateway.config import load_config
from gateway.runtime.gateway import Gateway
from plcsim import parse_sim_config
from plcsim.sim import PlcSim

DOC = Path(__file__).resolve().parents[2] / "docs" / "onboarding.md"
TIME_SCALE = float(os.environ.get("BENCH_ONBOARDING_SCALE", "60"))
HOURS = float(os.environ.get("BENCH_ONBOARDING_HOURS", "2.2"))
BLOCK = re.compile(r"^```\w+ file=(\S+)\n(.*?)^```", re.M | re.S)


def page_files() -> dict[str, str]:
    """The files the page writes, each as it last shows it."""
    return dict(BLOCK.findall(DOC.read_text()))


def minutes(seconds: float) -> str:
    m = round(seconds / 60)
    return f"{m} min" if m < 60 else f"{m // 60} h {m % 60:02d} min"


async def run(folder: Path) -> tuple[float, dict[str, list[tuple[int, str, bool]]]]:
    """Per loop, (round, verdict, sized) of every round; the analysis interval."""
    files = page_files()
    for name, text in files.items():
        (folder / name).write_text(text)
    sim_raw: dict[str, Any] = yaml.safe_load(files["plc-sim.yaml"])
    sim_raw.update(listen="127.0.0.1:0", time_scale=TIME_SCALE)
    gw_raw: dict[str, Any] = yaml.safe_load(files["gw.yaml"])
    gw_raw["modbus_server"] = {"listen": "127.0.0.1:0"}
    gw_raw["metrics"] = {"listen": "127.0.0.1:0"}
    gw_raw.setdefault("gateway", {})["time_scale"] = TIME_SCALE
    gw_raw["gateway"]["state_file"] = str(folder / "state" / "gateway.state")
    seen: dict[str, list[tuple[int, str, bool]]] = {}
    async with PlcSim(parse_sim_config(sim_raw, "plc-sim.yaml")) as sim:
        gw_raw["devices"][0]["port"] = sim.port
        (folder / "gw.yaml").write_text(yaml.safe_dump(gw_raw))
        config = load_config(folder / "gw.yaml")
        interval = config.gateway.analysis_interval_s
        gateway = Gateway(config)
        gateway.align_polls(sim.mid_step())
        async with gateway as gw:
            end = time.monotonic() + HOURS * 3600 / TIME_SCALE
            while time.monotonic() < end:
                await asyncio.sleep(0.2)
                for i, name in enumerate(gw.store.loops):
                    res = gw.store.results[i]
                    rows = seen.setdefault(name, [])
                    if res is not None and (not rows or rows[-1][0] != res.seq):
                        fd = res.assessment.fd
                        rows.append((res.seq, gw.store.verdict_name(i),
                                     fd is not None and math.isfinite(fd)))
    return interval, seen


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        interval, seen = asyncio.run(run(Path(tmp)))
    print(f"onboarding at real time: docs/onboarding.md's PLC and config, {HOURS:g} h of "
          f"process time run at {TIME_SCALE:g}x; a round every {interval:g} s")
    print(f"{'loop':8} {'verdicts, round by round (time of the round)':70} first sized")
    for name, rows in seen.items():
        spans: list[str] = []
        start = 0
        for k in range(1, len(rows) + 1):
            if k == len(rows) or rows[k][1] != rows[start][1]:
                a, b = rows[start][0], rows[k - 1][0]
                when = minutes(a * interval) if a == b else \
                    f"{minutes(a * interval)}-{minutes(b * interval)}"
                spans.append(f"{rows[start][1]} {when}")
                start = k
        sized = next((r[0] for r in rows if r[2]), None)
        print(f"{name:8} {', '.join(spans):70} "
              f"{'-' if sized is None else minutes(sized * interval)}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
