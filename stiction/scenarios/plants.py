"""Random plants with a known source of their shared oscillation, for developing and
measuring the plant-wide analysis (:mod:`stiction.plant`).

:func:`plant_scenarios` draws plants of one kind (``PLANT_KINDS``):

``sticky``
    a sticky valve (fs 1.5-6 % of span) in a fast loop whose PV feeds 2-6 loops through
    lags (a tree, sometimes with one path back: interacting loops): one group, its source
    the sticky loop.
``cascade``
    the same source as the inner (flow) loop of a cascade: the outer loop's OP is its
    setpoint, its PV drives the outer process; downstream loops follow.
``external``
    a periodic load from outside (square or sine, through a lag, 1-4 % of span) entering
    2-5 loops, good valves everywhere; in half the plants an indicator measures it: one
    group with no loop as its source.
``two``
    two sticky valves in two parts of the plant, the second with an integral time 2.5-4
    times longer (a longer cycle), each with its followers: two groups, each with its own
    source.
``tuning``
    an aggressively tuned loop (gain at 60-90 % of its ultimate gain) rung by its loads,
    feeding followers: the source is a loop, but not a valve.
``quiet``
    random loads and noise only: no group.

Every loop of a plant has loads and noise; processes are drawn by loop type (flow,
pressure, temperature, level) and tuned by the SIMC rules. Each plant is drawn from
``numpy.random.default_rng((seed, kind, index))``.
"""

from __future__ import annotations

import math

import numpy as np

from .._errors import ParameterError
from .plant import External, Indicator, Link, PlantLoop, PlantScenario

__all__ = ["NAMED_PLANTS", "PLANT_KINDS", "plant_scenarios"]

PLANT_KINDS = ("sticky", "cascade", "external", "two", "tuning", "quiet")
_TYPES = {  # (tau lo, tau hi, theta / tau lo, hi, integrating)
    "FIC": (3.0, 20.0, 0.05, 0.3, False),
    "PIC": (20.0, 120.0, 0.05, 0.3, False),
    "TIC": (100.0, 600.0, 0.05, 0.3, False),
    "LIC": (0.0, 0.0, 0.0, 0.0, True),
}


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _loop(rng: np.random.Generator, name: str, kind: str, **over: float | bool) -> PlantLoop:
    """A loop of type ``kind`` tuned by SIMC (tau_c = theta to 2 theta)."""
    tau_lo, tau_hi, r_lo, r_hi, integ = _TYPES[kind]
    if integ:
        kp = _u(rng, 0.005, 0.03)  # PV % per s per % valve
        theta = _u(rng, 2.0, 20.0)
        tc = _u(rng, 3.0, 8.0) * theta
        kc, ti, tau = 1.0 / (kp * (tc + theta)), 4.0 * (tc + theta), 1.0
    else:
        kp = _u(rng, 0.5, 2.0)
        tau = math.exp(_u(rng, math.log(tau_lo), math.log(tau_hi)))
        theta = tau * _u(rng, r_lo, r_hi)
        tc = _u(rng, 1.0, 2.0) * theta
        kc, ti = tau / (kp * (tc + theta)), min(tau, 4.0 * (tc + theta))
    fields: dict[str, float | bool] = {
        "kp": kp, "tau": tau, "theta": theta, "integrating": integ, "kc": kc, "ti": ti,
        "noise_sd": _u(rng, 0.02, 0.15), "load_sd": _u(rng, 0.0005, 0.004),
        "load_tau": _u(rng, 30.0, 300.0)}
    fields.update(over)
    return PlantLoop(name, **fields)  # type: ignore[arg-type]


def _sticky(rng: np.random.Generator, loop: PlantLoop) -> PlantLoop:
    """``loop`` with a sticky valve and the slow integral action plant flow loops often
    have (a stick-slip cycle of minutes, which the loops downstream see)."""
    fs = _u(rng, 0.015, 0.06)
    return PlantLoop(**{**loop.__dict__, "fs": fs, "fd": fs * _u(rng, 0.5, 0.9), "k": 1.99,
                        "ti": max(loop.ti, _u(rng, 150.0, 900.0)),
                        "kc": loop.kc * _u(rng, 0.3, 1.0),
                        "sp_step": _u(rng, 1.0, 4.0) * float(rng.choice([-1, 1])),
                        "load_sd": _u(rng, 0.0002, 0.0015)})


def _followers(rng: np.random.Generator, source: str, count: int, prefix: str,
               first: int) -> tuple[list[PlantLoop], list[Link]]:
    """``count`` loops reached from ``source`` as a tree of load paths."""
    loops: list[PlantLoop] = []
    links: list[Link] = []
    names = [source]
    for i in range(count):
        kind = str(rng.choice(["PIC", "TIC", "LIC", "FIC"], p=[0.3, 0.35, 0.25, 0.1]))
        name = f"{kind}{first + i}{prefix}"
        loops.append(_loop(rng, name, kind))
        parent = names[int(rng.integers(0, len(names)))] if rng.random() < 0.6 else names[0]
        links.append(Link(parent, name, gain=_u(rng, 0.5, 1.5) * float(rng.choice([-1, 1])),
                          tau=_u(rng, 5.0, 60.0), delay=_u(rng, 0.0, 20.0)))
        names.append(name)
    return loops, links


def _source_part(rng: np.random.Generator, kind: str, tag: str, first: int,
                 slower: float = 1.0) -> tuple[list[PlantLoop], list[Link], str, list[str]]:
    """A source loop (or cascade) and its followers; the source's name and the loops.
    ``slower`` multiplies a sticky source's integral time (a longer cycle)."""
    links: list[Link] = []
    if kind == "cascade":
        inner = _sticky(rng, _loop(rng, f"FIC{first}{tag}", "FIC"))
        outer_kind = str(rng.choice(["TIC", "LIC", "PIC"]))
        outer = _loop(rng, f"{outer_kind}{first + 1}{tag}", outer_kind, valve=False)
        # the outer loop is tuned against the inner loop's closed loop (slow, gain ~1)
        outer = PlantLoop(**{**outer.__dict__, "kc": outer.kc * 0.7})
        links += [Link(outer.name, inner.name, gain=1.0, tau=1.0, kind="setpoint"),
                  Link(inner.name, outer.name, gain=1.0, tau=1.0)]
        head, source = [inner, outer], inner.name
    elif kind == "tuning":
        base = _loop(rng, f"PIC{first}{tag}", str(rng.choice(["PIC", "FIC"])))
        ku = _ultimate(base)
        tuned = PlantLoop(**{**base.__dict__, "kc": ku * _u(rng, 0.6, 0.9),
                             "ti": base.tau * _u(rng, 1.0, 2.0), "load_sd": 0.004})
        head, source = [tuned], tuned.name
    else:
        sticky = _sticky(rng, _loop(rng, f"FIC{first}{tag}", str(rng.choice(["FIC", "PIC"]))))
        head = [PlantLoop(**{**sticky.__dict__, "ti": sticky.ti * slower})]
        source = head[0].name
    loops, more = _followers(rng, head[-1].name if kind == "cascade" else source,
                             int(rng.integers(2, 7)), tag, first + len(head))
    links += more
    if len(loops) >= 2 and rng.random() < 0.3:  # interacting: one path back
        links.append(Link(loops[-1].name, source, gain=_u(rng, 0.1, 0.3), tau=_u(rng, 30, 200)))
    return head + loops, links, source, [x.name for x in head + loops]


def _ultimate(lp: PlantLoop) -> float:
    """The ultimate gain of a PI loop on ``lp``'s FOPTD process (integral action ignored)."""
    w = np.logspace(-5, 1, 4000)
    phase = -np.arctan(lp.tau * w) - lp.theta * w
    k = int(np.argmax(phase <= -math.pi))
    return float(math.sqrt(1.0 + (lp.tau * w[k]) ** 2) / lp.kp)


def _external(rng: np.random.Generator, index: int) -> PlantScenario:
    loops = [_loop(rng, f"{k}{i + 1}", k) for i, k in enumerate(
        rng.choice(["PIC", "TIC", "LIC", "FIC"], size=int(rng.integers(3, 7))))]
    hit = sorted(rng.choice(len(loops), size=min(len(loops), int(rng.integers(2, 6))),
                            replace=False).tolist())
    ex = External("header", tuple(loops[i].name for i in hit),
                  tuple(_u(rng, 0.5, 1.0) * float(rng.choice([-1, 1])) for _ in hit),
                  amplitude=_u(rng, 0.01, 0.04), period=_u(rng, 300.0, 1500.0),
                  shape=str(rng.choice(["square", "sine"])), tau=_u(rng, 10.0, 120.0))
    ind = (Indicator("PI_HEADER", "header", tau=_u(rng, 5.0, 30.0)),) if rng.random() < 0.5 \
        else ()
    return PlantScenario(f"external-{index}", tuple(loops), externals=(ex,), indicators=ind,
                         sources={"header": ex.loops},
                         description=f"a {ex.shape} load of period {ex.period:.0f} s from "
                                     f"outside into {', '.join(ex.loops)}")


def plant_scenarios(kind: str, count: int, *, seed: int = 0) -> list[PlantScenario]:
    """``count`` plants of ``kind`` (see the module doc)."""
    if kind not in PLANT_KINDS:
        raise ParameterError("kind", f"must be one of {', '.join(PLANT_KINDS)}, was {kind!r}")
    out = []
    for i in range(count):
        rng = np.random.default_rng((seed, PLANT_KINDS.index(kind), i))
        if kind == "external":
            out.append(_external(rng, i))
        elif kind == "quiet":
            loops = [_loop(rng, f"{k}{j + 1}", k) for j, k in enumerate(
                rng.choice(["PIC", "TIC", "LIC", "FIC"], size=int(rng.integers(3, 7))))]
            out.append(PlantScenario(f"quiet-{i}", tuple(loops), description="loads only"))
        elif kind == "two":
            a_loops, a_links, a_src, a_all = _source_part(rng, "sticky", "a", 1)
            b_loops, b_links, b_src, b_all = _source_part(rng, "sticky", "b", 1,
                                                          slower=_u(rng, 2.5, 4.0))
            out.append(PlantScenario(
                f"two-{i}", tuple(a_loops + b_loops), tuple(a_links + b_links),
                sources={a_src: tuple(a_all[1:]), b_src: tuple(b_all[1:])},
                description=f"two sticky valves, {a_src} and {b_src}"))
        else:
            loops, links, src, names = _source_part(rng, kind, "", 1)
            out.append(PlantScenario(f"{kind}-{i}", tuple(loops), tuple(links),
                                     sources={src: tuple(n for n in names if n != src)},
                                     description=f"{kind}: source {src}"))
    return out


def _named() -> dict[str, PlantScenario]:
    """Hand-made plants for the demo, the simulated PLC and the tests."""
    fic101 = PlantLoop("FIC101", kp=1.0, tau=8.0, theta=2.0, kc=0.8, ti=150.0, fs=0.03,
                       fd=0.015, k=1.99, load_sd=0.0005, sp_step=2.0)
    tic201 = PlantLoop("TIC201", kp=1.5, tau=180.0, theta=20.0, kc=1.2, ti=180.0)
    lic301 = PlantLoop("LIC301", kp=0.01, integrating=True, theta=5.0, kc=2.5, ti=900.0)
    pic401 = PlantLoop("PIC401", kp=1.0, tau=40.0, theta=4.0, kc=1.0, ti=40.0)
    fic102 = PlantLoop("FIC102", kp=1.0, tau=6.0, theta=1.0, kc=0.5, ti=10.0)
    sticky = PlantScenario(
        "sticky-feeds-two", (fic101, tic201, lic301, pic401, fic102),
        (Link("FIC101", "TIC201", gain=0.8, tau=30.0), Link("FIC101", "LIC301", gain=0.6,
                                                             tau=20.0),
         # a slow path: PIC401 sees TIC201's slow wander, not the 2-3 minute cycle (with a
         # 60 s lag it carried it at a coherence of 0.3-0.8, about the bar: issue 37)
         Link("TIC201", "PIC401", gain=0.7, tau=600.0)),
        indicators=(Indicator("TI205", "TIC201", tau=60.0),),
        sources={"FIC101": ("TIC201", "LIC301")},
        description="a sticky flow valve (FIC101, fs 3 %) whose cycle reaches a temperature "
                    "and a level loop; PIC401 and FIC102 do not carry it")
    header = PlantScenario(
        "header-square", (tic201, lic301, pic401, fic102),
        externals=(External("steam", ("TIC201", "PIC401", "FIC102"), (0.8, -0.6, 0.5),
                            amplitude=0.02, period=600.0, shape="square", tau=30.0),),
        indicators=(Indicator("PI_STEAM", "steam", tau=10.0),),
        sources={"steam": ("TIC201", "PIC401", "FIC102")},
        description="a steam header cycling on/off every 600 s into three loops; every valve "
                    "good")
    fic501 = PlantLoop("FIC501", kp=1.0, tau=10.0, theta=2.0, kc=0.8, ti=450.0, fs=0.04,
                       fd=0.02, k=1.99, load_sd=0.0005, sp_step=-2.0)
    tic601 = PlantLoop("TIC601", kp=1.2, tau=150.0, theta=15.0, kc=1.2, ti=150.0)
    two = PlantScenario(
        "two-sources", (fic101, tic201, lic301, fic501, tic601),
        (Link("FIC101", "TIC201", gain=0.8, tau=30.0), Link("FIC101", "LIC301", gain=0.6,
                                                             tau=20.0),
         Link("FIC501", "TIC601", gain=0.9, tau=40.0)),
        sources={"FIC101": ("TIC201", "LIC301"), "FIC501": ("TIC601",)},
        description="two sticky flow valves at two periods, each with its followers")
    return {sc.name: sc for sc in (sticky, header, two)}


NAMED_PLANTS = _named()
"""Hand-made plants by name (the demo's, the simulated PLC's, the tests')."""
