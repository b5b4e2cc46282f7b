"""Is the verdict right on real loops? One table per data set, the SI-only detector beside
``analyze``, in one run.

Data sets (read each README's caveats in ../shared/data):

- **plant**: ``plant-stictiongpt``, 80 records of 34 tags. Scored per tag (majority of its
  records; ties count as stiction) and per record, with the loop types apart, because
  sticky records are mostly flow loops and the others mostly level loops.
- **TEP**: ``tep-sticky-valves``, 58 Tennessee Eastman runs. Scored per run, with the causes
  apart: normal operation, external disturbances, the loop a sticky valve disturbs
  (propagated) and the sticky valves (IDV 14 clear, IDV 15 barely visible).
- **simulations**: :func:`stiction.scenarios.realistic.realistic_loops`, each cause over
  several seeds. The ``ramp-load`` cause (a triangle or sawtooth load, which OP and PV
  cannot tell from a sticky valve) is shown on its own row and left out of the totals.

Every record is analysed as a new user would: ``analyze(op, pv, ts=ts)`` with nothing else
known (self-regulating, no op_range, no kp); the simulations once more with the process type
given, as the gateway's config gives it. A verdict ``stiction`` counts as a call;
``valve_not_responding`` counts as a call too, shown apart (it names the valve). "Decided"
means any verdict but ``undetermined`` and ``bad_data``.

SI only: He et al. (2007) alone, as the product had it before several tests: an ACF
oscillation on OP (PV for integrating loops) with at least 2.5 cycles of at least 8
samples, and SI >= 0.6. vote: the nine tests' weighted vote (stiction.diagnosis.combine,
stiction at >= 0.7), the decision before the learned one (issue 24), on the same evidence
``analyze`` gathered: the "before" beside ``analyze``'s "after".

**corpus**: the development corpus (``python -m lab corpus``) per source and cause, the vote
beside the learned decision, from the features ``python -m lab train`` cached (skipped
until it has run). The learned decision was fitted on this corpus, so these are in-sample;
the held-out figures are ``python -m lab train``'s.

``python -m bench real_data`` runs all three; ``REAL_DATA_SIMS=N`` sets the simulated
records per cause and seed (default 14, three seeds). The records are read and the
simulations drawn (and cached, keyed by the generator's source) by lab/sources/.
"""

from __future__ import annotations

import collections
import dataclasses
import os
import time
from collections.abc import Callable, Iterable

import numpy as np

from lab.sources.realistic import AMBIGUOUS, SIM_SEEDS, sim_cases
from lab.sources.records import PLANT, SHARED, TEP, Case, plant_cases, tep_cases
from stiction import Assessment, Verdict, analyze
from stiction.detectors.stiction_index import STICTION_SI, stiction_index
from stiction.diagnosis import combine
from stiction.diagnosis.evidence import TESTS
from stiction.diagnosis.model import load as load_model
from stiction.signal.oscillation import MIN_PERIOD, detect_oscillation

CALLS = (Verdict.STICTION, "valve_not_responding")
UNDECIDED = (Verdict.UNDETERMINED, Verdict.BAD_DATA)


# ----------------------------------------------------------------------------- detectors
def si_only(c: Case, process: str) -> str:
    """He et al. (2007) alone (see the module doc)."""
    x = c.pv if process == "integrating" else c.op
    if not np.all(np.isfinite(x)) or np.ptp(x) == 0:
        return str(Verdict.BAD_DATA)
    osc = detect_oscillation(x)
    if not osc.oscillating or osc.period is None:
        return str(Verdict.NOT_OSCILLATING)
    if osc.period < MIN_PERIOD or x.size / osc.period < 2.5:
        return str(Verdict.BAD_DATA)
    si = stiction_index(x, osc.period)
    if si.si is None:
        return str(Verdict.UNDETERMINED)
    if si.si >= STICTION_SI:
        return str(Verdict.STICTION)
    return str(Verdict.NO_STICTION if si.si <= 0.4 else Verdict.UNDETERMINED)


_ASSESSED: dict[tuple[str, str], Assessment] = {}


def full(c: Case, process: str) -> str:
    a = analyze(c.op, c.pv, ts=c.ts, process=process)
    _ASSESSED[(c.name, process)] = a
    return str(a.verdict)


def vote(c: Case, process: str) -> str:
    """The weighted vote on the evidence ``analyze`` gathered (the module doc)."""
    a = _ASSESSED.get((c.name, process)) or analyze(c.op, c.pv, ts=c.ts, process=process)
    if not a.evidence or a.verdict not in STICKY_OR_NOT:
        return str(a.verdict)  # a gate decided (bad data, not responding, ...)
    conf = combine.confidence(a.evidence)
    if conf >= combine.STICTION_CONFIDENCE:
        return str(Verdict.STICTION)
    if not a.oscillating and conf <= 0.5:  # as analyze said it then
        return str(Verdict.NOT_OSCILLATING)
    if conf <= combine.NO_STICTION_CONFIDENCE:
        return str(Verdict.NO_STICTION)
    return str(Verdict.UNDETERMINED)


def _tests(cases: list[Case], process: Callable[[Case], str],
           key: Callable[[Case], str]) -> None:
    """What each test said, by group of cases: '+' votes (says stiction) and '-' votes (says
    not) on the sticky cases and on the others, of how many."""
    print("  what each test said (votes +1 / -1 of n), analyze:")
    groups: dict[str, list[Case]] = collections.defaultdict(list)
    for c in cases:
        groups[key(c)].append(c)
    names = [e.test for e in _ASSESSED[(cases[0].name, process(cases[0]))].evidence] or \
        list(TESTS)
    print(f"    {'':<24}" + "".join(f"{n[:11]:>12}" for n in names))
    for label, members in sorted(groups.items()):
        votes = np.array([[next((e.vote for e in _ASSESSED[(c.name, process(c))].evidence
                                 if e.test == n), 0) for n in names] for c in members])
        cells = "".join(f"{int((votes[:, i] > 0).sum()):>5}/{int((votes[:, i] < 0).sum()):<3}"
                        f"{'':>3}" for i in range(len(names)))
        print(f"    {label:<24}{cells} n={len(members)}")


DETECTORS: dict[str, Callable[[Case, str], str]] = {"SI only": si_only, "analyze": full,
                                                     "vote": vote}  # vote after analyze
STICKY_OR_NOT = (Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                 Verdict.NOT_OSCILLATING)


# ------------------------------------------------------------------------------- scoring
@dataclasses.dataclass
class Score:
    tp: int = 0
    fn: int = 0
    fp: int = 0
    tn: int = 0
    decided: int = 0
    n: int = 0

    def add(self, sticky: bool, called: bool, decided: bool) -> None:
        self.n += 1
        self.decided += decided
        if sticky:
            self.tp += called
            self.fn += not called
        else:
            self.fp += called
            self.tn += not called

    @property
    def balanced(self) -> float:
        parts = [self.tp / (self.tp + self.fn)] if self.tp + self.fn else []
        parts += [self.tn / (self.tn + self.fp)] if self.tn + self.fp else []
        return float(np.mean(parts)) if parts else float("nan")

    def row(self) -> str:
        return (f"TP {self.tp:>3} FN {self.fn:>3} FP {self.fp:>3} TN {self.tn:>3}  "
                f"bal.acc {self.balanced:4.2f}  decided {self.decided / max(self.n, 1):4.0%}")


def _grouped(cases: Iterable[Case], verdicts: dict[str, str]) -> Score:
    """Per group: called when the majority of its records are (ties count as called),
    decided when the majority are."""
    groups: dict[str, list[Case]] = collections.defaultdict(list)
    for c in cases:
        groups[c.group].append(c)
    s = Score()
    for members in groups.values():
        calls = sum(verdicts[c.name] in CALLS for c in members)
        dec = sum(verdicts[c.name] not in UNDECIDED for c in members)
        s.add(members[0].sticky, 2 * calls >= len(members), 2 * dec >= len(members))
    return s


def _by(cases: list[Case], verdicts: dict[str, str], key: Callable[[Case], str]
        ) -> dict[str, Score]:
    out: dict[str, Score] = collections.defaultdict(Score)
    for c in cases:
        v = verdicts[c.name]
        out[key(c)].add(c.sticky, v in CALLS, v not in UNDECIDED)
    return dict(sorted(out.items()))


def _verdicts(cases: list[Case], process: Callable[[Case], str]
              ) -> dict[str, dict[str, str]]:
    return {name: {c.name: fn(c, process(c)) for c in cases} for name, fn in DETECTORS.items()}


def _table(title: str, rows: dict[str, dict[str, Score]]) -> None:
    print(f"  {title}")
    for label in next(iter(rows.values())):
        cells = "   |   ".join(f"{det}: {rows[det][label].row()}" for det in rows)
        print(f"    {label:<26} {cells}")


def _calls_by_cause(cases: list[Case], verdicts: dict[str, dict[str, str]]) -> None:
    print("  calls (stiction / valve_not_responding) and verdicts by cause, analyze:")
    causes = sorted({c.cause for c in cases})
    for cause in causes:
        members = [c for c in cases if c.cause == cause]
        counts = collections.Counter(verdicts["analyze"][c.name] for c in members)
        base = sum(verdicts["SI only"][c.name] in CALLS for c in members)
        calls = sum(counts[v] for v in CALLS)
        share = calls / len(members)
        print(f"    {cause:<22} n={len(members):>3}  called {calls:>3} ({share:4.0%})"
              f"  [SI only {base:>3} ({base / len(members):4.0%})]   "
              + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


def plant() -> dict[str, float]:
    cases = plant_cases()
    v = _verdicts(cases, lambda c: c.process)
    print(f"== plant records ({len(cases)} records, {len({c.group for c in cases})} tags) ==")
    tags = {det: {"tags (majority)": _grouped(cases, v[det])} for det in v}
    recs = {det: {"records": _by(cases, v[det], lambda c: "all")["all"],
                  **{f"  {k}": s for k, s in _by(cases, v[det], lambda c: c.cause).items()}}
            for det in v}
    _table("per tag", tags)
    _table("per record, by loop type", recs)
    print("  sticky tags, analyze (records called / records):")
    for tag in sorted({c.group for c in cases if c.sticky}):
        members = [c for c in cases if c.group == tag]
        calls = sum(v["analyze"][c.name] in CALLS for c in members)
        kinds = collections.Counter(v["analyze"][c.name] for c in members)
        print(f"    {tag:<28} {calls}/{len(members)}  "
              + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
    fps = sorted({c.group for c in cases if not c.sticky and v["analyze"][c.name] in CALLS})
    print(f"  non-sticky tags with any record called: {', '.join(fps) or 'none'}")
    _tests(cases, lambda c: c.process,
           lambda c: f"{'sticky' if c.sticky else 'not sticky'} {c.cause}")
    return {"tags": tags["analyze"]["tags (majority)"].balanced}


def tep() -> dict[str, float]:
    cases = tep_cases()
    v = _verdicts(cases, lambda c: c.process)
    print(f"== Tennessee Eastman ({len(cases)} runs) ==")
    _table("per run", {det: {"runs": _by(cases, v[det], lambda c: "all")["all"]} for det in v})
    _calls_by_cause(cases, v)
    wrong = [c.name for c in cases if (v["analyze"][c.name] in CALLS) != c.sticky
             and c.cause != "sticky (IDV 15)"]
    print(f"  wrong, analyze (IDV 15 aside): {', '.join(wrong) or 'none'}")
    _tests(cases, lambda c: c.process, lambda c: c.cause)
    return {"runs": _by(cases, v["analyze"], lambda c: "all")["all"].balanced}


def sims(per_seed: int) -> dict[str, float]:
    t0 = time.perf_counter()
    cases = sim_cases(per_seed)
    print(f"== realistic simulations ({len(cases)} records, {per_seed} per cause and seed, "
          f"seeds {SIM_SEEDS}; {time.perf_counter() - t0:.0f} s to load) ==")
    scored = [c for c in cases if c.cause not in AMBIGUOUS]
    for label, process in (("process unknown", lambda c: "self-regulating"),
                           ("process given", lambda c: c.process)):
        v = _verdicts(cases, process)
        print(f"  -- {label}")
        _table(f"all records but {', '.join(AMBIGUOUS)}",
               {det: {"records": _by(scored, v[det], lambda c: "all")["all"]} for det in v})
        _calls_by_cause(cases, v)
        _tests(cases, process, lambda c: c.cause)
    return {}


def main() -> None:
    t0 = time.perf_counter()
    if not PLANT.exists() or not TEP.exists():
        print(f"real_data: skipped, {SHARED} not found")
        return
    plant()
    tep()
    sims(int(os.environ.get("REAL_DATA_SIMS", "14")))
    corpus()
    print(f"({time.perf_counter() - t0:.0f} s)")


def corpus() -> None:
    """Per source and cause: the vote beside the learned decision (the module doc)."""
    from lab.features.rows import cached_rows  # noqa: PLC0415  (the built corpus's rows)
    from lab.training.report import vote  # noqa: PLC0415

    rows = cached_rows()
    if rows is None:
        print("== corpus: skipped (run python -m lab corpus, then python -m lab train) ==")
        return
    model = load_model()
    print(f"== corpus ({len(rows)} windows; in-sample for the learned decision, held out: "
          "python -m lab train) ==")
    print(f"  {'source':<12} {'cause':<14} {'n':>6}  called stiction: vote -> analyze")
    table: dict[tuple[str, str], list[int]] = collections.defaultdict(lambda: [0, 0, 0])
    for r in rows:
        cell = table[(r.source, r.cause_class)]
        cell[0] += 1
        if r.x is not None:
            cell[1] += vote(r.x) >= combine.STICTION_CONFIDENCE
            cell[2] += model.probability(r.x) >= model.stiction_at
    for (source, cause), (n, before, after) in sorted(table.items()):
        print(f"  {source:<12} {cause:<14} {n:>6}  {before:>5} ({before / n:4.0%}) -> "
              f"{after:>5} ({after / n:4.0%})")


if __name__ == "__main__":
    main()
