"""Helpers for the fleet tests and benchmark (tests/deploy/test_fleet_*.py, bench/fleet.py):
the shipped deploy/fleet files read back as command lines and configs, and throwaway
VictoriaMetrics and vmalert servers on 127.0.0.1 started from them, plus a stand-in for
Alertmanager that records what vmalert sends.

Every server runs the shipped flags (/etc/default ARGS, the unit's ExecStart) with only
the paths and addresses replaced, and the few test-speed flags named where they are set.
"""

from __future__ import annotations

import http.server
import json
import shlex
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import yaml
from deploy_support import DEPLOY, PROM_DIR, Server, require_tool

from bench._net import free_port

FLEET = DEPLOY / "fleet"
SITE_AGENT = FLEET / "site" / "prometheus-agent.yml"
SITE_DEFAULT = FLEET / "site" / "prometheus.default"
VM_DEFAULT = FLEET / "central" / "victoria-metrics.default"
VMALERT_UNIT = FLEET / "central" / "vmalert.service"
FLEET_RULE_FILES = sorted((FLEET / "central" / "rules").glob("*.yml"))
CENTRAL_RULE_FILES = sorted((PROM_DIR / "rules").glob("*.yml")) + FLEET_RULE_FILES


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


def with_flags(args: list[str], **flags: str | None) -> list[str]:
    """``args`` (``-name=value`` / ``--name=value`` items) with the named flags replaced,
    added, or dropped (value None); a flag's name has ``.`` where a keyword has ``_``."""
    wanted = {k.replace("_", "."): v for k, v in flags.items()}
    out = []
    for arg in args:
        name = arg.lstrip("-").split("=", 1)[0]
        if name in wanted:
            continue
        out.append(arg)
    dash = "--" if any(a.startswith("--") for a in args) else "-"
    out += [f"{dash}{k}={v}" for k, v in wanted.items() if v is not None]
    return out


def site_agent_config(*, site: str, area: str | None, instance: str, target: str,
                      remote_write: str, scrape_interval: str = "1s") -> dict[str, Any]:
    """The shipped agent config with one site's values: what an installer edits."""
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
    rw["queue_config"]["batch_send_deadline"] = "1s"  # test speed (shipped: 5s)
    return dict(cfg)


class VictoriaMetrics(Server):
    """The central store: victoria-metrics with the shipped ARGS, its data and listen
    address moved, and ``extra`` flags (e.g. a latency offset of 0 for tests)."""

    ready_path = "/health"

    def __init__(self, workdir: Path, **extra: str | None) -> None:
        binary = require_tool("victoria-metrics", "victoria-metrics")
        port = free_port()
        args = with_flags(default_args(VM_DEFAULT), storageDataPath=str(workdir / "data"),
                          httpListenAddr=f"127.0.0.1:{port}", **extra)
        super().__init__(workdir, [binary, *args], port, "victoria-metrics")

    def __enter__(self) -> VictoriaMetrics:
        super().__enter__()
        return self

    @property
    def write_url(self) -> str:
        return f"{self.url}/api/v1/write"

    def metric(self, name: str, **labels: str) -> float:
        """The sum of one of its own /metrics series (label subset match)."""
        return scrape_value(self.get("/metrics"), name, **labels)

    def force_flush(self) -> None:
        self.get("/internal/force_flush")


class VmAlert(Server):
    """vmalert with the shipped unit's flags: ``rules`` (a glob), reading from and writing
    to ``vm``, notifying ``notifier``; evaluating every ``interval``."""

    ready_path = "/health"

    def __init__(self, workdir: Path, rules: str, vm: VictoriaMetrics, notifier: str, *,
                 interval: str = "1s", **extra: str | None) -> None:
        require_tool("vmalert", "victoria-metrics")
        port = free_port()
        binary, *args = unit_exec_start(VMALERT_UNIT)
        args = with_flags(args, rule=rules, datasource_url=vm.url, remoteWrite_url=vm.url,
                          remoteRead_url=vm.url, notifier_url=notifier,
                          evaluationInterval=interval, httpListenAddr=f"127.0.0.1:{port}",
                          **extra)
        super().__init__(workdir, [binary, *args], port, "vmalert")

    def __enter__(self) -> VmAlert:
        super().__enter__()
        return self

    def rules(self) -> list[dict[str, Any]]:
        return [r for g in self.api("rules")["data"]["groups"] for r in g["rules"]]


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


class AlertSink:
    """Stands in for Alertmanager: records every alert POSTed to /api/v2/alerts."""

    def __init__(self) -> None:
        self.alerts: list[dict[str, Any]] = []
        self.lock = threading.Lock()
        sink = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
                with sink.lock:
                    sink.alerts.extend(json.loads(body or b"[]"))
                self.send_response(200)
                self.end_headers()

            def log_message(self, *args: object) -> None:
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> AlertSink:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.shutdown()
        self.server.server_close()

    def received(self) -> list[dict[str, str]]:
        """Label sets of every alert received (with repeats: vmalert re-sends)."""
        with self.lock:
            return [dict(a["labels"]) for a in self.alerts]


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
