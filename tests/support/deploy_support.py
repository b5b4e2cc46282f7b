"""Helpers for the deployment tests (tests/deploy/test_*.py): the real tools (promtool,
prometheus, mbpoll, systemd-analyze, victoria-metrics), the queries in the dashboards and
rules, and throwaway servers on 127.0.0.1 (:class:`Server`; :class:`Prometheus` here, the
fleet's VictoriaMetrics and vmalert in fleet_support.py).

A missing tool skips the test locally and fails it under ``CI=true`` (`.ci/run` installs
the tools from Debian packages, so in CI a missing one is a broken setup, not a reason to skip).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench import _servers as servers

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
DASHBOARDS = DEPLOY / "grafana" / "dashboards"
PROM_DIR = DEPLOY / "prometheus"
RULE_FILES = sorted((PROM_DIR / "rules").glob("*.yml"))
UNIT = DEPLOY / "systemd" / "stiction-gateway.service"


def unit_stop_timeout_s() -> float:
    """``TimeoutStopSec`` of deploy/systemd/stiction-gateway.service: how long systemd lets
    the gateway stop before SIGKILL, so how long a test waits for a clean exit."""
    unit = (REPO / "deploy" / "systemd" / "stiction-gateway.service").read_text()
    m = re.search(r"^TimeoutStopSec=(\d+)s?$", unit, re.M)
    assert m, "the unit has no TimeoutStopSec in seconds"
    return float(m.group(1))


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() == "true"


def require_tool(name: str, package: str) -> str:
    """Path of the executable ``name``; skip (locally) or fail (CI=true) when it is missing."""
    path = shutil.which(name)
    if path is not None:
        return path
    reason = f"{name} not found (Debian package {package!r}; .ci/run installs it)"
    if in_ci():
        pytest.fail(f"CI=true and {reason}")
    pytest.skip(reason)


def require(condition: bool, reason: str) -> None:
    """Skip (locally) or fail (CI=true) when something a test needs is not there."""
    if condition:
        return
    if in_ci():
        pytest.fail(f"CI=true and {reason}")
    pytest.skip(reason)


def run(cmd: list[str], timeout: float = 60, **kw: Any) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False, **kw)


def fake_root(tmp_path: Path, unit: Path) -> Path:
    """A root with systemd's own units, ``unit`` and stub executables at the paths it
    names, so `systemd-analyze verify` checks the real file in a container where
    /opt/stiction-gateway (or /usr/bin/vmalert) does not exist."""
    root = tmp_path / "root"
    shutil.copytree("/usr/lib/systemd/system", root / "usr/lib/systemd/system", symlinks=True)
    (root / "etc/systemd/system").mkdir(parents=True)
    shutil.copy(unit, root / "etc/systemd/system" / unit.name)
    text = unit.read_text()
    for exe in sorted(set(re.findall(r"^Exec\w+=[-@:+!]*(\S+)", text, re.M))):
        stub = root / exe.lstrip("/")
        stub.parent.mkdir(parents=True, exist_ok=True)
        stub.write_text("#!/bin/sh\n")
        stub.chmod(0o755)
    return root


# ------------------------------------------------------------------ dashboards and rules


@dataclass(frozen=True)
class Query:
    """One PromQL expression found in a deploy file."""

    where: str  # file and panel/rule, for messages
    expr: str
    kind: str  # "panel", "variable", "record", "alert"
    instant: bool = False


def load_dashboards() -> dict[str, dict[str, Any]]:
    return {p.name: json.loads(p.read_text()) for p in sorted(DASHBOARDS.glob("*.json"))}


def iter_panels(panels: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    for panel in panels:
        yield panel
        yield from iter_panels(panel.get("panels", []))  # collapsed rows


def dashboard_queries() -> list[Query]:
    out: list[Query] = []
    for name, dash in load_dashboards().items():
        for panel in iter_panels(dash["panels"]):
            for t in panel.get("targets", []):
                out.append(
                    Query(
                        f"{name}: panel {panel['title']!r} query {t['refId']}",
                        t["expr"],
                        "panel",
                        instant=bool(t.get("instant")) and not t.get("range"),
                    )
                )
        for var in dash["templating"]["list"]:
            if var["type"] == "query":
                q = var["query"]["query"] if isinstance(var["query"], dict) else var["query"]
                out.append(Query(f"{name}: variable ${var['name']}", q, "variable"))
    return out


def rule_queries() -> list[Query]:
    out: list[Query] = []
    for path in RULE_FILES:
        for group in yaml.safe_load(path.read_text())["groups"]:
            for rule in group["rules"]:
                kind = "alert" if "alert" in rule else "record"
                out.append(Query(f"{path.name}: {kind} {rule[kind]}", rule["expr"], kind))
    return out


def shortened_rules(dest: Path, files: Sequence[Path] = tuple(RULE_FILES)) -> list[Path]:
    """The rule ``files`` (default: the shipped ones) copied into ``dest`` with every
    ``for:`` set to 0s, the expressions untouched; returns the copies."""
    dest.mkdir(parents=True, exist_ok=True)
    out = []
    for path in files:
        doc = yaml.safe_load(path.read_text())
        for group in doc["groups"]:
            for rule in group["rules"]:
                if "for" in rule:
                    rule["for"] = "0s"
        (dest / path.name).write_text(yaml.safe_dump(doc, sort_keys=False))
        out.append(dest / path.name)
    return out


_LABEL_VALUES = re.compile(r"^label_values\((?:(?P<match>.+),\s*)?(?P<label>\w+)\)$", re.S)


def substitute(expr: str, *, loop: str, instance: str = ".*", rate: str = "1m",
               site: str = ".*") -> str:
    """Replace Grafana's template variables the way Grafana would, with the given values."""
    return (
        expr.replace("$__rate_interval", rate)
        .replace("$__interval", rate)
        .replace("$instance", instance)
        .replace("$site", site)
        .replace("$loop", loop)
    )


def parse_label_values(expr: str) -> tuple[str | None, str]:
    """``label_values(match, label)`` (a Grafana variable query) -> (match, label)."""
    m = _LABEL_VALUES.match(expr.strip())
    if m is None:
        raise ValueError(f"not a label_values() query: {expr!r}")
    return m.group("match"), m.group("label")


# ------------------------------------------------------------------ servers


class QueryRunner:
    """Runs the dashboards' and rules' queries on a server with the Prometheus query API
    (:class:`bench._servers.Server`)."""

    def run_query(self: Any, q: Query, *, loop: str, rate: str = "1m", seconds: float = 60,
                  site: str = ".*") -> Any:
        """Run a dashboard/rule query as Grafana or the rule engine would; returns the
        answer's ``data`` (a parse error or other failure raises AssertionError)."""
        expr = substitute(q.expr, loop=loop, rate=rate, site=site)
        if q.kind == "variable":
            match, label = parse_label_values(expr)
            params = {"match[]": match} if match else {}
            ans = self.api(f"label/{label}/values", **params)
        elif q.kind == "panel" and not q.instant:
            ans = self.query_range(expr, seconds)
        else:
            ans = self.query(expr)
        assert ans.get("status") == "success", f"{q.where}: {expr}\n -> {ans}"
        return ans["data"]


class Prometheus(QueryRunner, servers.Prometheus):
    """A real Prometheus on 127.0.0.1 with a temporary config and TSDB (or, with
    ``agent``, in agent mode); see :class:`bench._servers.Prometheus`."""

    def __init__(self, workdir: Path, config: dict[str, Any], rule_files: Sequence[Path] = (),
                 *, agent: bool = False, args: Sequence[str] = ()) -> None:
        super().__init__(workdir, config, rule_files, agent=agent, args=args,
                         binary=require_tool("prometheus", "prometheus"))

    def __enter__(self) -> Prometheus:
        super().__enter__()
        return self


def has_data(data: Any) -> bool:
    """Whether a query answer's ``data`` holds at least one sample/value."""
    if isinstance(data, list):  # label values
        return len(data) > 0
    result = data["result"]
    if data["resultType"] in ("scalar", "string"):
        return True
    return len(result) > 0
