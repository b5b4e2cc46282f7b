"""``stiction-gateway report --config gw.yaml --since 7d -o report.html``: the maintenance
meeting's page from what a gateway keeps (docs/onboarding.md, "The list and the report").

Read, never written, each as the running gateway reads it (bounded, checked): the state file
(each loop's latest assessment and the window of samples it holds), the verdict history
beside it (each loop's verdict on each day), the site calibration's file, the findings file
and the config (priorities, PV ranges). The loops are ranked as the gateway ranks them
(:mod:`gateway.core.ranking`) and the page is :func:`stiction.report.render`'s. It runs
beside a running gateway (the files are replaced atomically, never half-written).
"""

from __future__ import annotations

import datetime as dt
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

from stiction import Assessment
from stiction.ranking import SiteCalibration, Suspect, rank
from stiction.report import Finding, Listed, Report, Trend, render

from ..config.findings import Finding as LedgerFinding
from ..config.findings import verdicts_path
from ..config.model import Config
from ..core.points import Quality
from ..errors import ConfigError
from ..outputs.sitecal import calibration_path, read_calibration
from ..outputs.sitecal.file import CalibrationError
from ..outputs.statefile import read_state
from ..outputs.statefile.format import StateError
from ..outputs.verdicts import read_history
from ..outputs.verdicts.history import HistoryError
from .findings import read_configured

__all__ = ["build_report", "parse_since", "write_report"]

_SINCE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([hdw])\s*$")
_UNITS = {"h": 3600.0, "d": 86400.0, "w": 7 * 86400.0}


def parse_since(text: str) -> float:
    """``7d``, ``12h``, ``2w`` as seconds (ValueError otherwise)."""
    m = _SINCE.match(text)
    if m is None or float(m.group(1)) <= 0:
        raise ValueError(f"--since {text!r}: give a period such as 7d, 12h or 2w")
    return float(m.group(1)) * _UNITS[m.group(2)]


def _local(t: float | None) -> str:
    if t is None or not math.isfinite(t) or t <= 0:
        return ""
    return dt.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M")


def _state(config: Config) -> tuple[dict[str, Any], dict[str, Any], list[str]]:
    """Per loop its state entry with its window (t wall, op, pv), the plant roles, notes."""
    path = config.gateway.state_file
    if not Path(path).exists():
        return {}, {}, [f"no state file {path} yet: no assessments to list"]
    try:
        header, arrays = read_state(path)
    except StateError as exc:
        return {}, {}, [f"state file {path} unusable ({exc}): no assessments to list"]
    scale = config.gateway.time_scale
    out: dict[str, Any] = {}
    for k, bank in enumerate(header["banks"]):
        t = arrays[f"b{k}_t"]
        wall = float(header["saved_wall"]) + (t - float(header["saved_proc"])) / scale
        for c, entry in enumerate(bank["loops"]):
            good = arrays[f"b{k}_q"][:, c] == Quality.GOOD
            op = np.where(good, arrays[f"b{k}_op"][:, c], np.nan).astype(np.float64)
            pv = np.where(good, arrays[f"b{k}_pv"][:, c], np.nan).astype(np.float64)
            out[entry["name"]] = {**entry, "wall": wall, "proc": t, "op": op, "pv": pv}
    saved = _local(float(header["saved_wall"]))
    return out, header.get("plant", {}), [f"state file {path}, saved {saved}"]


def _history(config: Config) -> tuple[dict[str, Any], str]:
    path = verdicts_path(config.gateway.state_file)
    if not path.exists():
        return {}, f"no verdict history {path} yet"
    try:
        return read_history(path, max_loops=2 * len(config.loops) + 1000), \
            f"verdict history {path}"
    except HistoryError as exc:
        return {}, f"verdict history {path} unusable ({exc})"


def _calibration(config: Config) -> str:
    path = calibration_path(config.gateway.state_file)
    if not path.exists():
        return "the confidence is the shipped calibration's (no site calibration file)"
    try:
        _loops, cal, fitted = read_calibration(path, max_loops=2 * len(config.loops) + 1000)
    except CalibrationError as exc:
        return f"site calibration file {path} unusable ({exc})"
    return _calibration_note(cal, fitted)


def _calibration_note(cal: SiteCalibration, fitted: float) -> str:
    when = f", fitted {_local(fitted)}" if fitted else ""
    return f"calibration of the confidence: {cal.name} ({cal.why}{when})"


def _role(plant: dict[str, Any], name: str) -> str:
    entry = plant.get(name)
    if not entry or not entry[0]:
        return ""
    group, role, source = entry
    if role == "source":
        return f"source of plant-wide group {group}"
    return f"follower in group {group}, source {source or 'outside the loops read'}"


def _findings(found: list[LedgerFinding]) -> tuple[Finding, ...]:
    out = []
    for f in sorted(found, key=lambda f: (f.date, f.line)):
        test = ""
        if f.deadband is not None or f.resolution is not None:
            parts = [f"{k} {v:g} % of span" for k, v in (("dead band", f.deadband),
                                                         ("resolution", f.resolution))
                     if v is not None]
            test = ", ".join(parts)
        out.append(Finding(f.date.isoformat(), f.finding, f.fd, f.fs, f.by, f.note, test))
    return tuple(out)


def _changes(entry: dict[str, Any] | None, since: dt.date) -> tuple[tuple[str, str], ...]:
    """The verdict in force when the period began, then each change since."""
    if not entry:
        return ()
    days = [dt.date.fromisoformat(d) for d in entry["days"]]
    pairs = list(zip(days, entry["verdicts"], strict=True))
    before = [p for p in pairs if p[0] <= since]
    kept = [(d.isoformat(), v) for d, v in ([before[-1]] if before else [])
            + [p for p in pairs if p[0] > since]]
    if not kept or kept[-1][1] != entry["verdict"]:  # the latest, within its day
        kept.append((_local(float(entry["t"])), entry["verdict"]))
    return tuple(kept)


def _trend(entry: dict[str, Any], op_range: tuple[float, float]) -> Trend | None:
    """The window the state file holds, on the process's time (seconds from its first
    sample, whose wall time labels it)."""
    wall, proc, op, pv = entry["wall"], entry["proc"], entry["op"], entry["pv"]
    ok = np.isfinite(wall)
    if np.count_nonzero(ok & np.isfinite(op)) < 2:
        return None
    wall, proc, op, pv = wall[ok], proc[ok], op[ok], pv[ok]
    unit = "% of span" if op_range == (0.0, 100.0) else "OP units"
    return Trend(proc - proc[0], op, pv, _local(float(wall[0])), unit, "PV units")


def build_report(config: Config, *, since_s: float, now: float, sections: int = 25
                 ) -> Report:
    """The report of ``config``'s gateway over the ``since_s`` seconds before ``now``."""
    state, plant, notes = _state(config)
    history, said = _history(config)
    notes.append(said)
    read = read_configured(config)
    ledger: dict[str, list[LedgerFinding]] = {}
    for f in (read.findings if read is not None else ()):
        ledger.setdefault(f.loop, []).append(f)
    notes.append("no findings file in the config" if read is None else
                 f"findings {read.source}: {len(read.findings)} finding(s)")
    notes.append(_calibration(config))
    start = dt.datetime.fromtimestamp(now - since_s).date()
    loops, suspects = {}, []
    for lp in config.loops:
        res = (state.get(lp.name) or {}).get("result")
        if res is None:
            continue
        a = Assessment.from_dict(res["assessment"])
        span = None if lp.pv.range is None else lp.pv.range[1] - lp.pv.range[0]
        swing = res.get("pv_swing")
        amplitude = None if swing is None or not span else 100.0 * swing / span
        suspects.append(Suspect(lp.name, str(a.verdict), a.confidence, amplitude,
                                lp.priority))
        loops[lp.name] = (lp, a, res)
    listed = []
    for r in rank(suspects):
        lp, a, res = loops[r.name]
        calibrated = "Calibration: this site's" in a.reason
        listed.append(Listed(
            lp.name, r.rank, r.score, str(a.verdict), a.confidence, a.reason, a.sizes(),
            _local(res.get("since", res.get("judged", res["t"]))), _role(plant, lp.name),
            _findings(ledger.get(lp.name, [])), _changes(history.get(lp.name), start),
            _trend(state[lp.name], lp.op_range), _travel(a),
            "site" if calibrated else "shipped"))
    notes.insert(0, f"{len(listed)} of {len(config.loops)} loop(s) assessed; the period: "
                    f"from {start.isoformat()} to {_local(now)}")
    return Report(f"Valves to check, worst first: {config.gateway.site or config.source}",
                  tuple(listed), tuple(notes), sections,
                  f"stiction-gateway report, {_local(now)}")


def _travel(a: Assessment) -> str:
    if a.position_use is None:
        return ""
    sizes = a.sizes()
    if a.position_use == "used" and sizes is not None and sizes.band is not None:
        return (f"measured from the valve's position: band {sizes.band:.3g}, slip "
                f"{(sizes.slip or 0.0):.3g} ({sizes.unit})")
    note = next((e.note for e in a.evidence if e.test == "travel"), "")
    return f"position read, {a.position_use.replace('_', ' ')}: {note}".rstrip(": ")


def write_report(config: Config, out: str, *, since: str, now: float,
                 sections: int = 25) -> int:
    """Build the report and write it to ``out`` (``-``: stdout); returns the loops listed."""
    try:
        since_s = parse_since(since)
    except ValueError as exc:  # bad usage: exit 2, as a bad config
        raise ConfigError([str(exc)]) from None
    report = build_report(config, since_s=since_s, now=now, sections=sections)
    text = render(report)
    if out == "-":
        sys.stdout.write(text)
    else:
        Path(out).write_text(text, encoding="utf-8")
    return len(report.loops)
