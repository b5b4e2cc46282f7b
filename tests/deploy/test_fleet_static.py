"""Static checks of deploy/fleet/ with the real tools (issue 17): each site's Prometheus
agent config (promtool), the central VictoriaMetrics flags (victoria-metrics parses them),
the vmalert unit (systemd-analyze; vmalert -dryRun loads every rule with the unit's flags),
the fleet rules' unit tests (promtool), the Grafana datasource, and CI installing the tools.
The running fleet is tests/deploy/test_fleet_live.py."""

from __future__ import annotations

import re
from pathlib import Path

import yaml
from deploy_support import REPO, fake_root, require_tool, rule_queries, run
from fleet_support import (
    CENTRAL_RULE_FILES,
    FLEET,
    FLEET_RULE_FILES,
    SITE_AGENT,
    SITE_DEFAULT,
    VM_DEFAULT,
    VMALERT_UNIT,
    default_args,
    unit_exec_start,
    with_flags,
)


def test_site_agent_config_is_valid_and_complete() -> None:
    promtool = require_tool("promtool", "prometheus")
    r = run([promtool, "check", "config", str(SITE_AGENT)])
    assert r.returncode == 0, r.stdout + r.stderr
    cfg = yaml.safe_load(SITE_AGENT.read_text())
    assert set(cfg["global"]["external_labels"]) == {"site", "area"}
    (job,) = cfg["scrape_configs"]
    assert job["job_name"] == "stiction-gateway"
    (static,) = job["static_configs"]
    assert static["targets"] == ["127.0.0.1:9108"]
    assert static["labels"]["instance"]  # unique per box: every box scrapes 127.0.0.1
    (rw,) = cfg["remote_write"]
    assert rw["url"].endswith(":8428/api/v1/write")
    # no rules and no Alertmanager at the sites: alerts are evaluated once, centrally
    assert "rule_files" not in cfg and "alerting" not in cfg


def test_site_prometheus_runs_as_an_agent() -> None:
    args = default_args(SITE_DEFAULT)
    assert "--enable-feature=agent" in args
    assert "--storage.agent.path=/var/lib/prometheus/data-agent" in args
    assert "--web.listen-address=127.0.0.1:9090" in args


def test_victoria_metrics_takes_the_shipped_flags() -> None:
    binary = require_tool("victoria-metrics", "victoria-metrics")
    args = default_args(VM_DEFAULT)
    r = run([binary, *args, "-version"])
    assert r.returncode == 0, r.stdout + r.stderr
    r = run([binary, *args, "-retentionPeriod=13x", "-version"])  # the check is not vacuous
    assert r.returncode != 0
    flags = dict(a.lstrip("-").split("=", 1) for a in args)
    assert flags["retentionPeriod"] == "400d"  # 13 months: a year back across a turnaround
    assert flags["storageDataPath"] == "/var/lib/victoria-metrics"
    assert int(flags["search.maxUniqueTimeseries"]) >= 2_000_000


def test_vmalert_unit_verifies_and_is_hardened(tmp_path: Path) -> None:
    tool = require_tool("systemd-analyze", "systemd")
    root = fake_root(tmp_path, VMALERT_UNIT)
    r = run([tool, "verify", f"--root={root}", VMALERT_UNIT.name])
    assert r.returncode == 0, r.stdout + r.stderr
    assert not r.stderr.strip(), r.stderr
    r = run([tool, "security", "--offline=yes", f"--root={root}", "--threshold=20",
             VMALERT_UNIT.name])
    m = re.search(r"Overall exposure level for \S+: (\d+\.\d)", r.stdout)
    assert m is not None, r.stdout
    assert float(m.group(1)) <= 2.0, r.stdout


def test_vmalert_loads_every_rule_with_the_units_flags() -> None:
    """The unit's own flags (one -rule glob replaced by the repository's rule files) and
    every rule, templates included, pass vmalert's checks; a broken rule would not."""
    require_tool("vmalert", "victoria-metrics")
    binary, *args = unit_exec_start(VMALERT_UNIT)
    assert binary == "/usr/bin/vmalert"
    assert "-rule=/etc/vmalert/rules/*.yml" in args
    base = with_flags(args, rule=None)
    rules = [f"-rule={p}" for p in CENTRAL_RULE_FILES]
    r = run(["vmalert", *base, *rules, "-dryRun"])
    assert r.returncode == 0, r.stdout + r.stderr
    flags = dict(a.lstrip("-").split("=", 1) for a in args)
    vm = "http://127.0.0.1:8428"
    assert flags["datasource.url"] == flags["remoteWrite.url"] == flags["remoteRead.url"] == vm
    assert flags["notifier.url"]


def test_vmalert_refuses_a_broken_rule(tmp_path: Path) -> None:
    require_tool("vmalert", "victoria-metrics")
    bad = tmp_path / "bad.yml"
    bad.write_text("groups:\n  - name: x\n    rules:\n      - alert: A\n        expr: sum(\n")
    r = run(["vmalert", f"-rule={bad}", "-dryRun"])
    assert r.returncode != 0


def test_fleet_rules_unit_tests_every_fleet_alert_fires() -> None:
    """`promtool test rules` on deploy/fleet/tests: the shipped rules on two sites whose boxes
    and loops share names alert per site, and each fleet alert fires."""
    promtool = require_tool("promtool", "prometheus")
    r = run([promtool, "check", "rules", *map(str, FLEET_RULE_FILES)])
    assert r.returncode == 0, r.stdout + r.stderr
    tests = sorted((FLEET / "tests").glob("*.test.yml"))
    assert tests
    r = run([promtool, "test", "rules", *map(str, tests)])
    assert r.returncode == 0, r.stdout + r.stderr
    fired = {case["alertname"] for t in tests
             for group in yaml.safe_load(t.read_text())["tests"]
             for case in group.get("alert_rule_test", []) if case["exp_alerts"]}
    fleet_alerts = {rule["alert"] for p in FLEET_RULE_FILES
                    for g in yaml.safe_load(p.read_text())["groups"] for rule in g["rules"]
                    if "alert" in rule}
    assert fleet_alerts == {"StictionSiteSilent", "StictionSiteLabelMismatch"}
    assert fleet_alerts <= fired
    assert {"LoopStictionDiagnosed", "LoopFrictionAboveThreshold", "StictionGatewayDown"} <= fired
    names = {q.where.split()[-1] for q in rule_queries()}
    assert not fleet_alerts & names  # central only: not in the sites' rule files


def test_grafana_datasource_for_the_central_store() -> None:
    ds = yaml.safe_load((FLEET / "central" / "grafana-datasource.yaml").read_text())
    (src,) = ds["datasources"]
    assert (ds["apiVersion"], src["type"], src["access"]) == (1, "prometheus", "proxy")
    assert src["url"].endswith(":8428")
    assert src["uid"] != "stiction-prometheus"


def test_ci_installs_the_fleet_tools() -> None:
    ci = (REPO / ".ci" / "run").read_text()
    assert "victoria-metrics" in ci
    assert "command -v vmalert" in ci
