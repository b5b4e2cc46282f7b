"""Issue 39's acceptance: a simulated site of 200 loops (the simulated PLC's loops, 1 in 8 with
a sticky valve) polled every 10 s, where the shipped thresholds do not carry (most good loops
read `undetermined`, most sticky ones too): the gateway's list, worst first, holds more
sticky valves in its top 20 than the verdicts' own order (stiction calls first, then a valve
not responding, undetermined, ..., each in config order), measured side by side.

The windows are the simulated PLC's samples (plcsim.sim.PlcSim, stepped without a socket),
each analysed as a gateway worker analyses it (gateway.core.jobs.analyze_batch with
stiction.analyze), published into the gateway's result store and ranked by its list
(gateway.core.ranking). Seed 7: the list holds 20 sticky valves of 23 in its top 20, the
verdicts' order 10 (seeds 8-11: 19, 16, 20, 20 against 12, 7, 14, 10)."""

from __future__ import annotations

import math

import numpy as np

from gateway.core.jobs import LoopJob, analyze_batch
from gateway.core.ranking import rerank, suspects
from gateway.core.store import ResultStore
from plcsim import parse_sim_config
from plcsim.sim import PlcSim
from stiction.ranking import verdict_order

TS = 10.0  # s between samples: the gateway's poll interval
SAMPLES = 3600  # 10 h


def _site(seed: int) -> tuple[list[dict[str, object]], set[str]]:
    """200 loops: 1 in 8 a sticky valve of a flow loop (He's model, fs 0.5-8 % of span),
    the others perfect valves in loops tuned near their ultimate gain, under a sinusoidal
    load, or settling under noise and random loads."""
    rng = np.random.default_rng(seed)

    def lu(a: float, b: float) -> float:
        return float(math.exp(rng.uniform(math.log(a), math.log(b))))

    loops: list[dict[str, object]] = []
    sticky = set()
    for k in range(200):
        name, u = f"L{k:03d}", rng.random()
        noise = round(lu(0.01, 0.2), 4)
        if u < 0.125:
            fs = lu(0.005, 0.08)
            params = {"fs": round(fs, 5), "fd": round(fs * rng.uniform(0.5, 0.9), 5),
                      "kc": round(rng.uniform(0.5, 1.5), 3), "ti": round(rng.uniform(4, 15), 2),
                      "tau": round(rng.uniform(6, 40), 2)}
            loops.append({"name": name, "scenario": "table4-case1", "noise": noise,
                          "params": params})
            sticky.add(name)
        elif u < 0.45:
            loops.append({"name": name, "scenario": "aggressive-tuning", "noise": noise,
                          "params": {"kc": round(8.5 * rng.uniform(0.6, 1.0), 3),
                                     "load_sd": round(lu(0.003, 0.03), 4)}})
        elif u < 0.7:
            loops.append({"name": name, "scenario": "disturbance", "noise": noise,
                          "params": {"dist_amp": round(lu(0.005, 0.05), 4),
                                     "dist_period": round(rng.uniform(150, 900), 1),
                                     "tau": round(rng.uniform(20, 120), 1)}})
        else:
            loops.append({"name": name, "scenario": "healthy", "noise": round(lu(0.01, 0.3), 4),
                          "params": {"load_sd": round(lu(0.003, 0.03), 4)}})
    return loops, sticky


def test_the_lists_top_20_holds_more_sticky_valves_than_the_verdicts_order() -> None:
    loops, sticky = _site(7)
    cfg = parse_sim_config({"listen": "127.0.0.1:0", "seed": 7, "ts": TS, "loops": loops},
                           "site")
    sim = PlcSim(cfg)
    op, pv = np.empty((SAMPLES, 200)), np.empty((SAMPLES, 200))
    for i in range(SAMPLES):
        sim.step()
        op[i], pv[i] = sim.op[:200], sim.pv[:200]
    jobs = [LoopJob(k, op[:, k].astype(np.float32), pv[:, k].astype(np.float32),
                    np.zeros(SAMPLES, dtype=np.uint8), SAMPLES, TS, None, 0.0,
                    "self-regulating", (0.0, 100.0)) for k in range(200)]
    store = ResultStore([str(lp["name"]) for lp in loops])
    for index, a, fill, samples, _s, swing in analyze_batch("stiction:analyze", jobs):
        store.set_result(index, a, t=1e9, window_fill=fill, samples=samples, pv_swing=swing)
    rerank(store)
    listed = sorted(store.loops, key=lambda n: store.rank[store.index[n]])
    own = verdict_order(suspects(store))
    in_list = sum(n in sticky for n in listed[:20])
    in_own = sum(n in sticky for n in own[:20])
    print(f"{len(sticky)} sticky valves of 200; in the top 20: the list {in_list}, the "
          f"verdicts' own order {in_own}")
    assert len(sticky) == 23
    assert in_list >= in_own + 5, (in_list, in_own)
    assert in_list >= 15
    # the thresholds do not carry here: most good loops read undetermined, most sticky too
    verdicts = {n: str(store.results[store.index[n]].assessment.verdict) for n in store.loops}
    assert sum(v == "undetermined" for n, v in verdicts.items() if n not in sticky) >= 50
    assert sum(v == "stiction" for v in verdicts.values()) < 20
