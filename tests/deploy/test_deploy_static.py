"""Static checks of deploy/ with the real tools: promtool (config, rules, rule unit tests),
systemd-analyze (verify, security), the Grafana dashboards and provisioning files, and every
query in them parsed by a real Prometheus. No gateway needed."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from deploy_support import (
    DASHBOARDS,
    DEPLOY,
    PROM_DIR,
    REPO,
    RULE_FILES,
    UNIT,
    Prometheus,
    Query,
    dashboard_queries,
    fake_root,
    iter_panels,
    load_dashboards,
    parse_label_values,
    require_tool,
    rule_queries,
    run,
    substitute,
)

# ------------------------------------------------------------------ Prometheus


def test_promtool_check_config() -> None:
    promtool = require_tool("promtool", "prometheus")
    r = run([promtool, "check", "config", str(PROM_DIR / "prometheus.yml")])
    assert r.returncode == 0, r.stdout + r.stderr
    # the rule_files glob finds the shipped rules (a wrong glob passes with 0 files)
    assert f"SUCCESS: {len(RULE_FILES)} rule files found" in r.stdout + r.stderr


def test_prometheus_config_scrapes_the_gateway() -> None:
    cfg = yaml.safe_load((PROM_DIR / "prometheus.yml").read_text())
    (job,) = cfg["scrape_configs"]
    assert job["job_name"] == "stiction-gateway"
    assert job["static_configs"][0]["targets"] == ["127.0.0.1:9108"]


def test_promtool_check_rules() -> None:
    promtool = require_tool("promtool", "prometheus")
    assert len(RULE_FILES) == 2
    r = run([promtool, "check", "rules", *map(str, RULE_FILES)])
    assert r.returncode == 0, r.stdout + r.stderr


def test_promtool_rule_unit_tests_every_alert_fires() -> None:
    """`promtool test rules`: each alert fires on synthetic series at the time its `for:`
    allows, with the exact labels and annotations, and fd overrides work per loop."""
    promtool = require_tool("promtool", "prometheus")
    tests = sorted((PROM_DIR / "tests").glob("*.test.yml"))
    assert len(tests) == 4
    r = run([promtool, "test", "rules", *map(str, tests)])
    assert r.returncode == 0, r.stdout + r.stderr
    fired = set()
    for t in tests:
        for group in yaml.safe_load(t.read_text())["tests"]:
            for case in group.get("alert_rule_test", []):
                if case["exp_alerts"]:
                    fired.add(case["alertname"])
    alerts = {q.where.split()[-1] for q in rule_queries() if q.kind == "alert"}
    assert fired == alerts, f"alerts without a firing unit test: {alerts - fired}"


def test_rules_cover_what_plant_engineers_asked_for() -> None:
    alerts = {q.where.split()[-1]: q.expr for q in rule_queries() if q.kind == "alert"}
    assert set(alerts) == {
        "LoopStictionDiagnosed",  # a loop newly diagnosed with stiction
        "LoopValveNotResponding",  # OP travels, PV stands still
        "LoopFrictionAboveThreshold",  # fd above a configurable threshold
        "StictionDeviceDown",  # a device down
        "StictionGatewayDown",  # the gateway itself not scraped
        "LoopStale",  # a loop stale
        "AnalysisFallingBehind",  # analysis falling behind
        "StictionPollingBehindSchedule",  # polls miss their ticks (issue 22)
        "StictionStateNotWritten",  # state-file writes fail (issue 22)
        "PlantSourceDrivesLoops",  # one source drives N loops (issue 21)
        "StictionSiteFindingsContradict",  # the findings contradict the confidence (39)
    }
    assert "stiction:loop_fd_threshold:ratio" in alerts["LoopFrictionAboveThreshold"]
    rules = {q.where.split()[-1] for q in rule_queries()}
    assert "stiction:fd_threshold_default:ratio" in rules


# ------------------------------------------------------------------ systemd


def _fake_root(tmp_path: Path) -> Path:
    return fake_root(tmp_path, UNIT)


def test_systemd_analyze_verify(tmp_path: Path) -> None:
    tool = require_tool("systemd-analyze", "systemd")
    root = _fake_root(tmp_path)
    r = run([tool, "verify", f"--root={root}", UNIT.name])
    assert r.returncode == 0, r.stdout + r.stderr
    assert not r.stderr.strip(), r.stderr  # unknown keys only warn


def test_systemd_analyze_verify_catches_a_typo(tmp_path: Path) -> None:
    """The check above is not vacuous: a misspelt directive only warns (exit status 0),
    which the check catches by requiring an empty stderr."""
    tool = require_tool("systemd-analyze", "systemd")
    root = _fake_root(tmp_path)
    unit = root / "etc/systemd/system" / UNIT.name
    unit.write_text(unit.read_text().replace("WatchdogSec=", "WatchdogSecs="))
    r = run([tool, "verify", f"--root={root}", UNIT.name])
    assert "Unknown key 'WatchdogSecs' in section [Service]" in r.stderr


def test_systemd_security_exposure_is_low(tmp_path: Path) -> None:
    tool = require_tool("systemd-analyze", "systemd")
    root = _fake_root(tmp_path)
    r = run([tool, "security", "--offline=yes", f"--root={root}", "--threshold=20", UNIT.name])
    assert r.returncode == 0, r.stdout + r.stderr
    m = re.search(r"Overall exposure level for \S+: (\d+\.\d)", r.stdout)
    assert m is not None, r.stdout
    assert float(m.group(1)) <= 2.0, r.stdout


def _unit_settings() -> dict[str, list[str]]:
    settings: dict[str, list[str]] = {}
    for line in UNIT.read_text().splitlines():
        if "=" in line and not line.startswith(("#", "[")):
            key, value = line.split("=", 1)
            settings.setdefault(key.strip(), []).append(value.strip())
    return settings


def test_unit_has_the_service_contract_and_hardening() -> None:
    s = _unit_settings()
    expected = {
        "Type": "notify",
        "ExecReload": "/bin/kill -HUP $MAINPID",
        "Restart": "on-failure",
        "DynamicUser": "yes",
        "StateDirectory": "stiction-gateway",
        "ConfigurationDirectory": "stiction-gateway",
        "WorkingDirectory": "/var/lib/stiction-gateway",
        # hardening from ../shared/docs/library-notes.md
        "NoNewPrivileges": "yes",
        "ProtectSystem": "strict",
        "ProtectHome": "yes",
        "PrivateTmp": "yes",
        "PrivateDevices": "yes",
        "ProtectKernelTunables": "yes",
        "ProtectKernelModules": "yes",
        "ProtectKernelLogs": "yes",
        "RestrictAddressFamilies": "AF_INET AF_INET6 AF_UNIX",
        "MemoryDenyWriteExecute": "yes",
        "SystemCallFilter": "@system-service",
        "UMask": "0077",
    }
    for key, value in expected.items():
        assert s.get(key) == [value], (key, s.get(key))
    assert s["ExecStart"] == [
        "/opt/stiction-gateway/bin/stiction-gateway run --config /etc/stiction-gateway/gateway.yaml"
    ]
    assert re.fullmatch(r"\d+s", s["WatchdogSec"][0])


# ------------------------------------------------------------------ Grafana


def test_dashboards_have_fixed_uids_and_a_datasource_variable() -> None:
    dashes = load_dashboards()
    assert {d["uid"] for d in dashes.values()} == {"stiction-fleet", "stiction-loop"}
    for name, d in dashes.items():
        variables = {v["name"]: v for v in d["templating"]["list"]}
        assert variables["datasource"]["type"] == "datasource", name
        assert variables["datasource"]["query"] == "prometheus", name
        for panel in iter_panels(d["panels"]):
            if panel["type"] == "row":
                continue
            assert panel["datasource"] == {"type": "prometheus", "uid": "${datasource}"}, (
                name,
                panel["title"],
            )
            assert panel["targets"], (name, panel["title"])
            for t in panel["targets"]:
                assert t["datasource"]["uid"] == "${datasource}", (name, panel["title"])
                assert t["expr"].strip(), (name, panel["title"])
        for v in variables.values():
            if v["type"] == "query":
                assert v["datasource"]["uid"] == "${datasource}"
        ids = [p["id"] for p in iter_panels(d["panels"])]
        assert len(ids) == len(set(ids)), name


def test_loop_dashboard_is_driven_by_the_loop_variable() -> None:
    d = load_dashboards()["stiction-loop.json"]
    variables = {v["name"]: v for v in d["templating"]["list"]}
    assert "loop" in variables
    assert "instance" in variables
    for panel in iter_panels(d["panels"]):
        if panel["title"].endswith("at this site"):  # site-wide context, said so
            assert panel["description"].startswith("Site-wide (not only this loop)")
            continue
        for t in panel["targets"]:
            assert 'loop="$loop"' in t["expr"], (panel["title"], t["expr"])
    titles = {p["title"] for p in iter_panels(d["panels"])}
    assert {
        "Controller output OP",
        "Process variable PV",
        "Stiction index",
        "fd and fs",
        "Verdict history",
        "Latest finding",  # issue 30: the crew's findings beside the calls
        "Calls and findings",
        "Calls against findings at this site",
    } <= titles


def test_fleet_dashboard_panels() -> None:
    d = load_dashboards()["stiction-fleet.json"]
    panels = {p["title"]: p for p in iter_panels(d["panels"])}
    assert {
        "50 worst valves, fleet-wide: stiction ranked by fd, with confidence",
        "Verdicts per site",
        "Gateway health per site",
        "Gateways up, by site",
        "Loops per verdict",
        "Devices up",
        "Poll errors by kind",
    } <= set(panels)
    # issue 17: sites x verdicts, the 50 worst valves by fd with their confidence, and each
    # site's gateways (up, devices down, the age of its latest scrape)
    exprs = {title: [t["expr"] for t in p["targets"]] for title, p in panels.items()}
    assert exprs["Verdicts per site"] == [
        'sum by (site, verdict) (stiction_loop_verdict{site=~"$site", instance=~"$instance"})']
    worst = exprs["50 worst valves, fleet-wide: stiction ranked by fd, with confidence"]
    assert all("topk(50, stiction_loop_fd_ratio{" in e for e in worst)
    assert worst[1].startswith("stiction_loop_confidence_ratio{")
    health = " ".join(exprs["Gateway health per site"])
    assert 'up{job="stiction-gateway"' in health and "stiction_device_up" in health
    assert "timestamp(" in health


def test_both_dashboards_select_site_then_instance() -> None:
    """$site (label site of stiction_build_info), then $instance within it; every query of
    both dashboards is restricted to them."""
    for name, d in load_dashboards().items():
        variables = [v for v in d["templating"]["list"] if v["type"] == "query"]
        assert [v["name"] for v in variables][:2] == ["site", "instance"], name
        site, instance = variables[:2]
        assert site["query"]["query"] == "label_values(stiction_build_info, site)"
        assert instance["query"]["query"] == (
            'label_values(stiction_build_info{site=~"$site"}, instance)')
        for panel in iter_panels(d["panels"]):
            for t in panel.get("targets", []):
                assert 'site=~"$site"' in t["expr"], (name, panel["title"], t["expr"])
                assert "on (job, instance, loop)" not in t["expr"], (name, panel["title"])


def test_no_hard_coded_instances_or_datasources() -> None:
    for path in sorted(DASHBOARDS.glob("*.json")):
        text = path.read_text()
        assert not re.search(r'instance=~?"[^$]', text), path.name
        assert not re.search(r"\d+\.\d+\.\d+\.\d+|localhost|:9108|:9090", text), path.name
        assert '"uid": "stiction-prometheus"' not in text, path.name


def test_grafana_provisioning_files() -> None:
    prov = DEPLOY / "grafana" / "provisioning"
    (ds_file,) = sorted((prov / "datasources").glob("*.yaml"))
    ds = yaml.safe_load(ds_file.read_text())
    assert ds["apiVersion"] == 1
    (src,) = ds["datasources"]
    assert src["type"] == "prometheus"
    assert src["access"] == "proxy"
    assert src["uid"]
    (db_file,) = sorted((prov / "dashboards").glob("*.yaml"))
    db = yaml.safe_load(db_file.read_text())
    assert db["apiVersion"] == 1
    (provider,) = db["providers"]
    assert provider["type"] == "file"
    assert provider["options"]["path"].startswith("/")


def test_every_query_is_extracted() -> None:
    """Panel and variable queries, with the template variables known to substitute()."""
    qs = dashboard_queries()
    panels = sum(
        len(p.get("targets", []))
        for d in load_dashboards().values()
        for p in iter_panels(d["panels"])
    )
    assert len([q for q in qs if q.kind == "panel"]) == panels >= 20
    for q in qs:
        expr = substitute(q.expr, loop="X")
        assert "$" not in expr, (q.where, expr)
        if q.kind == "variable":
            parse_label_values(expr)


# ------------------------------------------------------------------ every query parses


@pytest.fixture(scope="module")
def empty_prometheus(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Prometheus]:
    """A Prometheus with the shipped rules and nothing to scrape: enough to parse queries."""
    cfg = {"global": {"scrape_interval": "15s", "evaluation_interval": "15s"}}
    with Prometheus(tmp_path_factory.mktemp("prom-empty"), cfg, RULE_FILES) as prom:
        yield prom


@pytest.mark.parametrize("q", dashboard_queries() + rule_queries(), ids=lambda q: q.where)
def test_query_parses_in_prometheus(empty_prometheus: Prometheus, q: Query) -> None:
    empty_prometheus.run_query(q, loop="FIC101")


def test_prometheus_rejects_a_broken_query(empty_prometheus: Prometheus) -> None:
    ans = empty_prometheus.query("sum by (loop (stiction_loop_pv)")
    assert ans["status"] == "error"
    assert ans["errorType"] == "bad_data"


def test_rules_load_into_prometheus(empty_prometheus: Prometheus) -> None:
    groups = empty_prometheus.api("rules")["data"]["groups"]
    names = {r["name"] for g in groups for r in g["rules"]}
    assert len(names) == len(rule_queries())
    assert all(r["health"] != "err" for g in groups for r in g["rules"])


# ------------------------------------------------------------------ docs/dashboards.md


@pytest.mark.parametrize("page", ["docs/dashboards.md", "README.md"])
def test_dashboards_doc_lists_every_panel_and_query(page: str) -> None:
    doc = (REPO / page).read_text()
    for d in load_dashboards().values():
        assert d["title"] in doc
        for panel in iter_panels(d["panels"]):
            assert f"| {panel['title']} |" in doc, panel["title"]
            for t in panel["targets"]:
                assert f"`{t['expr']}`" in doc.replace("\\|", "|"), t["expr"]
