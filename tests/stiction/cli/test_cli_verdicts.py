"""`stiction analyze` says what it cannot see (issue 32 items 4 and 5): what weighed in the
decision beside the tests' votes, a stuck valve with OP travelling, an export whose cycling
comes in bursts with the stretch to analyse named in the file's own time, and --from/--to
that analyse it."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np
import pytest
from detector_fixtures import cached_sim, write_loop_csv

from stiction import Verdict, analyze
from stiction.cli import main
from stiction.scenarios import scenario, simulate

START = dt.datetime(2024, 3, 1, 6, 0, 0)


def _export(path: Path, op: np.ndarray, pv: np.ndarray, ts: float) -> Path:
    """A historian's export: ';'-separated, day-first date-times, decimal commas."""
    with path.open("w") as fh:
        fh.write("Timestamp;OP;PV\n")
        for i in range(op.size):
            stamp = (START + dt.timedelta(seconds=ts * i)).strftime("%d.%m.%Y %H:%M:%S")
            fh.write(f"{stamp};{op[i]:.4f};{pv[i]:.4f}\n".replace(".", ",").replace(
                stamp.replace(".", ","), stamp))
    return path


def _bursts() -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """8 h of a good valve under a slow random load, with a sticky valve's cycling in six
    bursts of 15-33 min (table4-case2's valve), joined level to level; 1 s samples."""
    rng = np.random.default_rng(1)
    parts, bursts, t, k = [], [], 0, 0
    while t < 28800:
        quiet, burst = int(rng.uniform(2400, 4800)), int(rng.uniform(900, 2000))
        for name, dur in (("healthy", quiet), ("table4-case2", burst)):
            r = simulate(scenario(name, load_sd=0.02, load_tau=600.0), noise=0.1, seed=k,
                         duration=dur + 600)
            parts.append((r.op[600:], r.pv[600:]))
            k += 1
        bursts.append((t + quiet, t + quiet + burst))
        t += quiet + burst
    op, pv = [parts[0][0]], [parts[0][1]]
    for o, p in parts[1:]:
        op.append(o - o[0] + op[-1][-1])
        pv.append(p - p[0] + pv[-1][-1])
    return np.concatenate(op)[:28800], np.concatenate(pv)[:28800], bursts


def test_what_weighed_is_printed_apart_from_the_votes(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_loop_csv(tmp_path)
    assert main(["analyze", str(path), "--op-range", "0", "100", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["stretch"] is None
    weighed = got["weighed"]
    # every test of the learned decision, by its name (the shape network and the decision's
    # own probability are evidence beside it, not its entries)
    assert set(weighed) >= {e["test"] for e in got["evidence"]} - {"shape_net", "decision"}
    assert list(weighed) == sorted(weighed, key=lambda k: -abs(weighed[k]))
    assert main(["analyze", str(path), "--op-range", "0", "100"]) == 0
    out = capsys.readouterr().out
    assert ("  weighed in the decision (part of its log-odds, + for stiction; not votes):"
            in out)
    assert out.index("evidence (test, value, vote") < out.index("weighed in the decision")


def test_a_valve_stuck_while_op_travels_is_evidence_not_calm() -> None:
    """Issue 32 item 5: a valve stuck while OP ramps 55 -> 50 % and PV shows only its noise
    read `not_oscillating, confidence 0.05` (here 0.03 on main): the Table 6 loop with a
    sticky valve (fs 8 %), between two slips."""
    r = cached_sim("table6", 0.05, 2, fs=0.08, fd=0.07, duration=7200.0)
    op, pv = r.op[1000:3000], r.pv[1000:3000]
    assert op[0] == pytest.approx(55.8, abs=0.3) and op[-1] == pytest.approx(50.0, abs=0.3)
    a = analyze(op, pv, ts=1.0, op_range=(0.0, 100.0))
    assert a.verdict == Verdict.VALVE_NOT_RESPONDING, a.reason
    assert a.reason.startswith("valve not responding: OP travelled 6% of its span while PV "
                               "held within its noise (SD 0.05")
    assert "or a load that OP followed exactly" in a.reason
    b = analyze(op, pv, ts=1.0)  # no span: OP units
    assert b.verdict == Verdict.VALVE_NOT_RESPONDING
    assert "(OP units; give op_range for % of span)" in b.reason


def test_a_load_step_taken_up_by_op_is_not_a_stuck_valve() -> None:
    """OP's quick move and rest taking up a load step (a good valve) is not a ramp against
    a constant error: the loop stays calm."""
    r = cached_sim("healthy", 0.05, 2, dist_amp=0.0, load_sd=0.0, duration=7200.0)
    op, pv = r.op[2000:6000].copy(), r.pv[2000:6000]
    op[1000:] += 8.0 * (1 - np.exp(-np.arange(3000) / 60.0))  # OP takes up a load step
    assert analyze(op, pv, ts=1.0, op_range=(0.0, 100.0)).verdict == Verdict.NOT_OSCILLATING


@pytest.fixture(scope="module")
def bursts_csv(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[int, int]]]:
    op, pv, bursts = _bursts()
    path = _export(tmp_path_factory.mktemp("bursts") / "8h.csv", op[::10], pv[::10], 10.0)
    return path, bursts


def test_bursts_of_cycling_name_a_stretch_in_the_files_time(
        bursts_csv: tuple[Path, list[tuple[int, int]]],
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 32 item 5: an 8 h export with bursts of cycling (regularity 0.2-0.3 over the
    whole) gave no hint to analyse a stretch. Now it names one, in the file's time, with the
    --from/--to to pass back; the stretch holds a burst."""
    path, bursts = bursts_csv
    assert main(["analyze", str(path), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    st = got["stretch"]
    assert st is not None, got["reason"]
    assert "The cycling comes in bursts:" in got["reason"]
    start = (dt.datetime.strptime(st["from"], "%d.%m.%Y %H:%M:%S") - START).total_seconds()
    stop = (dt.datetime.strptime(st["to"], "%d.%m.%Y %H:%M:%S") - START).total_seconds()
    assert stop - start <= 0.8 * 28800
    assert any(start <= b0 and b1 <= stop + 10 for b0, b1 in bursts), (start, stop, bursts)
    assert st["period_s"] == pytest.approx(260.0, rel=0.2)  # the sticky valve's cycle
    assert main(["analyze", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"  hint: analyse {st['from']} to {st['to']} alone: --from '{st['from']}' --to " \
           f"'{st['to']}'" in out


def test_from_and_to_analyse_a_stretch(bursts_csv: tuple[Path, list[tuple[int, int]]],
                                       capsys: pytest.CaptureFixture[str]) -> None:
    path, bursts = bursts_csv
    b0, b1 = bursts[0]
    first, last = (START + dt.timedelta(seconds=10 * (s // 10))
                   for s in (b0 + 10, b1 - 10))
    args = ["analyze", str(path), "--from", first.strftime("%d.%m.%Y %H:%M:%S"),
            "--to", last.strftime("%d.%m.%Y %H:%M:%S"), "--op-range", "0", "100", "--json"]
    assert main(args) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["verdict"] == "stiction", got["reason"]  # the burst alone: the sticky valve
    assert got["period_s"] == pytest.approx(230.0, rel=0.2)
    with pytest.raises(SystemExit) as info:
        main(["analyze", str(path), "--from", "01.03.2024 25:00:00"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--from '01.03.2024 25:00:00': not a time as the file writes them (e.g. " \
           "'01.03.2024 06:00:00')" in err
    with pytest.raises(SystemExit):
        main(["analyze", str(path), "--from", "02.03.2024 06:00:00"])
    assert "--from/--to: 0 samples between them (the file runs from '01.03.2024 06:00:00' " \
           "to '01.03.2024 13:59:50')" in capsys.readouterr().err
