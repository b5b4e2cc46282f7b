"""Issue 35 item 2: a loop whose position is usable in some rounds and not in others flipped
between the two readings every round, past the verdict hysteresis: the valve's travel gives
a confidence of another kind (the share of reversals that stuck) than OP and PV (a
probability), and the margin rule compared them. Now only confidences of one kind publish a
change at once; between the two readings the rounds count.

From the product's simulator: a good valve under a square-wave load (OP and PV read it as a
sticky valve, ``stiction`` 0.91, before the shape network; its travel as a valve that follows
OP, ``no_stiction``),
its position read every round but lost for a fifth of the window in every other round (too
gappy to measure: OP and PV decide)."""

from __future__ import annotations

import numpy as np

from gateway.config import HysteresisSettings
from gateway.core.hysteresis import VerdictFilter, by_travel
from stiction import Assessment, Verdict, analyze
from stiction.models.simulate import LoopBank
from stiction.scenarios import scenario

WINDOW, ROUND, ROUNDS, WARM = 3600, 600, 7, 1200  # rounds a load period apart


def _square_load_loop(n: int) -> np.ndarray:
    """OP, PV and the valve's position of a good valve under a square load (period 600 s,
    5 % of span)."""
    sc = scenario("healthy")
    bank = LoopBank(1, sc.loop_params(0.05), sc.valve(), ts=1.0, seed=0)
    out = np.empty((3, n))
    for i in range(n):
        s = bank.step(50.0, load=0.05 if (i % 600) < 300 else -0.05)
        out[:, i] = s.op[0], s.pv[0], s.vp[0]
    return out


def _rounds() -> list[Assessment]:
    op, pv, vp = _square_load_loop(WARM + WINDOW + ROUNDS * ROUND)
    out = []
    for k in range(ROUNDS):
        w = slice(WARM + k * ROUND, WARM + k * ROUND + WINDOW)
        pos = vp[w].copy()
        if k % 2:
            pos[: WINDOW // 5] = np.nan  # the positioner's reading lost: too gappy to use
        out.append(analyze(op[w], pv[w], ts=1.0, op_range=(0.0, 100.0), position=pos))
    return out


def test_a_position_usable_every_other_round_does_not_flip_the_verdict() -> None:
    rounds = _rounds()
    # the two readings, far apart: the travel's no_stiction, OP and PV's stiction
    assert [by_travel(a) for a in rounds] == [k % 2 == 0 for k in range(ROUNDS)]
    assert {a.verdict for a in rounds[0::2]} == {Verdict.NO_STICTION}
    # OP and PV's reading: 'stiction' 0.91 before the shape network (issue 36), which reads
    # the square load for what it is; whatever it says, the published verdict holds
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    published = [f.publish("FIC101", a, float(k)).verdict for k, a in enumerate(rounds)]
    assert published == [Verdict.NO_STICTION] * ROUNDS
    assert f.counts["published"] == 0


def test_a_change_of_one_kind_is_still_published_at_once() -> None:
    """The margin rule stands where both confidences are OP and PV's (a valve repaired) or
    both the travel's."""
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    f.publish("L", Assessment(Verdict.STICTION, "r", confidence=0.95), 0.0)
    assert f.publish("L", Assessment(Verdict.NO_STICTION, "r", confidence=0.1),
                     1.0).verdict == Verdict.NO_STICTION
    rounds = _rounds()
    travel_sticks = Assessment(Verdict.STICTION, "r", confidence=1.0,
                               evidence=rounds[0].evidence)
    g = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    g.publish("L", travel_sticks, 0.0)
    assert g.publish("L", rounds[0], 1.0).verdict == Verdict.NO_STICTION
