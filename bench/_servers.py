"""Real Prometheus and VictoriaMetrics servers on 127.0.0.1, started from the shipped deploy
files, for the fleet benchmark (bench/speed/fleet.py) and the deployment tests
(tests/support/deploy_support.py, fleet_support.py).

Every server runs the shipped flags (/etc/default ARGS, a unit's ExecStart) with only the
paths and addresses replaced (:func:`with_flags`), plus the test-speed flags its caller
names. A server is a context manager: started and ready (its ready path answers 200) on
entry, stopped (then killed) on exit, its output in ``log_path``.
"""

from __future__ import annotations

import contextlib
import json
import shlex
import shutil
import subprocess
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from bench._net import free_port

__all__ = ["DEPLOY", "FLEET", "SITE_AGENT", "SITE_DEFAULT", "VMALERT_UNIT", "VM_DEFAULT",
           "Prometheus", "Server", "VictoriaMetrics", "default_args", "http_get", "keyed",
           "label_sets", "scrape_value", "site_agent_config", "tool", "unit_exec_start",
           "with_flags"]

DEPLOY = Path(__file__).resolve().parents[1] / "deploy"
FLEET = DEPLOY / "fleet"
SITE_AGENT = FLEET / "site" / "prometheus-agent.yml"
SITE_DEFAULT = FLEET / "site" / "prometheus.default"
VM_DEFAULT = FLEET / "central" / "victoria-metrics.default"
VMALERT_UNIT = FLEET / "central" / "vmalert.service"

Values = dict[tuple[tuple[str, str], ...], float]


def tool(name: str) -> str:
    """Path of the executable ``name`` (RuntimeError naming its Debian package if missing)."""
    path = shutil.which(name)
    if path is None:
        package = "prometheus" if name.startswith(("prom", "promtool")) else "victoria-metrics"
        raise RuntimeError(f"{name} not found (Debian package {package})")
    return path


def http_get(url: str, timeout: float = 5) -> str:
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return str(r.read().decode())


# ------------------------------------------------------------------ the shipped files


def default_args(path: Path) -> list[str]:
    """The ``ARGS="..."`` of an /etc/default file, split as the shell would."""
    for line in path.read_text().splitlines():
        if line.startswith("ARGS="):
            return shlex.split(line.removeprefix("ARGS="))[0].split()
    raise AssertionError(f"no ARGS= in {path}")


def unit_exec_start(path: Path) -> list[str]:
    """ExecStart of a systemd unit (continuation lines joined), split."""
    text = path.read_text().replace("\\\n", " ")
    for line in text.splitlines():
        if line.startswith("ExecStart="):
            return shlex.split(line.removeprefix("ExecStart="))
    raise AssertionError(f"no ExecStart= in {path}")


def with_flags(args: Sequence[str], **flags: str | None) -> list[str]:
    """``args`` (``-name=value`` or ``--name=value`` items) with the named flags replaced,
    added, or dropped (value None); in a keyword, ``_`` stands for the flag's ``.``."""
    wanted = {k.replace("_", "."): v for k, v in flags.items()}
    out = [a for a in args if a.lstrip("-").split("=", 1)[0] not in wanted]
    dash = "--" if any(a.startswith("--") for a in args) else "-"
    return out + [f"{dash}{k}={v}" for k, v in wanted.items() if v is not None]


def site_agent_config(*, site: str, area: str | None, instance: str, target: str,
                      remote_write: str, scrape_interval: str = "1s",
                      batch_send_deadline: str = "1s") -> dict[str, Any]:
    """The shipped site agent config (deploy/fleet/site/prometheus-agent.yml) with one
    site's values filled in, as an installer edits it."""
    cfg = yaml.safe_load(SITE_AGENT.read_text())
    cfg["global"]["scrape_interval"] = scrape_interval
    labels = cfg["global"]["external_labels"]
    labels["site"] = site
    if area is None:
        labels.pop("area", None)
    else:
        labels["area"] = area
    (job,) = cfg["scrape_configs"]
    (static,) = job["static_configs"]
    static["targets"] = [target]
    static["labels"]["instance"] = instance
    (rw,) = cfg["remote_write"]
    rw["url"] = remote_write
    rw["queue_config"]["batch_send_deadline"] = batch_send_deadline
    return dict(cfg)


# ------------------------------------------------------------------ answers


def scrape_value(text: str, name: str, **labels: str) -> float:
    """Sum of the samples of ``name`` in an exposition whose labels include ``labels``."""
    total = 0.0
    for line in text.splitlines():
        if not line.startswith(name) or line[len(name):len(name) + 1] not in ("{", " "):
            continue
        head, _, value = line.rpartition(" ")
        if all(f'{k}="{v}"' in head for k, v in labels.items()):
            total += float(value)
    return total


def label_sets(results: Mapping[tuple[tuple[str, str], ...], float], *keys: str
               ) -> Iterator[tuple[str, ...]]:
    """The values of ``keys`` of each series of :meth:`Server.values`' answer."""
    for labels in results:
        d = dict(labels)
        yield tuple(d.get(k, "") for k in keys)


def keyed(results: Mapping[tuple[tuple[str, str], ...], float], *keys: str
          ) -> dict[tuple[str, ...], float]:
    """:meth:`Server.values`' answer keyed by the values of ``keys`` only."""
    return dict(zip(label_sets(results, *keys), results.values(), strict=True))


# ------------------------------------------------------------------ servers


class Server:
    """A server binary on 127.0.0.1 (``argv``); those that answer the Prometheus query API
    (Prometheus, VictoriaMetrics, vmalert) share :meth:`api` and the query helpers."""

    ready_path = "/-/ready"
    ready_timeout_s = 20.0

    def __init__(self, workdir: Path, argv: list[str], port: int, name: str) -> None:
        self.workdir = workdir
        self.argv = argv
        self.port = port
        self.url = f"http://127.0.0.1:{port}"
        self.log_path = workdir / f"{name}.log"
        self.name = name
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> Server:
        self.workdir.mkdir(parents=True, exist_ok=True)
        with self.log_path.open("wb") as log:
            self.proc = subprocess.Popen(self.argv, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + self.ready_timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"{self.name} exited: {self.log_path.read_text()}")
            with (
                contextlib.suppress(OSError),
                urllib.request.urlopen(f"{self.url}{self.ready_path}", timeout=1) as r,
            ):
                if r.status == 200:
                    return self
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"{self.name} not ready: {self.log_path.read_text()}")

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self, timeout: float = 10) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def get(self, path: str) -> str:
        return http_get(f"{self.url}{path}", timeout=30)

    def api(self, path: str, **params: str) -> dict[str, Any]:
        """GET /api/v1/<path>; returns the JSON answer, also for 4xx (a parse error)."""
        url = f"{self.url}/api/v1/{path}?{urllib.parse.urlencode(params)}"
        try:
            with urllib.request.urlopen(url, timeout=30) as r:
                return dict(json.load(r))
        except urllib.error.HTTPError as e:
            return dict(json.load(e))

    def query(self, expr: str) -> dict[str, Any]:
        return self.api("query", query=expr)

    def query_range(self, expr: str, seconds: float, step: str = "1s") -> dict[str, Any]:
        end = time.time()
        return self.api(
            "query_range", query=expr, start=f"{end - seconds:.3f}", end=f"{end:.3f}", step=step
        )

    def values(self, expr: str) -> Values:
        """An instant query's result: {sorted label pairs: value}."""
        ans = self.query(expr)
        assert ans.get("status") == "success", f"{expr} -> {ans}"
        return {tuple(sorted(r["metric"].items())): float(r["value"][1])
                for r in ans["data"]["result"]}

    def metric(self, name: str, **labels: str) -> float:
        """The sum of one of the server's own /metrics series (label subset match)."""
        return scrape_value(self.get("/metrics"), name, **labels)


class Prometheus(Server):
    """Prometheus with a temporary config and storage; with ``agent``, in agent mode
    (scrape and remote-write only: no query API, no rules), started with ``args`` (e.g.
    the shipped /etc/default/prometheus ARGS) besides its paths."""

    def __init__(self, workdir: Path, config: dict[str, Any], rule_files: Sequence[Path] = (),
                 *, agent: bool = False, args: Sequence[str] = (), binary: str | None = None
                 ) -> None:
        port = free_port()
        workdir.mkdir(parents=True, exist_ok=True)
        config = dict(config)
        if rule_files:
            config["rule_files"] = [str(p) for p in rule_files]
        self.config_path = workdir / "prometheus.yml"
        self.config_path.write_text(yaml.safe_dump(config, sort_keys=False))
        storage = ("--storage.agent.path" if agent else "--storage.tsdb.path") + \
            f"={workdir / 'data'}"
        feature = [] if not agent or "--enable-feature=agent" in args else [
            "--enable-feature=agent"]
        argv = [binary or tool("prometheus"), *feature, *args,
                f"--config.file={self.config_path}", storage,
                f"--web.listen-address=127.0.0.1:{port}", "--log.level=warn"]
        super().__init__(workdir, argv, port, "prometheus")

    def __enter__(self) -> Prometheus:
        super().__enter__()
        return self

    def targets_up(self) -> list[dict[str, Any]]:
        return list(self.api("targets")["data"]["activeTargets"])

    def alerts(self) -> list[dict[str, Any]]:
        return list(self.api("alerts")["data"]["alerts"])


class VictoriaMetrics(Server):
    """The central store: victoria-metrics with the shipped ARGS, its data and listen
    address moved, and ``extra`` flags (e.g. a latency offset of 0 for tests)."""

    ready_path = "/health"

    def __init__(self, workdir: Path, *, binary: str | None = None, **extra: str | None
                 ) -> None:
        port = free_port()
        args = with_flags(default_args(VM_DEFAULT), storageDataPath=str(workdir / "data"),
                          httpListenAddr=f"127.0.0.1:{port}", **extra)
        super().__init__(workdir, [binary or tool("victoria-metrics"), *args], port,
                         "victoria-metrics")

    def __enter__(self) -> VictoriaMetrics:
        super().__enter__()
        return self

    @property
    def data_path(self) -> Path:
        return self.workdir / "data"

    @property
    def write_url(self) -> str:
        return f"{self.url}/api/v1/write"

    def force_flush(self) -> None:
        """Make the samples it has buffered searchable and written."""
        self.get("/internal/force_flush")
