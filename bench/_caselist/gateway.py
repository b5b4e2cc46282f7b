"""Issue 35's and 38's findings about the gateway, as cases (each one of the tree under
test: a state file, a findings file, a held verdict, a reload, as the gateway handles them;
the stiction analysis replaced by a stand-in where its answer is not the point)."""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import io
import logging
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from _case import REPO, case, run

# (bench/caselist.py runs this file with -P: its folder is not first on sys.path, where its
# own name would stand for the gateway package under test)

FAKE = '''
import numpy as np
from stiction import Assessment, Verdict

def analyze(op, pv, *, ts, **_):
    if float(np.ptp(op[-300:])) > 10.0:
        return Assessment(Verdict.STICTION, "fake: OP swings", oscillating=True)
    return Assessment(Verdict.NOT_OSCILLATING, "fake: OP still")
'''
SWING = [[50.0 + (15.0 if k % 10 < 5 else -15.0), 20.0, 50.0, 20.0] for k in range(100)]


@contextlib.contextmanager
def _folder() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="case-gw-") as tmp:
        (Path(tmp) / "casefake.py").write_text(FAKE)
        sys.path.insert(0, tmp)
        yield Path(tmp)


def _raw(folder: Path, columns: tuple[int, int] = (0, 1), window_s: float = 10.0,
         position: bool = False) -> dict[str, Any]:
    loop: dict[str, Any] = {"name": "A", "device": "plc", "op": {"column": columns[0]},
                            "pv": {"column": columns[1]}, "window_s": window_s,
                            "result_address": 0}
    if position:
        loop["position"] = {"column": 2}
    return {"gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                        "state_file": str(folder / "gw.state")},
            "metrics": {"listen": "127.0.0.1:0"}, "modbus_server": {"listen": "127.0.0.1:0"},
            "plant": {"enabled": False},
            "devices": [{"name": "plc", "protocol": "memory", "poll_interval_s": 0.05,
                         "timeout_s": 1.0, "values": SWING, "repeat": True}],
            "loops": [loop]}


class _Box:
    """A runtime polled by hand on a fake clock (what the tests' harness does)."""

    def __init__(self, raw: dict[str, Any], wall: float, old: Any = None) -> None:
        from gateway.config import parse_config  # noqa: PLC0415 - the tree under test
        from gateway.runtime.poller import Clocks  # noqa: PLC0415
        from gateway.runtime.reload import build_runtime  # noqa: PLC0415

        self.wall = wall
        self.config = parse_config(raw, "gw.yaml")
        self.rt = build_runtime(self.config, old.rt if old else None, wall=wall,
                                clocks=Clocks(mono=lambda: self.wall, wall=lambda: self.wall,
                                              perf=lambda: self.wall))

    async def tick(self, n: int) -> None:
        for _ in range(n):
            for p in self.rt.pollers:
                await p.tick()
            self.wall += 0.05

    async def round(self, sched: Any) -> Any:
        await sched.run_round(now=lambda: self.wall)
        return self.rt.store.results[0]


def _scheduler(box: _Box) -> Any:
    from gateway.runtime.scheduler import AnalysisScheduler  # noqa: PLC0415

    return AnalysisScheduler(box.rt.groups, box.rt.store, interval_wall_s=1e9,
                             analyze="casefake:analyze", executor=lambda: ThreadPoolExecutor(1))


@case("35.5", "restarts every 3 s, a 10 s window: 'last judged' is the judgement's; the hold "
              "ends after one window")
def held_verdict_age() -> tuple[str, bool]:
    from gateway.outputs.statefile import StateFile  # noqa: PLC0415

    async def go(folder: Path) -> list[Any]:
        box = _Box(_raw(folder), 1_772_344_789.0)
        await box.tick(220)
        sched = _scheduler(box)
        await sched.start()
        out = [await box.round(sched)]
        await sched.stop()
        await StateFile(box.rt.binding(), wall=lambda: box.wall).save(final=True)
        for _ in range(5):
            box = _Box(_raw(folder), box.wall + 1.0)
            sink = StateFile(box.rt.binding(), wall=lambda b=box: b.wall)
            await sink.start()
            await box.tick(40)
            sched = _scheduler(box)
            await sched.start()
            out.append(await box.round(sched))
            await sched.stop()
            await sink.stop()
        return out

    with _folder() as folder:
        rounds = asyncio.run(go(folder))
    judged = time.strftime("%H:%M:%S", time.gmtime(rounds[0].t))
    second = rounds[2].assessment.reason
    said = second[second.find("last judged"):][:31] if "last judged" in second else second[:40]
    last = str(rounds[-1].assessment.verdict)
    return (f"judged {judged}; restart 2: {said}; after 15 s: {last}",
            f"last judged 2026-03-01 {judged}" in second and last == "warming_up")


@case("35.5", "a loop's OP/PV addresses corrected by a reload: the old verdict is not held")
def corrected_addresses_start_fresh() -> tuple[str, bool]:
    async def go(folder: Path) -> list[Any]:
        box = _Box(_raw(folder), 1_772_344_800.0)
        await box.tick(220)
        sched = _scheduler(box)
        await sched.start()
        out = [await box.round(sched)]
        new = _Box(_raw(folder, columns=(2, 3)), box.wall, old=box)
        sched.reconfigure(new.rt.groups, new.rt.store, new.config)
        for _ in range(2):
            await new.tick(20)
            out.append(await new.round(sched))
        await sched.stop()
        return out

    with _folder() as folder:
        rounds = asyncio.run(go(folder))
    after = rounds[-1].assessment
    return (f"before: {rounds[0].assessment.verdict}; after: {after.verdict}: "
            f"{after.reason[:40]}", not after.reason.startswith("held"))


def _written_state(folder: Path, window_s: float = 10.0, fill: bool = False) -> Any:
    from gateway.outputs.statefile.format import snapshot, write_state  # noqa: PLC0415

    async def go() -> _Box:
        box = _Box(_raw(folder, window_s=window_s), 1_772_344_800.0)
        await box.tick(40)
        return box

    box = asyncio.run(go())
    if fill:
        bank = box.rt.groups[0].bank
        bank.op[:] = np.random.default_rng(1).normal(50, 5, bank.op.shape)
        bank.quality[:] = 0
        bank.t[:] = box.wall - 0.05 * np.arange(bank.size)[::-1]
        bank.count, bank.head = bank.size, 0
    header, arrays = snapshot(box.config, box.rt.groups, box.rt.store, wall=box.wall,
                              proc=box.wall, clean=True)
    write_state(folder / "gw.state", header, arrays)
    return box


@case("35.7", "a state file of a config without positions, read by the release before "
              "state file version 2 (a downgrade)")
def downgrade_reads_the_state() -> tuple[str, bool]:
    with _folder() as folder:
        _written_state(folder)
        archive = subprocess.run(["git", "-C", str(REPO), "archive", "dfc6edc^", "gateway",
                                  "stiction"], capture_output=True, check=True)
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(folder / "previous", filter="data")
        code = ("import sys\nfrom gateway.outputs.statefile.format import read_state\n"
                "print(read_state(sys.argv[1])[0]['version'])")
        out = subprocess.run([sys.executable, "-c", code, str(folder / "gw.state")],
                             capture_output=True, text=True, cwd=folder / "previous",
                             env={"PYTHONPATH": str(folder / "previous")}, check=False)
    said = (f"read: version {out.stdout.strip()}" if out.returncode == 0 else
            (out.stderr.strip().splitlines() or ["?"])[-1][-90:])
    return said, out.returncode == 0


@case("35.7", "window_s shortened 150,000 s -> 5,000 s: the state file (over the new "
              "bound) restores trimmed")
def shorter_window_restores() -> tuple[str, bool]:
    from gateway.outputs.statefile import StateFile  # noqa: PLC0415

    with _folder() as folder:
        first = _written_state(folder, window_s=150_000.0, fill=True)
        size = (folder / "gw.state").stat().st_size
        box = _Box(_raw(folder, window_s=5_000.0), first.wall + 1.0)
        sink = StateFile(box.rt.binding(), wall=lambda: box.wall)
        asyncio.run(sink.start())
        report = sink.report
    rows = box.rt.groups[0].bank.count
    aside = report.set_aside is not None if report is not None else True
    return (f"{size / 1e6:.0f} MB file: {'set aside' if aside else 'read'}, "
            f"{rows:,} samples restored", not aside and rows == 100_000)


def _ledger(text: bytes) -> Any:
    from gateway.config.findings import read_findings  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "f.csv"
        p.write_bytes(text)
        return read_findings(p, ["FIC101", "TIC301"], today=dt.date(2024, 3, 10))


@case("35.8", "crew rows as Excel saves them: a note over two lines, sep=;, Windows-1252, "
              "a trailing empty column")
def crew_rows_as_excel_saves_them() -> tuple[str, bool]:
    files = {
        "multi-line": b'loop,date,finding,note\nFIC101,2024-03-05,stiction,"packing\n'
                      b'tightened"\nTIC301,2024-03-07,ok,\n',
        "sep=;": b"sep=;\nloop;date;finding\nFIC101;05.03.2024;ok\nTIC301;05.03.2024;ok\n",
        "cp1252": "loop;date;finding;by\nFIC101;05.03.2024;ok;Müller\nTIC301;05.03.2024;ok;"
                  "\n".encode("cp1252"),
        "trailing ,": b"loop,date,finding,\nFIC101,2024-03-05,ok,\nTIC301,2024-03-05,ok,\n"}
    got = {name: _ledger(data) for name, data in files.items()}
    said = ", ".join(f"{n}: {len(g.findings)}/2" for n, g in got.items())
    return said, all(len(g.findings) == 2 and not g.problems for g in got.values())


@case("38.1", "a findings row dated 0001-01-01, east of UTC: the /metrics page renders")
def no_date_row_and_the_scrape() -> tuple[str, bool]:
    os.environ["TZ"] = "Europe/Berlin"
    time.tzset()
    from prometheus_client import CollectorRegistry  # noqa: PLC0415
    from prometheus_client.exposition import generate_latest  # noqa: PLC0415

    from gateway.core.findings import FindingsBook  # noqa: PLC0415
    from gateway.core.store import ResultStore  # noqa: PLC0415
    from gateway.outputs.prometheus import StoreCollector  # noqa: PLC0415

    read = _ledger(b"loop,date,finding\nFIC101,0001-01-01,stiction\nTIC301,01.01.0001,ok\n")
    book = FindingsBook()
    book.apply(read)
    registry = CollectorRegistry()
    registry.register(StoreCollector(ResultStore(["FIC101", "TIC301"]), book))
    try:
        generate_latest(registry)
    except Exception as exc:  # the scrape's 500
        return f"{len(read.findings)} row(s) taken; scrape: {type(exc).__name__}: {exc}", False
    return f"{len(read.findings)} row(s) taken, {len(read.problems)} refused; scrape ok", True


@case("38.2", "300 loops' first verdicts with 900 findings: comparisons made (linear: ~900)")
def findings_view_cost() -> tuple[str, bool]:
    from gateway.config.findings import Finding, FindingsFile  # noqa: PLC0415
    from gateway.core.findings import FindingsBook, VerdictHistory  # noqa: PLC0415

    class Counting(VerdictHistory):
        calls = 0

        def verdict_on(self, loop: str, date: dt.date) -> str:
            self.calls += 1
            return super().verdict_on(loop, date)

    history = Counting()
    book = FindingsBook(history)
    day = dt.date.today() - dt.timedelta(days=3)
    book.apply(FindingsFile("f.csv", tuple(Finding(f"L{k % 300}", day, "stiction", line=k)
                                           for k in range(900))))
    history.calls = 0
    for k in range(300):
        book.record(f"L{k}", time.time(), "stiction")
    return f"{history.calls:,} comparisons", history.calls <= 2 * 900


@case("38.3", "a FIFO as the findings file: check-config answers (30 s)")
def fifo_findings_check_config() -> tuple[str, bool]:
    with _folder() as folder:
        os.mkfifo(folder / "findings.csv")
        raw = _raw(folder)
        raw["findings"] = "findings.csv"
        (folder / "gw.yaml").write_text(yaml.safe_dump(raw))
        try:
            out = subprocess.run([sys.executable, "-m", "gateway.cli", "check-config",
                                  str(folder / "gw.yaml")], capture_output=True, text=True,
                                 timeout=30, check=False)
        except subprocess.TimeoutExpired:
            return "no answer in 30 s (hung on the FIFO)", False
    return f"exit {out.returncode}: {out.stderr.strip()[-70:]}", out.returncode == 0


@case("38.4", "a bank with one position: check-config's count against the windows allocated "
              "and a state write's peak")
def memory_count() -> tuple[str, bool]:
    import tracemalloc  # noqa: PLC0415

    from gateway.config.checks import window_bytes  # noqa: PLC0415
    from gateway.outputs.statefile.format import snapshot, write_state  # noqa: PLC0415

    with _folder() as folder:
        raw = _raw(folder, window_s=5_000.0, position=True)
        raw["loops"] += [{**raw["loops"][0], "name": f"B{k}", "result_address": 20 * (k + 1),
                          "position": None} for k in range(39)]
        for loop in raw["loops"][1:]:
            del loop["position"]
        box = _Box(raw, 1_772_344_800.0)
        banks = sum(g.bank.nbytes for g in box.rt.groups)
        bank = box.rt.groups[0].bank
        bank.count, bank.head = bank.size, 7
        tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        write_state(folder / "gw.state", *snapshot(box.config, box.rt.groups, box.rt.store,
                                                   wall=box.wall, proc=box.wall))
        peak = tracemalloc.get_traced_memory()[1] - before
        tracemalloc.stop()
    counted = window_bytes(box.config)
    return (f"windows {banks / 2**20:.1f} MiB, counted {counted / 2**20:.1f} MiB; a write "
            f"copies {peak / banks:.1f}x the windows",
            counted == banks and peak <= 1.2 * banks)


@case("38.12", "stiction-gateway findings: a sticking valve found before any verdict")
def findings_cli_without_a_verdict() -> tuple[str, bool]:
    from gateway.cli import main  # noqa: PLC0415

    with _folder() as folder:
        raw = _raw(folder)
        raw["findings"] = "findings.csv"
        (folder / "gw.yaml").write_text(yaml.safe_dump(raw))
        (folder / "findings.csv").write_text("loop,date,finding\nA,2024-03-05,stiction\n")
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            main(["findings", "--config", str(folder / "gw.yaml")])
    line = next((ln for ln in out.getvalue().splitlines() if "valves the gateway had" in ln),
                "")
    said = line[line.find("sticking valves"):][:90]
    return said, "0 of 1" not in line


@case("38.13", "loops reordered by a reload: register +19's new numbering is said")
def reorder_is_said() -> tuple[str, bool]:
    from gateway.runtime.gateway import Gateway  # noqa: PLC0415

    records: list[str] = []
    handler = logging.Handler()
    handler.emit = lambda r: records.append(r.getMessage())  # type: ignore[method-assign]
    logging.getLogger("gateway").addHandler(handler)
    logging.getLogger("gateway").setLevel(logging.INFO)

    def raw(folder: Path, names: list[str]) -> Any:
        from gateway.config import parse_config  # noqa: PLC0415

        r = _raw(folder)
        r["loops"] = [{**r["loops"][0], "name": n, "result_address": 20 * k}
                      for k, n in enumerate(names)]
        return parse_config(r, "gw.yaml")

    async def go(folder: Path) -> None:
        async with Gateway(raw(folder, ["A", "B", "C"]), serve_http=False,
                           executor=lambda: ThreadPoolExecutor(1)) as gw:
            await gw.reload(raw(folder, ["A", "C", "B"]))

    with _folder() as folder:
        asyncio.run(go(folder))
    said = next((r for r in records if "+19" in r), "")
    return said[:100] or "nothing said of the new order", bool(said)


if __name__ == "__main__":
    run(sys.argv[1:])
