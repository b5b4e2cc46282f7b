"""Issue 38's findings about the offline CLI (items 5 to 11), as cases: each file built the
way a new user builds it, from the product's own simulator (`stiction simulate`, its
`--historian` export), rewritten as another historian or a spreadsheet writes it, and read
by the CLI as a user runs it."""

from __future__ import annotations

import csv
import datetime as dt
import json
import os
import sys
import tempfile
import time
import tracemalloc
import zoneinfo
from pathlib import Path
from typing import Any

from _case import case, cli, run

TMP = Path(tempfile.mkdtemp(prefix="caselist-cli-"))
START = dt.datetime(2024, 3, 1, 6, 0, 0)
TAGS = ["--op", "FIC101.OP", "--pv", "FIC101.PV"]



def refused(err: str) -> str:
    return "exit 2: " + err.strip().splitlines()[-1][17:117] if err.strip() else "exit 2"


def simulated(name: str, *argv: str) -> list[list[str]]:
    """`stiction simulate ARGV -o NAME`'s rows (the header first)."""
    path = TMP / name
    code, _, err = cli("simulate", *argv, "-o", str(path))
    assert code == 0, err
    with path.open(newline="") as fh:
        return list(csv.reader(fh))


def written(name: str, rows: list[list[str]], sep: str = ",") -> Path:
    path = TMP / name
    with path.open("w", newline="") as fh:
        csv.writer(fh, delimiter=sep).writerows(rows)
    return path


def stamp(seconds: float, start: dt.datetime = START) -> str:
    return (start + dt.timedelta(seconds=seconds)).strftime("%Y-%m-%d %H:%M:%S")


def analysed(*argv: str) -> dict[str, Any] | str:
    code, out, err = cli("analyze", *argv, "--json")
    return json.loads(out) if code == 0 else refused(err)


def sticky() -> list[list[str]]:
    """A sticky flow loop, an hour at 1 s: t, sp, op, pv, vp."""
    return simulated("sticky.csv", "--scenario", "table4-case2", "--noise", "0.02",
                     "--duration", "3600", "--seed", "4")


@case("38.5", "a ';' export with '.' decimals, every number with three decimals (44.000): "
              "read (exit 0, a verdict), as the release before read it")
def semicolon_export_with_decimal_points() -> tuple[str, bool]:
    rows = sticky()
    out = [["Timestamp", "FIC101.OP", "FIC101.PV"]]
    out += [[stamp(float(r[0])), f"{float(r[2]):.3f}", f"{float(r[3]):.3f}"] for r in rows[1:]]
    got = analysed(str(written("outsider.csv", out, ";")), *TAGS)
    if isinstance(got, str):
        return got, False
    return f"exit 0, {got['verdict']} {got['confidence']:.2f}", True


@case("38.5", "stiction plant on 30 loops x 7,200 rows of three-decimal numbers: each "
              "column's decimal mark told once (cells judged one by one: none), seconds")
def wide_three_decimal_plant() -> tuple[str, bool]:
    import numpy as np  # noqa: PLC0415

    from stiction.cli import decimals  # noqa: PLC0415

    rng = np.random.default_rng(0)
    header = ["t"] + [f"L{k}.{s}" for k in range(30) for s in ("OP", "PV")]
    body = [[str(i), *(f"{x:.3f}" for x in 50.0 + 20.0 * np.sin(i / 60.0 + np.arange(60))
                       + rng.normal(0.0, 0.5, 60))] for i in range(7200)]
    path = written("wide.csv", [header, *body])
    judged = []
    real = decimals.kind
    decimals.kind = lambda c: judged.append(c) or real(c)  # type: ignore[assignment]
    t0 = time.perf_counter()
    code, _, err = cli("plant", str(path), "--json")
    seconds = time.perf_counter() - t0
    decimals.kind = real
    said = f"exit {code} in {seconds:.1f} s, cells judged one by one: {len(judged):,}"
    return said if code == 0 else f"{said}; {refused(err)}", code == 0 and len(judged) < 60


@case("38.6", "reading a `stiction simulate --historian` export of 100,000 rows: peak memory "
              "a few times the file (it held 28 x with the analysis, 12 x reading alone)")
def reading_memory() -> tuple[str, bool]:
    import numpy as np  # noqa: PLC0415

    from stiction.cli import historian  # noqa: PLC0415

    t = np.arange(100_000, dtype=float)
    path = TMP / "long.csv"
    with path.open("w", newline="") as fh:
        historian.write_export(fh, "FIC101", t, 50 + 10 * np.sin(t / 40), 50 + 8 * np.cos(t / 40))
    tracemalloc.start()
    table = historian.read_table(path)
    historian.read_signals(table, [("FIC101.OP", "--op"), ("FIC101.PV", "--pv")], None, None)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    ratio = peak / path.stat().st_size
    return f"peak {peak / 1e6:.1f} MB, {ratio:.1f} x the file, {peak / t.size:.0f} B/row", \
        ratio < 5


@case("38.7", "--csv of a manifest row '=HYPERLINK(...)': written as text, not a live formula")
def csv_formula_cell() -> tuple[str, bool]:
    formula = '=HYPERLINK("http://example.com","x")'
    (TMP / "loops.csv").write_text(f'file\n"{formula.replace(chr(34), chr(34) * 2)}"\n')
    out = TMP / "unit.csv"
    os.chdir(TMP)  # the manifest's folder '.': its cell starts the file's label
    cli("analyze", "--manifest", "loops.csv", "--csv", str(out))
    with out.open(encoding="utf-8-sig", newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    cell = row["file"]
    return f"file cell {cell[:40]!r}", not cell.startswith(("=", "+", "-", "@"))


@case("38.8", "no_stiction's explanation (the demo's advice, the one text in the code) "
              "does not clear the valve, as docs/accuracy.md measures")
def no_stiction_explained() -> tuple[str, bool]:
    from plcsim.demo import VERDICT_ADVICE  # noqa: PLC0415

    said = VERDICT_ADVICE["no_stiction"]
    clears = any(w in said for w in ("not the valve", "not the suspect"))
    return said[:110], "does not clear the valve" in said and not clears


@case("38.9", "PI export in Berlin local time across the spring change, no --tz: the hour "
              "skipped is named, with --tz")
def spring_change_named() -> tuple[str, bool]:
    rows = sticky()
    berlin = zoneinfo.ZoneInfo("Europe/Berlin")
    start = dt.datetime(2024, 3, 31, 0, 30, tzinfo=dt.UTC)
    out = [["Time", "FIC101.OP", "FIC101.PV"]]
    out += [[(start + dt.timedelta(seconds=float(r[0]))).astimezone(berlin).strftime(
        "%d-%b-%Y %H:%M:%S"), r[2], r[3]] for r in rows[1:]]
    got = analysed(str(written("spring.csv", out)), *TAGS)
    if isinstance(got, str):
        return got, False
    named = any("skip an hour" in w and "--tz" in w for w in got["warnings"])
    return f"{got['verdict']}: {got['reason'][:90]}", named


@case("38.9", "Ignition's t_stamp (Unix ms) and PI DataLink's empty first header: the time "
              "column found without --time")
def time_column_names() -> tuple[str, bool]:
    rows = sticky()
    said, ok = [], True
    for name, header, cell in (
            ("ignition.csv", "t_stamp", lambda t: str(1_709_272_800_000 + round(1000 * t))),
            ("datalink.csv", "", lambda t: (START + dt.timedelta(seconds=t)).strftime(
                "%d-%b-%Y %H:%M:%S"))):
        out = [[header, "FIC101.OP", "FIC101.PV"]]
        out += [[cell(float(r[0])), r[2], r[3]] for r in rows[1:]]
        got = analysed(str(written(name, out)), *TAGS)
        said.append(f"{name}: {got if isinstance(got, str) else got['verdict']}")
        ok = ok and not isinstance(got, str)
    return "; ".join(said), ok


@case("38.9", "a manifest's tz column per file (two sites' local time)")
def manifest_tz() -> tuple[str, bool]:
    manifest = TMP / "sites.csv"
    manifest.write_text("file,tz\nsticky.csv,Europe/Berlin\n")
    sticky()
    code, out, err = cli("analyze", "--manifest", str(manifest), "--json")
    if code != 0:
        return refused(err), False
    (got,) = json.loads(out)
    return (got.get("error") or got["verdict"])[:110], "error" not in got


@case("38.10", "a PHD export, PV 0 at Confidence 0 for 30 minutes: those samples gaps, as "
               "the same stretch written 'Bad'")
def phd_confidence() -> tuple[str, bool]:
    rows = simulated("sticky4h.csv", "--scenario", "table4-case2", "--noise", "0.02",
                     "--duration", "14400", "--seed", "4")
    phd = [["Timestamp", "FIC101.OP", "FIC101.PV", "Confidence"]]
    bad = [["Timestamp", "FIC101.OP", "FIC101.PV"]]
    for i, r in enumerate(rows[1:]):
        lost = 5400 <= i < 7200
        phd.append([stamp(float(r[0])), r[2], "0" if lost else r[3], "0" if lost else "100"])
        bad.append([stamp(float(r[0])), r[2], "Bad" if lost else r[3]])
    a, b = analysed(str(written("phd.csv", phd)), *TAGS), \
        analysed(str(written("bad.csv", bad)), *TAGS)
    if isinstance(a, str) or isinstance(b, str):
        return f"{a if isinstance(a, str) else a['verdict']}", False
    return f"Confidence: {a['verdict']} ({a['reason'][:50]}); Bad: {b['verdict']}", \
        (a["verdict"], a["reason"]) == (b["verdict"], b["reason"])


@case("38.10", "a long export (DateTime,TagName,Value as Wonderware writes it): read, one "
               "column per tag")
def long_export() -> tuple[str, bool]:
    rows = sticky()
    out = [["DateTime", "TagName", "Value"]]
    for r in rows[1:]:
        out += [[stamp(float(r[0])), "FIC101.OP", r[2]], [stamp(float(r[0])), "FIC101.PV", r[3]]]
    got = analysed(str(written("long.csv", out)), *TAGS)
    return (got if isinstance(got, str) else f"exit 0, {got['verdict']}"), \
        not isinstance(got, str)


@case("38.11", "the batch table piped (no terminal): the reason whole, its caveat "
               "'sample faster' kept")
def table_not_cut() -> tuple[str, bool]:
    rows = simulated("dist.csv", "--scenario", "disturbance", "--dist-period", "300",
                     "--noise", "0.05", "--duration", "28800", "--seed", "1")
    path = written("a-long-folder-name-of-a-plant-share-FIC4711-feed.csv",
                   [["t", "op", "pv"], *([r[0], r[2], r[3]] for r in rows[1::60])])
    _, out, _ = cli("analyze", str(path), str(path))
    # (the file's cell, after a rank column where the tree ranks the batch: issue 39)
    line = next(ln[ln.index(str(path)):] for ln in out.splitlines()
                if str(path) in ln and ln.split(str(path))[0].strip() in ("", "1", "2"))
    return line[len(str(path)):][:120], line.endswith("sample faster.")


@case("38.11", "a week's export: its period in seconds (not 7.568e+04); --every 1d: one "
               "verdict per day")
def week_by_day() -> tuple[str, bool]:
    rows = sticky()
    out = [["Timestamp", "FIC101.OP", "FIC101.PV"]]  # the hour, as if sampled every 168 s
    out += [[stamp(168.0 * float(r[0])), r[2], r[3]] for r in rows[1:]]
    path = written("week.csv", out, ";")
    _, text, _ = cli("analyze", str(path), *TAGS)
    period = next((ln.strip() for ln in text.splitlines() if "period_s" in ln), "no period")
    code, days, err = cli("analyze", str(path), *TAGS, "--every", "1d", "--json")
    if code != 0:
        return f"{period}; --every: {refused(err)}", False
    got = json.loads(days)
    return f"{period}; --every 1d: {len(got)} verdicts", "e+" not in period and len(got) == 7


if __name__ == "__main__":
    run(sys.argv[1:])
