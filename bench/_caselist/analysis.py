"""Issue 35's findings about the analysis (confident wrong answers), as cases."""

from __future__ import annotations

import sys

import numpy as np
from _case import case, run


@case("35.1", "a good valve under a 5-min sine load, exported at 1 min: never `stiction`")
def fast_cycle_load_at_one_minute() -> tuple[str, bool]:
    from stiction.scenarios.named import scenario, simulate  # noqa: PLC0415

    sim = simulate(scenario("disturbance", dist_period=300.0), noise=0.05, duration=28800.0,
                   seed=1)
    op, pv = np.asarray(sim.op)[::60], np.asarray(sim.pv)[::60]
    from stiction import analyze  # noqa: PLC0415

    a = analyze(op, pv, ts=60.0)
    conf = "-" if a.confidence is None else f"{a.confidence:.2f}"
    return f"{a.verdict.value} {conf}", a.verdict.value != "stiction"


if __name__ == "__main__":
    run(sys.argv[1:])
