"""What `stiction plant` prints: the groups and every loop's verdict as text (with headers
and a legend), as JSON (every evidence with its figure), and the spectral map."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._assessment import Assessment
from ..plant import Group, PlantAssessment
from ..plant.source import MemberEvidence
from ..plant.spectra import spectra
from ._common import pyplot

__all__ = ["LEGEND", "as_json", "print_text", "spectral_map", "text_lines"]

LEGEND = (
    "confidence: the per-loop analysis' confidence that the loop's own valve sticks (0-1; "
    "stiction from 0.87). role: source (its cycle starts there) or follower (it carries a "
    "cycle from elsewhere; called stiction alone, it reads propagated); kept: called "
    "stiction, in a group whose evidence does not overturn its call; '-' in no group.")
RANKING_HEADER = ("loop", "score", "own verdict", "valve", "Granger", "NLI", "lag s")
RANKING_LEGEND = (
    "score: the rank (higher: likelier the source); own verdict: the per-loop analysis; "
    "valve: how much more of PV a sticky valve explains than a linear one, with stuck "
    "intervals and stick-slip episodes; Granger: net flow of the cycle from this loop to "
    "the others (positive: it leads); NLI: nonlinearity index of its cycle (above 1: "
    "nonlinear; highest at the source); lag s: its cycle's lag behind the source's.")


def _fmt(x: float | None, spec: str) -> str:
    """``x`` formatted, "-" when None; never "-0"."""
    if x is None:
        return "-"
    text = format(x, spec)
    return format(0.0, spec) if float(text) == 0 else text


def _evidence(e: MemberEvidence) -> dict[str, Any]:
    return {"loop": e.loop, "score": round(e.score, 4), "verdict": e.verdict,
            "confidence": e.confidence, "valve_gain": e.valve_gain, "valve": round(e.valve, 4),
            "kano": e.kano, "episodes": e.episodes, "granger_flow": e.flow, "nli": e.nli,
            "lag_s": e.lag_s, "harmonics": round(e.harmonics, 4), "strength": e.strength,
            "signal": e.signal}


def as_json(view: PlantAssessment, after: dict[str, Assessment], notes: list[str]
            ) -> dict[str, Any]:
    """``groups`` (each with ``loops``, ``indicators``, ``period_s``, ``source``,
    ``named_by``, ``entry``, ``source_ranking`` with every evidence's figure, ``marginal``:
    the signals that may carry its cycle but not clearly, with their share; ``kept``: the
    loops called ``stiction`` whose call stands, with why; ``upstream``: an indicator that
    leads the cycle while a loop is its source) and ``loops``
    (each with ``loop``, ``verdict``, ``confidence``, ``group``, ``role``, ``reason``)."""
    return {
        "groups": [{
            "group": g.number, "period_s": g.period_s, "unit": g.unit, "loops": list(g.loops),
            "indicators": [m.name for m in g.members if m.kind == "indicator"],
            "strength": {m.name: round(m.strength, 4) for m in g.members},
            "marginal": {m.name: round(m.strength, 4) for m in g.marginal},
            "source": g.source, "also_sources": list(g.also_sources),
            "named_by": list(g.named_by), "entry": g.entry, "external": g.external,
            "reason": g.reason, "followers_called_stiction": dict(g.demoted),
            "kept": dict(g.kept), "upstream": g.upstream,
            "source_ranking": [_evidence(e) for e in g.ranking],
            "indicator_evidence": [{"name": i.name, "strength": i.strength,
                                    "granger_flow": i.flow, "nli": i.nli}
                                   for i in g.indicators],
        } for g in view.groups],
        "loops": [{"loop": tag, "verdict": str(a.verdict), "confidence": a.confidence,
                   "group": view.roles[tag].group, "role": view.roles[tag].role,
                   "reason": a.reason} for tag, a in after.items()],
        "left_out": dict(view.left_out),
        "warnings": notes,
    }


def _group_text(g: Group) -> list[str]:
    loops = [m for m in g.members if m.kind == "loop"]
    inds = [m for m in g.members if m.kind != "loop"]
    count = f"{len(loops)} loop{'s' if len(loops) != 1 else ''}" + \
        (f" and {len(inds)} indicator{'s' if len(inds) != 1 else ''}" if inds else "")
    if g.source is not None:
        where = f"source {g.source} (named by {', '.join(g.named_by)})" + (
            f", also fed from outside? (indicator {g.upstream} leads it)" if g.upstream else "")
    elif g.entry is not None:
        where = f"enters from outside (indicator {g.entry} leads it)"
    else:
        where = "no loop shows evidence of being its source"
    unit = f", unit {g.unit}" if g.unit else ""
    out = [f"group {g.number}: period {g.period_s:.0f} s{unit}, {count}, {where}",
           "  loops: " + ", ".join(f"{m.name} {m.strength:.0%}" for m in loops)]
    if inds:
        out.append("  indicators: " + ", ".join(f"{m.name} {m.strength:.0%}" for m in inds))
    if g.marginal:
        out.append("  in the margin (may carry it, not clearly: no role): " + ", ".join(
            f"{m.name} {m.strength:.0%}" for m in g.marginal))
    out.append("  (each member's share of its power in the cycle's band)")
    out.append("  source ranking:")
    rows = [RANKING_HEADER] + [(
        e.loop, f"{e.score:.2f}",
        "-" if e.verdict is None else f"{e.verdict} {_fmt(e.confidence, '.2f')}",
        f"{e.valve:.2f}", _fmt(e.flow, "+.2f"), _fmt(e.nli, ".1f"), _fmt(e.lag_s, ".0f"))
        for e in g.ranking]
    widths = [max(len(r[k]) for r in rows) for k in range(len(RANKING_HEADER))]
    out += ["    " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in rows]
    out.append(f"  {g.reason}")
    return out


def print_text(view: PlantAssessment, after: dict[str, Assessment], notes: list[str]) -> None:
    print("\n".join(text_lines(view, after, notes)))


def text_lines(view: PlantAssessment, after: dict[str, Assessment], notes: list[str]
               ) -> list[str]:
    """The text report's lines: the groups, then the loop table (its header first)."""
    out = [] if view.groups else ["no oscillation shared by two loops or more"]
    for g in view.groups:
        out += _group_text(g)
    if view.groups:
        out.append(f"({RANKING_LEGEND})")
    out.append("")
    rows = [("loop", "verdict", "confidence", "plant role", "reason")]
    for tag, a in after.items():
        role = view.roles[tag]
        place = "-" if not role.group else f"group {role.group} {role.role or 'kept'}"
        rows.append((tag, str(a.verdict), _fmt(a.confidence, ".2f"), place, a.reason))
    widths = [max(len(r[k]) for r in rows) for k in range(4)]
    out += ["  ".join(c.ljust(w) for c, w in zip(r[:4], widths, strict=True)) + "  " + r[4]
            for r in rows]
    out.append(f"({LEGEND})")
    out += [f"left out of the plant view: {name}: {why}" for name, why in view.left_out.items()]
    return out + [f"warning: {n}" for n in notes]


def spectral_map(path: Path, ts: float, loops: dict[str, tuple[np.ndarray, np.ndarray]],
                 view: PlantAssessment) -> list[str]:
    """Loops x period, each loop's OP and PV power (normalised, log scale, with its colour
    scale); each group's period a dashed line with its number and source, its members
    dotted, its source ringed. Returns the labels drawn (the colour scale's first)."""
    names = list(loops)
    rows = np.array([s for tag in names for s in loops[tag]])
    spec = spectra(np.nan_to_num(rows - np.nanmean(rows, axis=1, keepdims=True)))
    power = spec.power[0::2] + spec.power[1::2]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 0.4 * len(names) + 2.5))
    period = 1.0 / np.maximum(spec.freqs, 1e-12) * ts
    mesh = ax.pcolormesh(period[::-1], np.arange(len(names)),
                         np.log10(power[:, ::-1] / 2.0 + 1e-6), shading="nearest",
                         cmap="viridis")
    bar = fig.colorbar(mesh, ax=ax, pad=0.01)
    bar.set_label("share of the loop's power (log10)")
    drawn = [bar.ax.get_ylabel()]
    ax.set_xscale("log")
    ax.set_yticks(np.arange(len(names)), names)
    ax.set_xlabel("period, s")
    for g in view.groups:
        ax.axvline(g.period_s, color="w", lw=1, ls="--")
        rows_in = [names.index(m) for m in g.loops if m in names]
        ax.scatter([g.period_s] * len(rows_in), rows_in, color="w", marker="o", s=30,
                   edgecolors="k", zorder=3)
        for src in (g.source, *g.also_sources):
            if src in names:
                ax.scatter([g.period_s], [names.index(src)], facecolors="none",
                           edgecolors="r", marker="o", s=160, linewidths=2, zorder=4)
        label = f" group {g.number}: " + (f"source {g.source}" if g.source else
                                          f"from outside ({g.entry})" if g.entry else
                                          "no loop source")
        drawn.append(label.strip())
        ax.text(g.period_s, len(names) - 0.5 - 0.35 * (g.number % 2), label, color="w",
                fontsize=8, va="top", bbox={"facecolor": "k", "alpha": 0.6, "pad": 1.5,
                                            "edgecolor": "none"})
    ax.set_title("each loop's OP and PV power by period; dots: a group's members, red "
                 "ring: its source", pad=12)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return drawn
