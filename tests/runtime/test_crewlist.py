"""The list worst first and the site's calibration in the running gateway (issue 39): the
gateway's own scheduler, crew list, findings book, result server, metrics and calibration
file, driven by hand (memory devices, a fake clock); the fake analysis reads the confidence
of stiction off the OP's swing (tests/support/confidence_fake_analyze.py)."""

from __future__ import annotations

import datetime as dt
import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
import yaml
from gateway_helpers import run
from memory_harness import FakeTime, Harness, mconfig, mloop

from gateway.cli import main
from gateway.config import parse_config
from gateway.core.findings import FindingsBook
from gateway.core.sitecal import SiteBook
from gateway.inputs.memory import memory_device
from gateway.outputs.prometheus.site import SiteCollector
from gateway.outputs.sitecal import CalibrationFile
from gateway.outputs.statefile import StateFile
from gateway.outputs.verdicts import VerdictFile
from gateway.runtime.crewlist import CrewList
from gateway.runtime.findings import load_findings, observe, read_configured
from gateway.runtime.scheduler import AnalysisScheduler
from gateway.wire.results import decode_block

CONF = "confidence_fake_analyze:analyze"
W0 = 1_772_344_800.0  # 2026-03-01 06:00:00 UTC


def _rows(swings: list[float], pv_swing: list[float] | None = None) -> list[list[float]]:
    """100 rows: per loop an OP square wave of peak-to-peak ``swing`` (period 10) and a PV
    of peak-to-peak ``pv_swing`` around 50."""
    pvs = pv_swing or [0.0] * len(swings)
    out = []
    for k in range(100):
        sign = 1.0 if k % 10 < 5 else -1.0
        row: list[float] = []
        for a, b in zip(swings, pvs, strict=True):
            row += [50.0 + sign * a / 2, 50.0 + sign * b / 2]
        out.append(row)
    return out


def _raw(tmp: Path, swings: list[float], names: list[str], *, findings: str | None = None,
         extra: dict[str, dict[str, Any]] | None = None, pv_swing: list[float] | None = None,
         **analysis: Any) -> dict[str, Any]:
    loops = [mloop(n, "plc", 2 * k, 32 * k, **(extra or {}).get(n, {}))
             for k, n in enumerate(names)]
    raw = mconfig([memory_device("plc", _rows(swings, pv_swing), poll_interval_s=0.05,
                                 repeat=True)], loops, state_file=str(tmp / "gw.state"))
    raw["modbus_server"]["block_registers"] = 32
    if findings is not None:
        raw["findings"] = findings
    if analysis:
        raw["analysis"] = analysis
    return raw


class Site:
    """A harness with the gateway's list and calibration wired as Gateway wires them."""

    def __init__(self, raw: dict[str, Any], time: FakeTime | None = None) -> None:
        self.h = Harness(parse_config(raw, "gw.yaml"), time=time or FakeTime(wall=W0))
        self.book = observe(self.h.store, FindingsBook())
        self.crew = CrewList(SiteBook(self.h.config.analysis), self.book,
                             wall=lambda: self.h.time.wall)
        self.h.registry.register(SiteCollector(self.crew.site))
        self.sched = AnalysisScheduler(self.h.runtime.groups, self.h.store,
                                       interval_wall_s=1e9, analyze=CONF, hooks=self.crew,
                                       plant=self.h.config.plant,  # off, as mconfig says
                                       executor=lambda: ThreadPoolExecutor(1))
        self.file = CalibrationFile(self.h.runtime.binding(), self.crew.site,
                                    wall=lambda: self.h.time.wall)

    async def start(self) -> None:
        today = dt.datetime.fromtimestamp(self.h.time.wall).date()
        load_findings(self.book, read_configured(self.h.config, today))
        await self.file.start()
        await self.sched.start()
        await self.crew.start(self.h.store, self.h.config)

    async def round(self) -> None:
        await self.h.tick(220)
        await self.sched.run_round(now=lambda: self.h.time.wall)
        await self.crew.refit()

    async def stop(self) -> None:
        await self.sched.stop()
        await self.file.stop()

    def verdict(self, loop: str) -> str:
        return self.h.store.verdict_name(self.h.store.index[loop])


def test_the_list_ranks_by_confidence_cost_and_priority(tmp_path: Path) -> None:
    """A: 0.95, its PV cycling +-9 % of its range (weight 3); B: 0.99, no PV range (1); C:
    0.60, priority 3; D: 0.20. Published in the metrics and the extended block's +25/+26."""
    names = ["B", "D", "A", "C"]
    raw = _raw(tmp_path, [39.6, 8.0, 38.0, 24.0], names, pv_swing=[1.0, 1.0, 18.0, 1.0],
               extra={"A": {"pv": {"column": 5, "range": [0.0, 100.0]}},
                      "C": {"priority": 3}})

    async def go() -> Site:
        s = Site(raw)
        await s.start()
        await s.round()
        await s.stop()
        return s

    s = run(go())
    h = s.h
    order = {n: h.metric("stiction_loop_rank", loop=n) for n in names}
    assert order == {"A": 1.0, "C": 2.0, "B": 3.0, "D": 4.0}
    assert h.metric("stiction_loop_suspicion", loop="A") == pytest.approx(0.95 * 3, rel=0.02)
    assert h.metric("stiction_loop_suspicion", loop="C") == pytest.approx(1.8, rel=0.02)
    block = decode_block(h.registers()[64:96])  # A's extended block
    assert block["rank"] == 1 and block["suspicion"] == pytest.approx(2.85, rel=0.02)
    assert block["reserved"] == 0
    assert h.metric("stiction_loop_verdict_since_timestamp_seconds", loop="A") == h.time.wall
    # no findings file: the reasons say nothing of a calibration, the state is "off"
    assert "Calibration" not in h.store.results[0].assessment.reason
    assert h.metric("stiction_site_calibration", state="off") == 1.0


SITE = ["S1", "S2", "S3", "S4", "S5", "S6", "G1", "G2", "G3", "G4", "G5", "G6", "X1", "X2"]
SWINGS = [39.6] * 6 + [36.0] * 6 + [36.4, 39.4]  # 0.99 sticky, 0.90 fine, 0.91 and 0.985


def _ledger(tmp: Path, rows: list[tuple[str, str]]) -> str:
    day = dt.datetime.fromtimestamp(W0).date().isoformat()
    path = tmp / "findings.csv"
    path.write_text("loop,date,finding\n" + "".join(f"{n},{day},{f}\n" for n, f in rows))
    return str(path)


def test_findings_teach_the_site_and_its_fit_survives_a_restart(tmp_path: Path) -> None:
    """Six valves found sticking (0.99), six found fine though called (0.90): the site's
    calibration withdraws the call of a valve like the fine ones (X1, 0.91) and keeps the
    one like the sticky (X2, 0.985); the metrics say so; after a restart the fit is in force
    from the calibration file, before any round."""
    found = [(n, "stiction") for n in SITE[:6]] + [(n, "ok") for n in SITE[6:12]]
    raw = _raw(tmp_path, SWINGS, SITE, findings=_ledger(tmp_path, found))

    async def first() -> Site:
        s = Site(raw)
        await s.start()
        assert s.crew.site.view.state == "too_few"  # no confidence on the findings' day yet
        await s.round()  # records the confidences, fits, judged before the fit
        await s.round()  # judged with it
        await s.stop()
        return s

    s = run(first())
    h, view = s.h, s.crew.site.view
    assert view.state == "site" and view.calibration.findings == 12
    # (published at once: the confidence moved by more than the hysteresis' margin)
    assert s.verdict("X1") == "no_stiction" and s.verdict("X2") == "stiction"
    x1 = h.store.results[h.store.index["X1"]].assessment
    assert x1.reason.startswith("not stiction at this site: the analysis said stiction at "
                                "confidence 0.91")
    assert x1.fd is None and x1.confidence < 0.4
    assert "Calibration: this site's, from 12 findings" in \
        h.store.results[h.store.index["X2"]].assessment.reason
    assert h.metric("stiction_site_calibration", state="site") == 1.0
    assert h.metric("stiction_site_findings_used") == 12.0
    assert h.metric("stiction_site_precision", calibration="shipped") == pytest.approx(0.5)
    assert h.metric("stiction_site_precision", calibration="site") == 1.0
    assert h.metric("stiction_site_recall", calibration="site") == 1.0
    # the loops called by the shipped calibration but found fine rank below the sticky
    assert h.metric("stiction_loop_rank", loop="G1") > h.metric("stiction_loop_rank",
                                                                 loop="X2")

    async def restart() -> Site:
        again = Site(raw, time=h.time)
        again.h.time.advance(5.0)
        await again.file.start()  # the calibration file, as the gateway's sink loads it
        return again

    again = run(restart())
    assert again.crew.site.view.calibration == view.calibration
    assert again.crew.site.view.state == "site"
    assert again.crew.site.history.on("S1", dt.datetime.fromtimestamp(W0).date()) == \
        pytest.approx(0.99)


def test_a_contradicting_or_small_ledger_or_turning_it_off_keeps_the_shipped_one(
        tmp_path: Path) -> None:
    contradicting = [(n, "ok") for n in SITE[:6]] + [(n, "stiction") for n in SITE[6:12]]
    for sub in "abc":
        (tmp_path / sub).mkdir()
    cases = {"contradictory": (_ledger(tmp_path / "a", contradicting), {}),
             "too_few": (_ledger(tmp_path / "b", [("S1", "stiction"), ("G1", "ok")]), {}),
             "off": (_ledger(tmp_path / "c", contradicting), {"site_calibration": False})}
    for state, (ledger, analysis) in cases.items():
        raw = _raw(tmp_path, SWINGS, SITE, findings=ledger, **analysis)

        async def go(raw: dict[str, Any] = raw) -> Site:
            s = Site(raw)
            await s.start()
            await s.round()
            await s.round()
            await s.stop()
            return s

        s = run(go())
        assert s.crew.site.view.state == state
        assert s.verdict("X1") == "stiction"  # the shipped calibration's call stands
        reason = s.h.store.results[s.h.store.index["X1"]].assessment.reason
        if state == "off":
            assert "Calibration" not in reason
        else:
            assert f"Calibration: shipped ({s.crew.site.view.calibration.why})" in reason
            assert reason.endswith(").")
        assert s.h.metric("stiction_site_calibration", state=state) == 1.0


def test_the_report_lists_what_the_gateway_keeps(tmp_path: Path) -> None:
    """`stiction-gateway report` from the state file, the verdict history, the calibration
    file and the findings a running gateway keeps: its list in the gateway's order, the
    site's calibration named, each suspect's section with its findings and its plots."""
    found = [(n, "stiction") for n in SITE[:6]] + [(n, "ok") for n in SITE[6:12]]
    raw = _raw(tmp_path, SWINGS, SITE, findings=_ledger(tmp_path, found))

    async def go() -> Site:
        s = Site(raw)
        await s.start()
        await s.round()
        await s.round()
        await s.stop()  # the calibration file written
        binding = s.h.runtime.binding()
        await StateFile(binding, wall=lambda: s.h.time.wall).save(final=True)
        await VerdictFile(binding, s.book, wall=lambda: s.h.time.wall).save()
        return s

    s = run(go())
    (tmp_path / "gw.yaml").write_text(yaml.safe_dump(raw))
    out = tmp_path / "report.html"
    assert main(["report", "--config", str(tmp_path / "gw.yaml"), "--since", "2w",
                 "-o", str(out)]) == 0
    page = out.read_text()
    listed = re.findall(r"<tr><td class='num'>(\d+)</td><td>(?:<a [^>]*>)?([^<]*)", page)
    ranks = {n: int(s.h.store.rank[s.h.store.index[n]]) for n in SITE}
    assert [name for _r, name in listed] == sorted(SITE, key=ranks.__getitem__)
    assert "calibration of the confidence: site (fitted on 6 sticky and 6 not sticky" in page
    assert page.count("<section class='valve'") == 7  # S1-S6 and X2 are called
    assert "The crew found it sticking on" in page and page.count("<img ") == 14
    assert "(site calibration)" in page
    code = main(["report", "--config", str(tmp_path / "gw.yaml"), "--since", "7 days",
                 "-o", str(out)])
    assert code == 2  # a period it cannot read: bad usage, said


def test_a_calibration_file_that_cannot_be_used_is_set_aside(tmp_path: Path) -> None:
    raw = _raw(tmp_path, SWINGS[:2], SITE[:2])
    (tmp_path / "gw.calibration").write_text('{"format": "stiction-gateway-calibration"}')

    async def go() -> Site:
        s = Site(raw)
        await s.start()
        await s.stop()
        return s

    s = run(go())
    assert s.file.set_aside is not None and s.file.set_aside.name.startswith(
        "gw.calibration.foreign-")
    assert (tmp_path / "gw.calibration").exists()  # written afresh at stop
