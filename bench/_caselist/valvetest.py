"""Issue 35's findings about step tests and sizes (items 3 and 4) and issue 38's about the
simulated PLC's step test (item 13, part), as cases: each built the way a new user builds
it, from the product's own simulator (`stiction simulate`, the simulated PLC) and its CLI
on CSV files."""

from __future__ import annotations

import csv
import json
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from _case import REPO, case, cli, run

TMP = Path(tempfile.mkdtemp(prefix="caselist-valvetest-"))
FV101 = ["--scenario", "table4-case1", "--fs", "0.03", "--fd", "0.01", "--k", "1",
         "--noise", "0.02"]  # dead band fs + fd = 4 %, resolution fs - fd = 2 %



def simulated(name: str, *argv: str) -> Path:
    path = TMP / name
    code, _, err = cli("simulate", *argv, "-o", str(path))
    assert code == 0, err
    return path


def edited(src: Path, name: str, pv: Callable[[int, float], float]) -> Path:
    """``src`` with its PV column rewritten, as a user edits it in a spreadsheet."""
    rows = list(csv.reader(src.open()))
    col = [c.lower() for c in rows[0]].index("pv")
    for i, r in enumerate(rows[1:]):
        r[col] = f"{pv(i, float(r[col])):.6f}"
    path = TMP / name
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return path


def valve_test(path: Path, *argv: str) -> dict[str, Any] | str:
    """The JSON report, or what refused it (exit status and the error's last line)."""
    code, out, err = cli("valve-test", str(path), "--op-range", "0", "100", "--json", *argv)
    if code != 0:
        return f"exit {code}: {(err.strip().splitlines() or ['?'])[-1][:90]}"
    got: dict[str, Any] = json.loads(out)
    return got


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def shown(r: dict[str, Any] | str) -> str:
    if isinstance(r, str):
        return r
    lo, hi = r["deadband_bounds"]
    rlo, rhi = r["resolution_bounds"]
    unread = sum(s["moved"] is None for s in r["steps"])
    return (f"dead band {_f(r['deadband'])} ({_f(lo)}..{_f(hi)}), resolution "
            f"{_f(r['resolution'])} ({_f(rlo)}..{_f(rhi)}), "
            f"{sum(s['moved'] is True for s in r['steps'])} moved"
            + (f", {unread} unread" if unread else ""))


def physical(r: dict[str, Any] | str) -> bool:
    """Every figure absent, or >= 0 and inside its bounds (a refusal has no figures)."""
    if isinstance(r, str):
        return True
    for key in ("deadband", "resolution"):
        lo, hi = r[f"{key}_bounds"]
        hi = np.inf if hi is None else hi
        if lo < 0 or (r[key] is not None and not lo <= r[key] <= hi):
            return False
    return r["slip"] is None or r["slip"] >= 0


def near(r: dict[str, Any] | str, key: str, truth: float) -> bool:
    return not isinstance(r, str) and r[key] is not None and \
        abs(r[key] - truth) <= max(0.1 * truth, 0.2)


@case("35.3", "valve-test: a disturbance during one hold (PV +1.5 for 25 s, OP still)")
def disturbance_during_a_hold() -> tuple[str, bool]:
    src = simulated("fv101.csv", *FV101, "--step-test", "60")
    r = valve_test(edited(src, "bumped.csv",
                          lambda i, v: v + (1.5 if 3380 <= i < 3405 else 0.0)))
    said = shown(r) + ("; the hold named" if not isinstance(r, str) and any(
        "disturbance" in n for n in r["notes"]) else "")
    return said, physical(r) and near(r, "deadband", 4.0) and near(r, "resolution", 2.0)


@case("35.3", "valve-test: holds as short as the process lag (12 s holds, lag 12 s)")
def holds_as_short_as_the_lag() -> tuple[str, bool]:
    r = valve_test(simulated("short.csv", *FV101, "--step-test", "12"))
    return shown(r), physical(r) and near(r, "deadband", 4.0) and near(r, "resolution", 2.0)


@case("35.3", "valve-test: a good valve, noisy PV (SD 1 % of span) at 10 s")
def good_valve_noisy_pv_at_10_s() -> tuple[str, bool]:
    r = valve_test(simulated("good10.csv", "--scenario", "table4-case1", "--fs", "0",
                             "--fd", "0", "--k", "1", "--ts", "10", "--noise", "1", "--seed",
                             "1", "--step-test", "60"))
    ok = physical(r) and not isinstance(r, str) and r["deadband_bounds"][0] == 0.0 \
        and r["resolution_bounds"][0] == 0.0
    return shown(r), ok


@case("35.3", "valve-test: a PV frozen at one value while OP steps")
def frozen_pv() -> tuple[str, bool]:
    src = simulated("fv101.csv", *FV101, "--step-test", "60")
    r = valve_test(edited(src, "frozen.csv", lambda i, v: 50.0))
    return shown(r), isinstance(r, str) and "one value" in r


@case("35.3", "valve-test on plc-sim --step-test FIC601 (configs/plc-sim.yaml): PV vs the "
      "valve's position")
def plc_recording_pv_against_position() -> tuple[str, bool]:
    from plcsim.config import parse_sim_config  # noqa: PLC0415
    from plcsim.sim import PlcSim  # noqa: PLC0415

    cfg = yaml.safe_load((REPO / "configs" / "plc-sim.yaml").read_text())
    record = TMP / "fic601.csv"
    cfg.update(listen="127.0.0.1:0", step_test={"loop": "FIC601", "record": str(record)})
    sim = PlcSim(parse_sim_config(cfg))
    player = sim.step_test[2]  # type: ignore[index]
    while not player.done:
        sim.step()
    pv, pos = valve_test(record), valve_test(record, "--position", "position")
    agree = (isinstance(pv, str) and isinstance(pos, str)) or (
        not isinstance(pv, str) and not isinstance(pos, str) and (
            pv["deadband"] == pos["deadband"] or
            abs((pv["deadband"] or np.inf) - (pos["deadband"] or np.inf)) <= 1.0))
    return f"PV: {shown(pv)} | position: {shown(pos)}", physical(pv) and physical(pos) and agree


@case("35.3", "valve-test: an operator's steps, each ramped over 8 s")
def ramped_steps() -> tuple[str, bool]:
    from stiction import HeValve  # noqa: PLC0415
    from stiction.models.simulate import LoopBank, LoopParams  # noqa: PLC0415
    from stiction.valvetest import step_test_levels  # noqa: PLC0415

    bank = LoopBank(1, LoopParams(kc=0.0, tau=12.0, noise_sd=0.02), HeValve(0.03, 0.01, 1.0),
                    seed=1)
    levels = step_test_levels()
    path = TMP / "ramped.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "op", "pv", "vp"])
        for k, level in enumerate(levels):
            before = levels[max(k - 1, 0)]
            for j in range(60):
                u = level if j >= 7 else before + (level - before) * (j + 1) / 8
                out = bank.step(manual=[u / 100.0])
                w.writerow([k * 60 + j, f"{out.op[0]:.4f}", f"{out.pv[0]:.4f}",
                            f"{out.vp[0]:.4f}"])
    pv, pos = valve_test(path), valve_test(path, "--position", "vp")
    ok = physical(pv) and not isinstance(pv, str) and not isinstance(pos, str) and \
        pv["deadband"] is not None and pos["deadband"] is not None and \
        abs(pv["deadband"] - pos["deadband"]) <= 0.3 and 3.5 <= pv["deadband"] <= 5.5
    return f"PV: {shown(pv)} | position: {shown(pos)}", ok


@case("35.3", "valve-test --kp 1: the process gain given is used")
def kp_given() -> tuple[str, bool]:
    r = valve_test(simulated("fv101.csv", *FV101, "--step-test", "60"), "--kp", "1")
    if isinstance(r, str):
        return r, False
    return f"gain {_f(r['gain'])} per % of span; {shown(r)}", r["gain"] == 1.0


@case("35.4", "a sticky level loop analysed with --kp 1, without --process integrating")
def level_read_as_self_regulating() -> tuple[str, bool]:
    path = simulated("lic.csv", "--scenario", "table5-case1", "--noise", "0.02")
    code, out, err = cli("analyze", str(path), "--kp", "1", "--op-range", "0", "100",
                         "--json")
    if code != 0:
        return f"exit {code}: {err.strip()[-90:]}", False
    a = json.loads(out)
    size = a.get("size") or {}
    figures = {k: size.get(k) for k in ("fd", "fs", "jump")}
    over = {k: v for k, v in figures.items() if v is not None and v > 100.0}
    why = a["reason"][a["reason"].find("Size:"):][:150]
    said = (f"{a['verdict']}; fd {_f(figures['fd'])}, fs {_f(figures['fs'])}, jump "
            f"{_f(figures['jump'])} (% of span); {why}")
    named = a["verdict"] != "stiction" or "integrating" in a["reason"]
    return said, not over and named


@case("35.4", "stiction analyze --help: --process has a help text")
def process_help() -> tuple[str, bool]:
    _, out, _ = cli("analyze", "--help")
    text = " ".join(out.split())
    at = text.find("--process {self-regulating,integrating}", text.find("options:"))
    said = text[at:at + 120] if at >= 0 else "no --process option"
    return said, "integrating: PV ramps" in text


@case("38.13", "plc-sim --step-test FIC101 (configs/plc-sim.yaml): a test an operator allows")
def plc_step_test_an_operator_allows() -> tuple[str, bool]:
    from plcsim.config import parse_sim_config  # noqa: PLC0415
    from plcsim.sim import PlcSim  # noqa: PLC0415

    cfg = yaml.safe_load((REPO / "configs" / "plc-sim.yaml").read_text())
    record = TMP / "fic101.csv"
    cfg.update(listen="127.0.0.1:0", step_test={"loop": "FIC101", "start_s": 600,
                                                "record": str(record)})
    sim = PlcSim(parse_sim_config(cfg))
    player = sim.step_test[2]  # type: ignore[index]
    before = 0.0
    while not player.done:
        if sim.steps <= 600:
            before = float(sim.op[0])
        sim.step()
    rows = np.array([[float(x) for x in r] for r in list(csv.reader(record.open()))[1:]])
    op = rows[:, 1]
    steps = np.diff(op)[np.diff(op) != 0]
    first = int(np.flatnonzero(np.diff(op))[0]) + 1
    said = (f"{steps.size} steps of {np.abs(steps).min():.2g}..{np.abs(steps).max():.2g} % "
            f"over {rows[-1, 0] - rows[0, 0] + 1:.0f} s, OP {op.min():.1f}..{op.max():.1f} "
            f"from {before:.1f} (bump {op[0] - before:+.2f}), first step after {first} s")
    ok = (steps.size <= 30 and np.abs(steps).max() <= 2.0 + 1e-6
          and np.abs(op - before).max() <= 5.0 and abs(op[0] - before) < 0.01
          and first >= 60)
    return said, ok


if __name__ == "__main__":
    run(sys.argv[1:])
