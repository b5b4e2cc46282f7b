"""Which loop the source evidence names (issue 37, item 4): the benchmark's misses, each from
its own evidence as `python -m bench plantwide` measured it (stiction.plant.decide).

- a declared cascade's outer loop does not compete with its inner loop's nonlinearity;
- at a historian's sampling (a cycle of under 8 samples) a lead of 0.3 or more still counts;
- a weak lead and a nonlinear cycle do not name a loop whose valve fit clears its valve;
- a confident call whose linear cycle trails an indicator's clearly nonlinear one is kept,
  the cycle entering from outside;
- an indicator's lead does not stop a loop's own sticky valve (or its suspected valve and
  nonlinear cycle) naming it, unless the indicator's cycle is the clearly nonlinear one and
  the loop's linear.
"""

from __future__ import annotations

from stiction.plant.decide import IndicatorEvidence, decide
from stiction.plant.source import MemberEvidence


def _loop(name: str, conf: float, flow: float | None, nli: float | None, *,
          verdict: str = "undetermined", gain: float | None = None,
          strength: float = 0.5) -> MemberEvidence:
    return MemberEvidence(name, strength, gain, 0.0, 0, conf, 0.0, verdict, flow, nli)


def _flows(pairs: dict[tuple[str, str], float]):  # type: ignore[no-untyped-def]
    def flow(a: str, b: str) -> float:
        return pairs.get((a, b), -pairs.get((b, a), 0.0))

    def granger(a: str, b: str) -> float:
        return max(flow(a, b), 0.0)

    return flow, granger


def test_a_cascades_outer_loop_does_not_outrank_its_inner_loops_nonlinearity() -> None:
    """cascade-14 at 20 s: the sticky inner flow loop FIC1 leads the group (+0.47) with a
    nonlinear cycle (3.2); its declared outer loop PIC2 carries the same cycle, more
    nonlinear (5.6): its valve is FIC1. Before, PIC2's index kept FIC1 from being named."""
    ranking = [_loop("FIC1", 0.96, 0.47, 3.23), _loop("PIC2", 0.95, 0.06, 5.59),
               _loop("LIC6", 0.84, -0.2, 1.42), _loop("LIC5", 0.86, -0.33, None)]
    flow, granger = _flows({("FIC1", "PIC2"): 0.4, ("FIC1", "LIC6"): 0.5,
                            ("FIC1", "LIC5"): 0.5})
    d = decide(ranking, [], flow, granger, cascades={"PIC2": "FIC1"})
    assert d.source == "FIC1" and d.named_by[:2] == ("direction", "nonlinearity")
    # an outer loop of another cascade still competes
    d = decide(ranking, [], flow, granger, cascades={})
    assert d.source is None


def test_a_clear_lead_outweighs_a_followers_call_at_a_historians_sampling() -> None:
    """two-7 at 60 s (a 191 s cycle: 3.2 samples a period): FIC1a's own window says
    undetermined at 0.98 and it leads the group by +0.5; two good valves it feeds are
    called stiction at 0.98 and trail it. Before, a lead counted for nothing under 8
    samples a period and PIC3a (a good valve) was named the source by its call."""
    ranking = [_loop("FIC1a", 0.98, 0.5, 2.32),
               _loop("PIC3a", 0.98, -0.13, 1.85, verdict="stiction"),
               _loop("PIC4a", 0.98, -0.26, 1.3, verdict="stiction"),
               _loop("TIC2a", 0.13, -0.12, None, verdict="not_oscillating")]
    flow, granger = _flows({("FIC1a", "PIC3a"): 0.55, ("FIC1a", "PIC4a"): 0.65,
                            ("FIC1a", "TIC2a"): 0.3})
    d = decide(ranking, [], flow, granger, cascades={}, period=3.2)
    assert d.source == "FIC1a" and set(d.demoted) == {"PIC3a", "PIC4a"} and not d.kept
    # a lead within the noise of a net flow at this sampling does not
    flow, granger = _flows({("FIC1a", "PIC3a"): 0.2, ("FIC1a", "PIC4a"): 0.2})
    weak = [_loop("FIC1a", 0.98, 0.15, 2.32), *ranking[1:]]
    d = decide(weak, [], flow, granger, cascades={}, period=3.2)
    assert d.source == "PIC3a"


def test_a_weak_lead_does_not_name_a_loop_whose_valve_fit_clears_it() -> None:
    """external-3 at 4 s (a square load from outside, every valve good, no indicator): the
    level it enters first leads weakly (+0.09) with a nonlinear cycle (1.7), and its valve
    fit explains nothing a linear valve does not (0.0). Before, it was named the source
    by direction and nonlinearity."""
    others = [_loop("FIC2", 0.17, -0.06, 0.13, verdict="not_oscillating", gain=0.01),
              _loop("FIC6", 0.02, -0.04, 0.06, verdict="no_stiction", gain=0.0)]
    level = _loop("LIC1", 0.03, 0.09, 1.66, verdict="no_stiction", gain=0.0)
    flow, granger = _flows({})
    d = decide([level, *others], [], flow, granger, cascades={})
    assert d.source is None
    # no fit (a historian's coarse export), or a fit that says sticky: named as before
    for gain in (None, 0.41):
        e = _loop("LIC1", 0.03, 0.09, 1.66, verdict="no_stiction", gain=gain)
        assert decide([e, *others], [], flow, granger, cascades={}).source == "LIC1"
    # a clear lead names it whatever its fit
    e = _loop("LIC1", 0.03, 0.35, 1.66, verdict="no_stiction", gain=0.0)
    assert decide([e, *others], [], flow, granger, cascades={}).source == "LIC1"


def test_a_confident_call_trailing_a_clearly_nonlinear_indicator_is_kept() -> None:
    """external-14 at 60 s: a good flow valve called stiction at 0.93 (a false call of its
    own window), its cycle linear (-0.1) and trailing (-0.13); the steam header's pressure
    leads the group (+0.24) with a clearly nonlinear cycle (2.7). Before, the loop was named
    the source (5c94178: propagated). Its call stands, kept; the cycle enters from
    outside."""
    ranking = [_loop("FIC1", 0.93, -0.13, -0.08, verdict="stiction", gain=0.03),
               _loop("TIC3", 0.38, -0.11, -0.59, verdict="no_stiction")]
    header = IndicatorEvidence("PI_HEADER", 0.95, flow=0.24, nli=2.69)
    flow, granger = _flows({})
    d = decide(ranking, [header], flow, granger, cascades={})
    assert d.source is None and d.outside == "PI_HEADER"
    assert "FIC1" in d.kept and "FIC1" not in d.demoted
    # issue 37's real record: an index of 1.6 is no such evidence (the loop leads, too)
    level = _loop("LIC1", 0.94, 0.05, 0.8, verdict="stiction", gain=0.19, strength=0.8)
    d = decide([level, ranking[1]], [IndicatorEvidence("FI4", 0.7, flow=0.12, nli=1.6)],
               flow, granger, cascades={})
    assert d.source == "LIC1" and d.upstream == "FI4"


def test_an_indicator_read_before_the_loops_transmitter_does_not_hide_its_sticky_valve() -> None:
    """A sticky level valve whose level transmitter lags 60 s (tests/stiction/plant/
    test_decide.py's plant at kc 1.0, ti 1200 s, 12 h at 20 s): its own window says
    undetermined at 0.72, a sticky valve explains 77 % more of its PV than a linear one and
    its cycle is nonlinear (4.0); a second level gauge, read before the transmitter's lag,
    leads it (+0.91, index 5.8). Before, the cycle 'entered from outside' by the gauge and
    the sticky valve was a follower; now its valve names it, the gauge upstream."""
    ranking = [_loop("LIC101", 0.72, 0.19, 4.0, gain=0.77),
               _loop("FIC201", 0.3, -0.5, 4.33, verdict="no_stiction"),
               _loop("PIC301", 0.2, -0.6, 4.44, verdict="no_stiction")]
    gauge = IndicatorEvidence("LI105", 0.07, flow=0.91, nli=5.77)
    flow, granger = _flows({("LIC101", "FIC201"): 0.77, ("LIC101", "PIC301"): 0.8})
    d = decide(ranking, [gauge], flow, granger, cascades={})
    assert d.source == "LIC101" and d.named_by[0] == "own valve" and d.upstream == "LI105"
    assert d.outside is None
    # a loop whose cycle is linear while the indicator's is clearly nonlinear: from outside
    linear = [_loop("LIC101", 0.72, 0.19, 0.4, gain=0.77), *ranking[1:]]
    d = decide(linear, [gauge], flow, granger, cascades={})
    assert d.source is None and d.outside == "LI105"


def test_a_suspected_valve_is_not_hidden_by_a_signal_read_after_it() -> None:
    """TEP mode 1, IDV 14 at 1 % (the reactor cooling-water valve XMV10 sticks; 36 s, a 269 s
    cycle: 7.5 samples a period): its own window suspects it at 0.98 (undetermined: the
    cycle is too fast to see its shape), its cycle is the nonlinear one (2.2); the cooling
    water's outlet temperature XMEAS21, right after the valve, leads it (+0.17, index 4.5).
    Before, the cycle 'entered from outside' by XMEAS21; now XMV10 is named by its
    nonlinearity, XMEAS21 upstream. A loop its window does not suspect is not."""
    other = _loop("XMV11", 0.19, -0.11, -0.1, verdict="not_oscillating")
    xmeas21 = IndicatorEvidence("XMEAS21", 0.45, flow=0.17, nli=4.46)
    flow, granger = _flows({})
    valve = _loop("XMV10", 0.98, -0.06, 2.18, strength=0.38)
    d = decide([valve, other], [xmeas21], flow, granger, cascades={}, period=7.5)
    assert d.source == "XMV10" and d.named_by[0] == "nonlinearity" and d.upstream == "XMEAS21"
    unsure = _loop("XMV10", 0.6, -0.06, 2.18, strength=0.38)
    d = decide([unsure, other], [xmeas21], flow, granger, cascades={}, period=7.5)
    assert d.source is None and d.outside == "XMEAS21"
