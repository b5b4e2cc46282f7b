"""Reading one large export (issue 38 item 6): `stiction analyze` held about 28 times the file
(23 MB -> 767 MB; a row of text became a list of strings of some 60 bytes each, read and
split whole, then copied column by column). The file is now streamed a chunk of rows at a
time and only its numbers kept: the reading's peak, measured by tracemalloc (numpy's arrays
included), stays within the bytes a row stiction.cli.memory documents, a few times the file."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np

from stiction.cli import historian

ROWS = 100_000


def test_reading_holds_a_few_times_the_file(tmp_path: Path) -> None:
    t = np.arange(ROWS, dtype=float)
    rng = np.random.default_rng(0)
    op = 50.0 + 10.0 * np.sin(t / 40.0) + rng.normal(0.0, 0.1, ROWS)
    pv = 50.0 + 8.0 * np.sin(t / 40.0 - 0.5) + rng.normal(0.0, 0.1, ROWS)
    path = tmp_path / "fic101.csv"
    with path.open("w", newline="") as fh:
        historian.write_export(fh, "FIC101", t, op, pv)  # `stiction simulate --historian`
    size = path.stat().st_size
    tracemalloc.start()
    try:
        table = historian.read_table(path)
        got = historian.read_signals(table, [("FIC101.OP", "--op"), ("FIC101.PV", "--pv")],
                                     None, None)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert got.series[0].size == ROWS and np.nanmax(np.abs(got.series[1] - pv)) < 1e-3
    assert peak < 5 * size, f"{peak / size:.1f} x the file"  # 3.4 x; it was 12 x
    from stiction.cli.memory import READ_BYTES_PER_ROW  # noqa: PLC0415 - new in issue 38

    assert peak / ROWS < 1.2 * READ_BYTES_PER_ROW, f"{peak / ROWS:.0f} bytes a row"
