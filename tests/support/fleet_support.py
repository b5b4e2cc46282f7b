"""Helpers for the fleet tests (tests/deploy/test_fleet_*.py): the central VictoriaMetrics
(the shipped ARGS) and vmalert (the shipped unit's flags) on 127.0.0.1, answering the
dashboards' queries like deploy_support's Prometheus, and a stand-in for Alertmanager that
records what vmalert sends. The shipped files are read back by bench/_servers.py."""

from __future__ import annotations

import http.server
import json
import threading
from pathlib import Path
from typing import Any

from deploy_support import PROM_DIR, QueryRunner, require_tool

from bench import _servers as servers
from bench._net import free_port
from bench._servers import (
    FLEET,
    SITE_AGENT,
    SITE_DEFAULT,
    VM_DEFAULT,
    VMALERT_UNIT,
    default_args,
    keyed,
    label_sets,
    site_agent_config,
    unit_exec_start,
    with_flags,
)

__all__ = ["CENTRAL_RULE_FILES", "FLEET", "FLEET_RULE_FILES", "SITE_AGENT", "SITE_DEFAULT",
           "VMALERT_UNIT", "VM_DEFAULT", "AlertSink", "VictoriaMetrics", "VmAlert",
           "default_args", "keyed", "label_sets", "site_agent_config", "unit_exec_start",
           "with_flags"]

FLEET_RULE_FILES = sorted((FLEET / "central" / "rules").glob("*.yml"))
CENTRAL_RULE_FILES = sorted((PROM_DIR / "rules").glob("*.yml")) + FLEET_RULE_FILES


class VictoriaMetrics(QueryRunner, servers.VictoriaMetrics):
    """The central store with the shipped ARGS (see :class:`bench._servers.VictoriaMetrics`);
    skips locally, fails under CI=true, without the victoria-metrics package."""

    def __init__(self, workdir: Path, **extra: str | None) -> None:
        super().__init__(workdir, binary=require_tool("victoria-metrics", "victoria-metrics"),
                         **extra)

    def __enter__(self) -> VictoriaMetrics:
        super().__enter__()
        return self


class VmAlert(QueryRunner, servers.Server):
    """vmalert with the shipped unit's flags: ``rules`` (a glob), reading from and writing
    to ``vm``, notifying ``notifier``, evaluating every ``interval``, and ``extra`` flags."""

    ready_path = "/health"

    def __init__(self, workdir: Path, rules: str, vm: servers.VictoriaMetrics, notifier: str,
                 *, interval: str = "1s", **extra: str | None) -> None:
        binary = require_tool("vmalert", "victoria-metrics")
        port = free_port()
        _, *args = unit_exec_start(VMALERT_UNIT)
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
