"""`stiction simulate` and `stiction signature` from the command line."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stiction.cli import main
from stiction.models.signature import pressure_ramp, valve_signature


def test_simulate_writes_csv_with_the_documented_columns(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "loop.csv"
    assert main(["simulate", "--scenario", "table6", "--tau", "450", "--noise", "0.1",
                 "--seed", "3", "--duration", "600", "-o", str(out)]) == 0
    assert "wrote 600 samples" in capsys.readouterr().out
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", "sp", "op", "pv", "vp"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (600, 5)
    np.testing.assert_array_equal(data[:, 0], np.arange(600.0))
    assert data[:, 2].min() >= 0.0 and data[:, 2].max() <= 100.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "nope"], "--scenario: `scenario` is unknown: 'nope'"),
        (["--scenario", "table6", "--fs", "-0.1"], "--fs: `fs` must be >= 0, was -0.1"),
        (["--scenario", "table6", "--fd", "0.5"], "--fd: `fd` must not exceed fs"),
        (["--scenario", "table6", "--ts", "0"], "--ts: `ts` must be > 0, was 0.0"),
        (["--scenario", "table6", "--ts", "-1"], "--ts: `ts` must be > 0, was -1.0"),
        (["--scenario", "table6", "--noise", "-1"], "--noise: `noise` must be >= 0"),
        (["--scenario", "table6", "--tau", "abc"], "argument --tau: invalid float value"),
    ],
)
def test_simulate_bad_arguments_exit_2_naming_the_argument(
    tmp_path: Path, capsys, args: list[str], message: str  # type: ignore[no-untyped-def]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["simulate", *args, "-o", str(tmp_path / "x.csv")])
    assert info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


def test_simulate_unwritable_output_exits_2(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SystemExit) as info:
        main(["simulate", "--scenario", "healthy", "--duration", "10",
              "-o", str(tmp_path / "missing-dir" / "x.csv")])
    assert info.value.code == 2
    assert "cannot write" in capsys.readouterr().err


def test_console_script_runs(tmp_path: Path) -> None:
    out = tmp_path / "a.csv"
    proc = subprocess.run(
        [sys.executable, "-m", "stiction.cli", "simulate", "--scenario", "table4-case2",
         "--duration", "100", "-o", str(out)], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().startswith("t,sp,op,pv,vp")


def test_pressure_ramp_is_the_paper_input() -> None:
    p = pressure_ramp()
    assert p[0] == 0.0 and p.max() == pytest.approx(12.0)
    np.testing.assert_allclose(np.abs(np.diff(p)), 0.02, atol=1e-9)


def test_physical_and_semiphysical_signatures_overlap() -> None:
    """Paper Figure 2b. Tolerance proven: 1e-4 of travel at every sample (we measure
    about 1e-7: the Stribeck term's effect on the slip length is tiny, and both models
    slip at the same sample)."""
    sig = valve_signature()
    assert sig.k == pytest.approx(1.99, abs=0.005)
    slips_p = np.flatnonzero(np.abs(np.diff(sig.x_physical)) > 1e-6)
    slips_s = np.flatnonzero(np.abs(np.diff(sig.x_semiphysical)) > 1e-6)
    assert len(slips_p) >= 10
    np.testing.assert_array_equal(slips_p, slips_s)
    assert sig.max_abs_difference < 1e-4
    # the signature is a stiction signature: stuck stretches between jumps
    assert np.mean(np.diff(sig.x_physical) == 0) > 0.9


def test_signature_command_reports_and_plots(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pytest.importorskip("matplotlib")
    png = tmp_path / "sig.png"
    assert main(["signature", "--plot", str(png), "--csv", str(tmp_path / "s.csv")]) == 0
    out = capsys.readouterr().out
    assert "fs 0.3202, fd 0.2668, K 1.9907" in out
    assert "max |x_physical - x_semiphysical|" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
