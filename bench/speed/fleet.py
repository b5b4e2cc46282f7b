"""Benchmark (issue 17): a fleet writing to one VictoriaMetrics, every part real.

One plant's tag list of G x M loops on G simulated PLCs (``stiction-gateway plc-sim``) is
split by ``stiction-gateway shard --gateways G`` into G gateway configs; each gateway
(``stiction-gateway run``) has its own Prometheus in agent mode (the shipped
deploy/fleet/site files) scraping it every 15 s and remote-writing to one VictoriaMetrics
(the shipped deploy/fleet/central ARGS). Default: 3 gateways x 2,000 loops for 300 s.
``BENCH_QUICK=1`` (or ``--quick``) runs 60 s; ``BENCH_FLEET_SECONDS=S`` sets the duration.

At the end every agent is reloaded with no target (the gateways' series get their stale
markers, no scrape follows) and drained, then the books are closed:

* scraped: samples the agents appended (``prometheus_agent_samples_appended_total``, the
  gateways' series plus ``up`` and the scrape_* series, stale markers included);
* sent, failed, dropped: the agents' remote-write counters;
* received: rows VictoriaMetrics took over remote write
  (``vm_rows_inserted_total{type="promremotewrite"}``); lost = scraped - received;
* queryable: samples a query finds (``count_over_time`` over the run; stale markers are
  not samples to a query);
* ingestion rate: received / duration; disk: the data directory after a flush, split into
  the index (per series: VictoriaMetrics indexes each series once per day) and the data
  (per sample), giving the bytes one loop costs per day at 15 s scrapes. A 5-minute run
  compresses worse than a long one (short series, unmerged parts): an upper bound.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import yaml

from bench._net import free_port, wait_port
from bench._servers import (
    SITE_DEFAULT,
    Prometheus,
    VictoriaMetrics,
    default_args,
    keyed,
    scrape_value,
    site_agent_config,
    tool,
    with_flags,
)
from bench.speed._scale import SCENARIO_MIX, cpu_seconds, rss_bytes

GATEWAYS, LOOPS = 3, 2000
SCRAPE_S = 15.0  # the shipped scrape_interval
SITE = "bench-plant"
DAY_S = 86400.0


def duration(argv: list[str] | None = None) -> float:
    argv = sys.argv[1:] if argv is None else argv
    fixed = os.environ.get("BENCH_FLEET_SECONDS")
    if fixed:
        return float(fixed)
    return 60.0 if "--quick" in argv or os.environ.get("BENCH_QUICK") else 300.0


@dataclasses.dataclass
class GatewayRun:
    name: str
    loops: int
    scraped: float = 0.0  # samples the agent appended
    sent: float = 0.0
    failed: float = 0.0
    dropped: float = 0.0
    pending: float = 0.0
    series: float = 0.0  # active series in the agent
    scrapes: float = 0.0
    gateway_cpu_s: float = 0.0
    agent_cpu_s: float = 0.0
    agent_rss: float = 0.0


@dataclasses.dataclass
class FleetResult:
    gateways: list[GatewayRun]
    duration_s: float
    scrape_s: float
    received: float
    queryable: float
    data_bytes: int
    index_bytes: int
    vm_cpu_s: float
    vm_rss: float

    @property
    def loops(self) -> int:
        return sum(g.loops for g in self.gateways)

    @property
    def scraped(self) -> float:
        return sum(g.scraped for g in self.gateways)

    @property
    def lost(self) -> float:
        return self.scraped - self.received

    @property
    def series(self) -> float:
        return sum(g.series for g in self.gateways)

    @property
    def rate(self) -> float:
        return self.received / self.duration_s

    def per_loop_day_bytes(self) -> float:
        """Disk one loop costs per day at the scrape interval: its share of the samples at
        this run's bytes per sample, plus its series' index entries (once per day)."""
        per_sample = self.data_bytes / max(self.received, 1)
        series_per_loop = self.series / self.loops
        samples = series_per_loop * DAY_S / self.scrape_s
        return per_sample * samples + self.index_bytes / self.loops


def _tag_list(work: Path, sims: list[Path], ports: list[int], loops: int) -> tuple[Path, Path]:
    """One plant's tag list (every PLC's loops) and the base config with the PLCs."""
    rows = []
    for k, sim_path in enumerate(sims):
        sim = yaml.safe_load(sim_path.read_text())
        for i, lp in enumerate(sim["loops"]):
            integrating = lp["scenario"] in ("table5-case1", "table5-case2")
            rows.append({"name": lp["name"], "device": f"plc{k + 1}", "op": 4 * i,
                         "pv": 4 * i + 2, "type": "float32",
                         "process": "integrating" if integrating else "self-regulating",
                         "window_s": 300})
    tags = work / "plant.csv"
    with tags.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    base = {
        "gateway": {"analysis_interval_s": 150, "site": SITE, "analysis_workers": 1},
        "devices": [{"name": f"plc{k + 1}", "protocol": "modbus", "host": "127.0.0.1",
                     "port": ports[k]} for k in range(len(sims))],
    }
    (work / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    return tags, work / "base.yaml"


def _start(cmd: list[str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as f:
        return subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT)


@contextlib.contextmanager
def _processes() -> Iterator[list[subprocess.Popen[bytes]]]:
    procs: list[subprocess.Popen[bytes]] = []
    try:
        yield procs
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def _sample_counts(agent: Prometheus, run: GatewayRun) -> None:
    text = agent.get("/metrics")
    run.scraped = scrape_value(text, "prometheus_agent_samples_appended_total")
    run.sent = scrape_value(text, "prometheus_remote_storage_samples_total")
    run.failed = scrape_value(text, "prometheus_remote_storage_samples_failed_total")
    run.dropped = scrape_value(text, "prometheus_remote_storage_samples_dropped_total")
    run.pending = scrape_value(text, "prometheus_remote_storage_samples_pending")


def run_fleet(gateways: int = GATEWAYS, loops: int = LOOPS, *, seconds: float = 300.0,
              scrape_s: float = SCRAPE_S, work: Path | None = None) -> FleetResult:
    """Run the fleet (see the module docstring) and return its books."""
    from gateway.config.shard import shard_tags  # noqa: PLC0415

    tmp = tempfile.TemporaryDirectory(prefix="bench-fleet-") if work is None else None
    work = Path(tmp.name) if tmp is not None else work
    assert work is not None
    py = [sys.executable, "-m", "gateway.cli"]
    with _processes() as procs, contextlib.ExitStack() as stack:
        vm = stack.enter_context(VictoriaMetrics(work / "vm"))
        sims, ports = [], []
        for k in range(gateways):
            port = free_port()
            sim = {"listen": f"127.0.0.1:{port}", "ts": 1.0, "seed": k, "loops": [
                {"name": f"S{k + 1}L{i:04d}", "scenario": SCENARIO_MIX[i % len(SCENARIO_MIX)],
                 "noise": 0.05} for i in range(loops)]}
            path = work / f"plc-sim-{k + 1}.yaml"
            path.write_text(yaml.safe_dump(sim, sort_keys=False))
            procs.append(_start([*py, "plc-sim", "--config", str(path)],
                                work / f"plc-sim-{k + 1}.log"))
            wait_port(port, 60)  # listening before the next free port is picked
            sims.append(path)
            ports.append(port)
        tags, base = _tag_list(work, sims, ports, loops)
        shards, _ = shard_tags(tags, gateways, base, name="edge")
        runs, agents, gw_procs = [], [], []
        for s in shards:
            (work / s.csv_name).write_text(s.csv_text)
            cfg = yaml.safe_load(s.yaml_text)
            metrics_port = free_port()
            cfg["metrics"] = {"listen": f"127.0.0.1:{metrics_port}"}
            cfg["modbus_server"] = {"listen": f"127.0.0.1:{free_port()}"}
            cfg["gateway"]["state_file"] = str(work / f"{s.yaml_name}.state")
            (work / s.yaml_name).write_text(yaml.safe_dump(cfg, sort_keys=False))
            gw = _start([*py, "run", "--config", str(work / s.yaml_name)],
                        work / f"{s.yaml_name}.log")
            procs.append(gw)
            gw_procs.append(gw)
            wait_port(metrics_port, 60)
            name = s.yaml_name.removesuffix(".yaml")
            agent_cfg = site_agent_config(
                site=SITE, area=None, instance=name, target=f"127.0.0.1:{metrics_port}",
                remote_write=vm.write_url, scrape_interval=f"{scrape_s:g}s",
                batch_send_deadline="5s")
            args = with_flags(default_args(SITE_DEFAULT), **{"storage.agent.path": None,
                                                             "web.listen-address": None})
            agents.append(stack.enter_context(
                Prometheus(work / name, agent_cfg, agent=True, args=args)))
            runs.append(GatewayRun(name, s.loops))
        t0 = time.time()
        cpu0 = [cpu_seconds(p.pid) for p in gw_procs]
        vm_cpu0 = vm.metric("process_cpu_seconds_total")
        time.sleep(seconds)
        # close the books: no target any more (stale markers, no further scrape), drain
        for agent in agents:
            cfg = yaml.safe_load(agent.config_path.read_text())
            cfg["scrape_configs"] = []
            agent.config_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
            assert agent.proc is not None
            agent.proc.send_signal(signal.SIGHUP)
        elapsed = time.time() - t0
        for run, gw, c0 in zip(runs, gw_procs, cpu0, strict=True):
            run.gateway_cpu_s = cpu_seconds(gw.pid) - c0
        deadline = time.monotonic() + 120
        for agent, run in zip(agents, runs, strict=True):
            while True:
                _sample_counts(agent, run)
                if (run.sent + run.failed + run.dropped >= run.scraped and not run.pending) \
                        or time.monotonic() > deadline:
                    break
                time.sleep(1)
            assert agent.proc is not None
            run.agent_cpu_s = agent.metric("process_cpu_seconds_total")
            run.agent_rss = rss_bytes(agent.proc.pid)[0]
            run.series = agent.metric("prometheus_agent_active_series")
        vm.force_flush()
        time.sleep(2)
        received = vm.metric("vm_rows_inserted_total", type="promremotewrite")
        scrapes = keyed(vm.values(f'count_over_time(up{{job="stiction-gateway"}}'
                                  f'[{int(elapsed) + 60}s])'), "instance")
        series = keyed(vm.values(f'count by (instance) (last_over_time({{job="stiction-gateway"'
                                 f'}}[{int(elapsed) + 60}s]))'), "instance")
        queryable = sum(vm.values(f'sum(count_over_time({{job="stiction-gateway"}}'
                                  f'[{int(elapsed) + 60}s]))').values())
        for run in runs:
            run.scrapes = scrapes.get((run.name,), 0.0)
            run.series = series.get((run.name,), run.series)
        sizes = _data_sizes(vm)
        return FleetResult(runs, elapsed, scrape_s, received, queryable,
                           sizes["data"], sizes["index"],
                           vm.metric("process_cpu_seconds_total") - vm_cpu0,
                           rss_bytes(vm.proc.pid)[0] if vm.proc else 0.0)


def _data_sizes(vm: VictoriaMetrics) -> dict[str, int]:
    """Bytes on disk under the store's data and index directories."""
    def du(path: Path) -> int:
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())

    root = vm.data_path
    return {"data": du(root / "data"), "index": du(root / "indexdb")}


def print_result(r: FleetResult) -> None:
    print(f"{'gateway':<8} {'loops':>6} {'series':>7} {'scrapes':>7} {'scraped':>10} "
          f"{'sent':>10} {'failed':>6} {'dropped':>7} {'GW CPU%':>7} {'agent CPU%':>10} "
          f"{'agent MiB':>9}")
    for g in r.gateways:
        print(f"{g.name:<8} {g.loops:>6} {g.series:>7.0f} {g.scrapes:>7.0f} {g.scraped:>10.0f} "
              f"{g.sent:>10.0f} {g.failed:>6.0f} {g.dropped:>7.0f} "
              f"{100 * g.gateway_cpu_s / r.duration_s:>7.1f} "
              f"{100 * g.agent_cpu_s / r.duration_s:>10.1f} {g.agent_rss / 2**20:>9.0f}")
    ok = r.lost == 0
    print(f"{'central':<8} {r.loops:>6} {r.series:>7.0f} {'':>7} {r.scraped:>10.0f} "
          f"received {r.received:.0f}, queryable {r.queryable:.0f}")
    print(f"  {'MET   ' if ok else 'MISSED'} none lost: scraped {r.scraped:.0f} - received "
          f"{r.received:.0f} = {r.lost:.0f} (target 0)")
    print(f"  ingestion: {r.rate:,.0f} samples/s central ({r.rate / len(r.gateways):,.0f} per "
          f"gateway, {r.rate / r.loops:.2f} per loop at {r.scrape_s:g} s scrapes); "
          f"{r.series / r.loops:.1f} series per loop")
    per_sample = r.data_bytes / max(r.received, 1)
    print(f"  disk: data {r.data_bytes / 2**20:.1f} MiB ({per_sample:.2f} B/sample), index "
          f"{r.index_bytes / 2**20:.1f} MiB ({r.index_bytes / max(r.series, 1):.0f} B/series); "
          f"per loop per day: {r.per_loop_day_bytes() / 2**10:,.0f} KiB "
          f"({r.per_loop_day_bytes() * 365 / 2**20:,.0f} MiB a year)")
    print(f"  VictoriaMetrics: {100 * r.vm_cpu_s / r.duration_s:.1f} % of one core, "
          f"RSS {r.vm_rss / 2**20:.0f} MiB")


def main() -> None:
    secs = duration()
    print(f"== fleet: {GATEWAYS} gateways x {LOOPS:,} loops, each scraped by its own "
          f"Prometheus agent every {SCRAPE_S:g} s, remote-writing to one VictoriaMetrics, "
          f"{secs:.0f} s (cores: {os.cpu_count()}) ==")
    try:
        tool("prometheus")
        tool("victoria-metrics")
    except RuntimeError as exc:
        print(f"fleet: not run: {exc}")
        return
    print_result(run_fleet(seconds=secs))
    print()


if __name__ == "__main__":
    main()
