"""The recorded sources: the plant records (../shared/data/plant-stictiongpt, a run per tag),
the shared Tennessee Eastman runs (../shared/data/tep-sticky-valves) and the single cases of
../shared/data/cases whose right answer is stated; each as :class:`Case` records to score
(``python -m bench real_data``) and as the corpus's windows and plant runs."""

from __future__ import annotations

import collections
import csv
import dataclasses
import re
from pathlib import Path

import numpy as np

from .._types import PlantRun, Window

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
PLANT = SHARED / "plant-stictiongpt"
TEP = SHARED / "tep-sticky-valves"
CASES = SHARED / "cases"
# the cases' README gives what went wrong and the right answer; each known file here
CASE_LABELS = {"aggressive-tuning-analyze-raises": ("tuning", "tuning", "self-regulating")}


@dataclasses.dataclass(frozen=True)
class Case:
    """One record to score: ``group`` is what a score is grouped by (tag, run, loop)."""

    dataset: str
    name: str
    group: str
    sticky: bool
    cause: str
    op: np.ndarray
    pv: np.ndarray
    ts: float
    process: str = "self-regulating"
    note: str = ""


def _csv(path: Path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {n: np.asarray(data[n], dtype=np.float64) for n in data.dtype.names or ()}


def plant_cases() -> list[Case]:
    with (PLANT / "labels.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        d = _csv(PLANT / f"{r['loop']}.csv")
        out.append(Case("plant", r["loop"], r["tag"], r["label"] == "stiction",
                        r["loop_type"], d["op"], d["pv"], float(np.median(np.diff(d["t"])))))
    return out


def _tep_cause(cause: str, sticky: bool) -> str:
    if sticky:
        return "sticky (IDV 14)" if "14" in cause else "sticky (IDV 15)"
    if cause.startswith("propagated"):
        return "propagated"
    if cause.startswith("none"):
        return "normal"
    return "disturbance"


def tep_cases() -> list[Case]:
    out = []
    for sub in ("braatz", "ricker"):
        with (TEP / sub / "labels.csv").open() as fh:
            for r in csv.DictReader(fh):
                d = _csv(TEP / sub / f"{r['name']}.csv")
                sticky = r["label"] == "stiction"
                out.append(Case("tep", f"{sub}/{r['name']}", f"{sub}/{r['name']}", sticky,
                                _tep_cause(r["cause"], sticky), d["op"], d["pv"],
                                float(r["ts"])))
    return out



def plant_windows() -> list[Window]:
    """The plant records, one run per tag (records of a tag are one valve)."""
    with (PLANT / "labels.csv").open() as fh:
        types = {r["loop"]: r["loop_type"] for r in csv.DictReader(fh)}
    out = []
    for c in plant_cases():
        kind = types[c.name]
        process = "integrating" if kind == "level" else "self-regulating"
        out.append(Window(
            "plant", f"plant-{c.group}", c.name, kind,
            "stiction" if c.sticky else "non-stiction", c.sticky, c.op, c.pv, c.ts, process,
            f"{kind} loop, tag {c.group}; label as published (how it was assigned is not "
            "documented); process type from the loop type (level: integrating)",
            float("nan"), "record", float("nan"), {"tag": c.group, "loop_type": kind}))
    return out


def _shared_run(name: str) -> tuple[str, str, int | None]:
    """(run, loop, IDV) of a shared TEP record: ``braatz/d14_te_reactor_cw`` is loop
    ``reactor_cw`` of run ``braatz/d14_te``, IDV 14."""
    sub, base = name.split("/", 1)
    m = re.match(r"(d(\d\d)(?:_te)?|idv(\d\d))_(.+)$", base)
    if m is None:
        return name, "loop", None
    idv = int(m.group(2) or m.group(3))
    return f"{sub}/{m.group(1)}", m.group(4), idv or None


def shared_tep_windows() -> list[Window]:
    out = []
    for c in tep_cases():
        run, loop, idv = _shared_run(c.name)
        cls = {"normal": "normal", "propagated": "propagated", "disturbance": "disturbance"}
        cause_class = "stiction" if c.sticky else cls.get(c.cause, "disturbance")
        cause = f"idv{idv}" if idv else "normal"
        hidden = "; README: IDV 15 is barely visible in these records" if idv == 15 else ""
        out.append(Window(
            "tep-shared", f"tep-shared-{run}", loop, cause, cause_class, c.sticky, c.op, c.pv,
            c.ts, "self-regulating", f"{c.name}: {c.cause}{hidden}", float("nan"), "record",
            float("nan"), {"idv": idv}))
    return out


def shared_tep_plant_runs(windows: list[Window]) -> list[PlantRun]:
    """The shared TEP runs as plant runs: two loops each (the two cooling-water valves'),
    no other signal recorded."""
    by_run: dict[str, list[Window]] = collections.defaultdict(list)
    for w in windows:
        by_run[w.run].append(w)
    out = []
    for run, ws in sorted(by_run.items()):
        n = min(w.op.size for w in ws)
        idv = ws[0].meta["idv"]
        sticky = tuple(w.loop for w in ws if w.sticky)
        out.append(PlantRun(
            run, "tep-shared", "mode1", None, ((idv, 1.0),) if idv else (), {},
            ws[0].ts, {w.loop: (w.op[:n], w.pv[:n]) for w in ws}, {}, {},
            {w.loop: w.cause_class for w in ws}, sticky,
            bool(idv) and idv not in (14, 15), "; ".join(sorted({w.note for w in ws}))))
    return out


def case_windows() -> list[Window]:
    """The single cases whose right answer the README gives (others are left out)."""
    out = []
    for path in sorted(CASES.glob("*.csv")):
        if path.stem not in CASE_LABELS:
            continue
        cause, cause_class, process = CASE_LABELS[path.stem]
        d = np.genfromtxt(path, delimiter=",", names=True)
        ts = float(np.median(np.diff(d["t"])))
        out.append(Window(
            "cases", f"case-{path.stem}", "loop", cause, cause_class, False,
            np.asarray(d["op"], np.float64), np.asarray(d["pv"], np.float64), ts, process,
            "README: a healthy valve, PI tuned far too aggressively; the right answer is a "
            "verdict and not stiction", 0.0, "record", float("nan"), {}))
    return out
