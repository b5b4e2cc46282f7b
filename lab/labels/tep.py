"""Windows and plant runs of the Tennessee Eastman runs (lab/windows/tep.py), labelled
(lab/labels/rules.py) against their operating mode's normal runs."""

from __future__ import annotations

import collections
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._types import PlantRun, Window
from ..sources.tep import LOOPS, valve_command
from ..sources.tep_plan import TepRun
from ..windows.tep import GATEWAY_AT, GATEWAY_N, HISTORIAN, RECORD_H, TS, views
from . import rules

PROCESS = "self-regulating"  # flows and temperatures; none of the XMV loops is a level
_PVS = {lp.pv for lp in LOOPS}


def valve_stats(v: dict[str, Any]) -> dict[str, rules.ValveStats]:
    """A kept sticky valve's stats per gateway window and over the whole recorded part."""
    cmd = valve_command(v["op"].astype(np.float64), v["band"], start=v["start"])
    stats = {"whole": rules.valve_stats(cmd, TS)}
    for k, at in enumerate(GATEWAY_AT):
        i = round(at * 3600 / TS)
        if i + GATEWAY_N <= cmd.size:
            stats[f"gateway{k}"] = rules.valve_stats(cmd[i : i + GATEWAY_N], TS)
    return stats



def _references(items: Sequence[dict[str, Any]]) -> list[rules.Reference] | None:
    normals = [d for d in items if d["run"].cause == "normal" and not d["tripped"]]
    if not normals:
        return None
    return [rules.Reference.of([d["summary"][j] for d in normals]) for j in range(len(LOOPS))]


def _other_labels(d: dict[str, Any], refs: list[rules.Reference]) -> dict[int, rules.OtherLabel]:
    run: TepRun = d["run"]
    cycles = [v["f0"] for v in d["valves"].values()
              if v["stats"]["whole"].cause_class == "stiction"]
    return {j: rules.other_label(d["summary"][j], refs[j], sticky=bool(run.sticky),
                               cycles_hz=cycles, disturbed=run.disturbed)
            for j in range(len(LOOPS)) if j not in d["valves"]}


def _meta(run: TepRun, op: np.ndarray, extra: dict[str, Any]) -> dict[str, Any]:
    sat = float(np.mean((op <= 0.5) | (op >= 99.5)))
    return {"mode": run.mode, "seed": run.seed, "idvs": run.idvs, "sticky": run.sticky,
            "op_sd": float(op.std()), "op_p2p": float(np.ptp(op)), "saturated": sat, **extra}


def _label(d: dict[str, Any], j: int, view: str, stats_key: str,
           others: dict[int, rules.OtherLabel]) -> tuple[str, float, dict[str, Any], str]:
    """(cause class, stiction size, meta, note) of loop ``j`` in one view of run ``d``; a
    sticky valve's position (simulated, not measured in a plant) is in the gateway and
    historian views' meta as ``valve_position``."""
    if j in d["valves"]:
        v = d["valves"][j]
        st: rules.ValveStats = v["stats"][stats_key]
        pos = v["pos_historian"] if view == "historian" else \
            v["pos_gateway"].get(int(stats_key[-1])) if view == "gateway" else None
        meta = {"slips": st.slips, "held": st.held, "median_hold": st.median_hold,
                "slip_period_s": st.period_s, "cycle_s": 1.0 / v["f0"],
                "model_error": v["model_error"],
                "valve_position": None if pos is None else pos.astype(np.float64)}
        note = (f"sticky valve, band {v['band']:g} % of span: {st.slips} slips, held "
                f"{st.held:.0%} of samples, median rest {st.median_hold:g} samples, "
                f"cycle about {1.0 / v['f0']:.0f} s")
        return st.cause_class, float(v["band"]), meta, note
    o = others[j]
    note = (f"SD {o.sd_ratio:.2f} x the normal runs' largest, power in the sticky cycle's "
            f"band {o.cycle_ratio:.1f} x")
    return o.cause_class, 0.0, {"sd_ratio": o.sd_ratio, "cycle_ratio": o.cycle_ratio}, note


def _run_windows(d: dict[str, Any], refs: list[rules.Reference]) -> list[Window]:
    run: TepRun = d["run"]
    others = _other_labels(d, refs)
    out = []
    tripped = f"; plant tripped ({d['tripped']})" if d["tripped"] else ""
    for view, key, ts, t0, ops, pvs in views(d):
        for j, lp in enumerate(LOOPS):
            cls, size, extra, note = _label(d, j, view, key, others)
            op = ops[j].astype(np.float64)
            meta = _meta(run, op, extra)
            sat = f"; OP at a limit {meta['saturated']:.0%} of the window" \
                if meta["saturated"] > 0.2 else ""
            out.append(Window(
                f"tep-{run.mode}", run.id, lp.name, run.cause, cls, j in d["valves"], op,
                pvs[j].astype(np.float64), ts, PROCESS,
                f"{lp.description}; {run.id}; OP SD {meta['op_sd']:.3g} %; {note}{sat}"
                f"{tripped}", size, view, t0, meta))
    return out


def _plant_run(d: dict[str, Any], windows: Sequence[Window]) -> PlantRun | None:
    if "historian" not in d:
        return None
    run: TepRun = d["run"]
    h = d["historian"]
    labels = {w.loop: w.cause_class for w in windows if w.view == "historian"}
    loops = {lp.name: (h["op"][j].astype(np.float64), h["pv"][j].astype(np.float64))
             for j, lp in enumerate(LOOPS)}
    sps = {lp.name: h["sp"][j].astype(np.float64) for j, lp in enumerate(LOOPS)}
    indicators = {f"XMEAS{i + 1}": h["xmeas"][i].astype(np.float64)
                  for i in range(h["xmeas"].shape[0]) if i not in _PVS}
    sticky = tuple(LOOPS[j].name for j in sorted(d["valves"]))
    bands = {LOOPS[j].name: float(v["band"]) for j, v in d["valves"].items()}
    note = f"{run.id}: 24 h from {RECORD_H[0]:g} h, onset at 0.5 h, snapshots every 36 s"
    if d["tripped"]:
        note += f"; plant tripped ({d['tripped']})"
    return PlantRun(run.id, f"tep-{run.mode}", run.mode, run.seed, run.idvs, bands,
                    TS * HISTORIAN, loops, sps, indicators, labels, sticky, bool(run.idvs),
                    note, {"sticky": run.sticky, "cause": run.cause, "t0": RECORD_H[0]})


def tep_records(reduced: Sequence[dict[str, Any]]) -> tuple[list[Window], list[PlantRun]]:
    """Windows and plant runs of every reduced run whose mode has a normal run."""
    by_mode: dict[str, list[dict[str, Any]]] = collections.defaultdict(list)
    for d in reduced:
        by_mode[d["run"].mode].append(d)
    windows: list[Window] = []
    plant_runs: list[PlantRun] = []
    for items in by_mode.values():
        refs = _references(items)
        if refs is None:
            continue
        for d in items:
            for v in d["valves"].values():
                v["stats"] = valve_stats(v)  # rebuilt from OP at each load: cheap
            ws = _run_windows(d, refs)
            windows += ws
            pr = _plant_run(d, ws)
            if pr is not None:
                plant_runs.append(pr)
    return windows, plant_runs
