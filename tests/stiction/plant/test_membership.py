"""Membership with margins (issue 37, item 3; issue 35): a signal joins a group only when
it clearly carries the cycle; one about a bar is marginal, listed with the group and given
no role, so no machine puts it on one side and another machine on the other."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from stiction import Assessment, Verdict
from stiction.plant import Group, Member, PlantAssessment, analyze_plant
from stiction.plant.groups import MEMBER, STRANGER

N, PERIOD = 7200, 100.0


def _lagged(x: np.ndarray, tau: float) -> np.ndarray:
    a = np.exp(-1.0 / tau)
    y = np.empty_like(x)
    s = 0.0
    for i, v in enumerate(x):
        s = a * s + (1.0 - a) * v
        y[i] = s
    return y


@functools.cache
def _loops() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A square cycle of 100 samples whose phase wanders (FIC1, its source), a clear
    follower (TIC2), and PIC3: the cycle in step with the source but weak (3-4 % of its
    power) and half drowned by a cycle of its own at the same period (coherence with the
    source about 0.76): between the bars (the member bar is 0.06 of its power in a peak,
    or a coherence of 0.9; the stranger bar 0.03, or 0.6). Deterministic: no simulated
    valve, so the same numbers on every machine."""
    rng = np.random.default_rng(37)
    t = np.arange(N)
    phase = 2.0 * np.pi * t / PERIOD + np.cumsum(rng.normal(0.0, 0.02, N))
    own = 2.0 * np.pi * t / PERIOD + np.cumsum(rng.normal(0.0, 0.02, N))
    square = np.sign(np.sin(phase))
    weak = 0.2 * np.sin(phase - 0.7) + 0.18 * np.sin(own)
    return {
        "FIC1": (50 + 5 * square + rng.normal(0, 0.2, N),
                 50 + 5 * _lagged(square, 5.0) + rng.normal(0, 0.2, N)),
        "TIC2": (50 + 3 * _lagged(square, 20.0) + rng.normal(0, 0.3, N),
                 50 + 3 * _lagged(square, 30.0) + rng.normal(0, 0.3, N)),
        "PIC3": (50 + weak + rng.normal(0, 1.3, N), 50 + weak + rng.normal(0, 1.3, N)),
    }


def test_the_bars_leave_a_band_between_member_and_stranger() -> None:
    for field in dataclasses.fields(MEMBER):
        assert getattr(MEMBER, field.name) >= 1.2 * getattr(STRANGER, field.name), field.name


def test_a_loop_that_carries_a_cycle_weakly_is_marginal_and_keeps_its_verdict() -> None:
    loops = _loops()
    called = {n: Assessment(Verdict.STICTION, "stiction", confidence=0.95) for n in loops}
    view = analyze_plant(loops, ts=1.0, assessments=called)
    (g,) = view.groups
    assert abs(g.period_s - PERIOD) < 10.0
    assert set(g.loops) == {"FIC1", "TIC2"}
    (m,) = g.marginal
    assert m.name == "PIC3" and m.kind == "loop" and 0.02 < m.strength < 0.05
    assert view.roles["PIC3"].role is None and view.roles["PIC3"].group is None
    after = view.apply(called)
    assert after["PIC3"] == called["PIC3"]  # no role: its own call stands


def test_a_member_held_from_the_last_round_stays_while_it_is_in_the_band() -> None:
    """Hysteresis is the same band: held as a member, PIC3 stays one; never one, it stays
    out."""
    loops = _loops()
    held = Group(1, PERIOD, (Member("FIC1", "loop", 0.8), Member("TIC2", "loop", 0.9),
                             Member("PIC3", "loop", 0.04)), (), "FIC1", "")
    previous = PlantAssessment((held,), {})
    view = analyze_plant(loops, ts=1.0, previous=previous)
    (g,) = view.groups
    assert set(g.loops) == {"FIC1", "TIC2", "PIC3"} and not g.marginal
    without = dataclasses.replace(held, members=held.members[:2])
    view = analyze_plant(loops, ts=1.0, previous=PlantAssessment((without,), {}))
    (g,) = view.groups
    assert set(g.loops) == {"FIC1", "TIC2"} and [m.name for m in g.marginal] == ["PIC3"]
