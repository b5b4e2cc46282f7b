"""Issue 35's findings about the analysis (confident wrong answers), as cases."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable
from typing import Any

import numpy as np
from _case import SHARED, case, run

MEASURED = "measured from the valve's travel"
RECORD = SHARED / "data" / "plant-stictiongpt" / "STI_2411FIC20102_0825_0004.csv"


def _said(a: Any) -> str:
    conf = "-" if a.confidence is None else f"{a.confidence:.2f}"
    return f"{a.verdict.value} {conf}"


@case("35.1", "a good valve under a 5-min sine load, exported at 1 min: never `stiction`")
def fast_cycle_load_at_one_minute() -> tuple[str, bool]:
    from stiction.scenarios.named import scenario, simulate  # noqa: PLC0415

    sim = simulate(scenario("disturbance", dist_period=300.0), noise=0.05, duration=28800.0,
                   seed=1)
    op, pv = np.asarray(sim.op)[::60], np.asarray(sim.pv)[::60]
    from stiction import analyze  # noqa: PLC0415

    a = analyze(op, pv, ts=60.0)
    return _said(a), a.verdict.value != "stiction"


@case("35.1", "plant record STI_2411FIC20102_0825_0004 (all nine tests abstain, one SP step): "
              "never `stiction` on nothing an engineer can check: a call names the evidence "
              "that backs it (a test or the shape network voting stiction), with or without "
              "its SP column")
def plant_record_of_a_setpoint_step() -> tuple[str, bool]:
    from stiction import analyze  # noqa: PLC0415

    def backed(a: Any) -> bool:  # (the learned decision's own evidence is no backing)
        return a.verdict.value != "stiction" or any(
            e.vote == 1 for e in a.evidence if e.test != "decision")

    data = np.genfromtxt(RECORD, delimiter=",", names=True)
    plain = analyze(data["op"], data["pv"], ts=10.0)
    said, ok = f"op/pv: {_said(plain)}", backed(plain)
    try:
        with_sp = analyze(data["op"], data["pv"], ts=10.0, sp=data["sp"])
    except TypeError:  # no setpoint in this tree's analyze
        return f"{said}; sp: not read", False
    votes = ",".join(e.test for e in with_sp.evidence if e.vote == 1 and e.test != "decision")
    return (f"{said}; with sp: {_said(with_sp)} (stiction votes: {votes or 'none'})",
            ok and backed(with_sp) and "setpoint" in with_sp.reason)


def _sim(name: str, *, duration: float, noise: float, seed: int) -> Any:
    from stiction.scenarios.named import simulate  # noqa: PLC0415

    return simulate(name, duration=duration, noise=noise, seed=seed)


def _not_used(sim: Any, pos: np.ndarray) -> tuple[str, bool]:
    """OP and PV's verdict, the position not used (the travel did not decide)."""
    from stiction import analyze  # noqa: PLC0415

    plain = analyze(sim.op, sim.pv, ts=1.0)
    a = analyze(sim.op, sim.pv, ts=1.0, position=pos)
    decided = "travel decided" if MEASURED in a.reason else "OP/PV decided"
    return (f"{_said(a)} ({decided}; OP/PV alone {_said(plain)})",
            a.verdict == plain.verdict and MEASURED not in a.reason)


def _late(vp: np.ndarray, k: int = 5) -> np.ndarray:
    return np.concatenate((np.full(k, vp[0]), vp[:-k]))


BROKEN: tuple[tuple[str, str, str, dict[str, Any], Callable[[Any], np.ndarray]], ...] = (
    ("position_inverted", "inverted (100 - position), a very sticky valve", "table4-case2",
     {"duration": 3600.0, "noise": 0.05, "seed": 1}, lambda s: 100 - s.vp),
    ("position_pv_wired_in", "PV wired in as the position, a good valve", "disturbance",
     {"duration": 7200.0, "noise": 0.02, "seed": 1}, lambda s: s.pv),
    ("position_fraction", "a 0-1 fraction, a sticky valve", "table4-case1",
     {"duration": 3600.0, "noise": 0.05, "seed": 1}, lambda s: s.vp / 100),
    ("position_frozen", "frozen while PV follows OP, a good valve", "disturbance",
     {"duration": 3600.0, "noise": 0.05, "seed": 1}, lambda s: np.full_like(s.vp, s.vp[0])),
    ("position_late", "5 samples late, an aggressively tuned loop", "aggressive-tuning",
     {"duration": 1800.0, "noise": 0.02, "seed": 3}, lambda s: _late(s.vp)),
)


def _broken(fn: str, name: str, kw: dict[str, Any], make: Callable[[Any], np.ndarray]
            ) -> Callable[[], tuple[str, bool]]:
    def one() -> tuple[str, bool]:
        sim = _sim(name, **kw)
        return _not_used(sim, make(sim))

    one.__name__ = fn
    return one


for _fn, _what, _name, _kw, _make in BROKEN:
    case("35.2", f"a position {_what}: OP and PV's verdict, the position not used")(
        _broken(_fn, _name, _kw, _make))


@case("35.2", "a position usable every other round (a good valve, square load): the "
              "published verdict does not flip")
def position_usable_every_other_round() -> tuple[str, bool]:
    from gateway.config import HysteresisSettings  # noqa: PLC0415
    from gateway.core.hysteresis import VerdictFilter  # noqa: PLC0415
    from stiction import analyze  # noqa: PLC0415
    from stiction.models.simulate import LoopBank  # noqa: PLC0415
    from stiction.scenarios import scenario  # noqa: PLC0415

    sc = scenario("healthy")
    bank = LoopBank(1, sc.loop_params(0.05), sc.valve(), ts=1.0, seed=0)
    n, window, step, warm = 9000, 3600, 600, 1200
    rows = np.empty((3, n))
    for i in range(n):
        s = bank.step(50.0, load=0.05 if (i % 600) < 300 else -0.05)
        rows[:, i] = s.op[0], s.pv[0], s.vp[0]
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    published = []
    for k in range(7):
        w = slice(warm + k * step, warm + k * step + window)
        pos = rows[2, w].copy()
        if k % 2:
            pos[: window // 5] = np.nan
        a = analyze(rows[0, w], rows[1, w], ts=1.0, op_range=(0.0, 100.0), position=pos)
        published.append(f.publish("FIC101", a, float(k)).verdict.value)
    flips = sum(x != y for x, y in itertools.pairwise(published))
    return f"{flips} flips in {len(published)} rounds ({', '.join(published)})", flips == 0


_SAME = """
import sys
import numpy as np
from stiction.scenarios.plant import simulate_plants
from stiction.scenarios.plants import NAMED_PLANTS
(rec,) = simulate_plants([NAMED_PLANTS["sticky-feeds-two"]], duration=2400.0, ts=1.0, seed=4)
np.save(sys.argv[1], np.array([rec.pv[n] for n in sorted(rec.pv)]))
"""


@case("35.0", "the demo's plant runs the same on every processor path (numpy's AVX-512 "
              "paths on and off): the demo's verdicts are the same on every machine")
def demo_plant_same_everywhere() -> tuple[str, bool]:
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, off in enumerate(("", "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL "
                                     "AVX512_ICL AVX512_SPR X86_V4")):
            out = os.path.join(tmp, f"{k}.npy")
            env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": off}
            subprocess.run([sys.executable, "-c", _SAME, out], check=True, env=env)
            runs.append(np.load(out))
    diff = float(np.abs(runs[0] - runs[1]).max())
    return f"largest PV difference between the two runs {diff:.3g}", diff == 0.0


if __name__ == "__main__":
    run(sys.argv[1:])
