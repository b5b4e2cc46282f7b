"""Issue 23 item 8: what misled a newcomer in the docs and the demo. `make demo` passes
options, the demo prints whole reasons, docs/install.md keeps Debian's Prometheus config
and says the result server must listen where the SCADA reaches it, docs/fleet.md gives the
central server's steps as commands, with the vmauth TLS proxy it names shipped."""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import types
from pathlib import Path

import yaml
from deploy_support import REPO, fake_root, require_tool, run

from gateway.core.store import ResultStore
from plcsim.demo import render_table
from stiction import Assessment, Verdict

CENTRAL = REPO / "deploy" / "fleet" / "central"


def test_make_demo_passes_its_options() -> None:
    make = shutil.which("make")
    assert make is not None
    r = subprocess.run([make, "-n", "demo", "DEMO_ARGS=--duration 7"], cwd=REPO,
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    assert re.search(r"stiction-gateway demo --duration 7$", r.stdout, re.M), r.stdout
    assert 'make demo DEMO_ARGS="--duration 60"' in (REPO / "README.md").read_text()


def test_the_demo_prints_the_whole_reason() -> None:
    reason = ("stiction (confidence 0.97; for: horch, kano, stick_slip, hammerstein); fd "
              "26.9, fs 29.8 % of span, from OP at the PV jumps over 4 cycles (He & Wang "
              "2014); every word of this reason must reach the screen, the last one too: END")
    st = ResultStore(["FIC101"])
    st.set_result(0, Assessment(Verdict.STICTION, reason, fd=0.269, fs=0.298), t=1.7e9,
                  window_fill=1.0, samples=1800)
    gw = types.SimpleNamespace(store=st, config=types.SimpleNamespace(
        gateway=types.SimpleNamespace(time_scale=40.0)))
    out = io.StringIO()
    render_table(gw, 0.0, out)  # type: ignore[arg-type]
    text = out.getvalue()
    assert "..." not in text
    assert " ".join(text.split()).count(reason) == 1  # whole, only wrapped
    assert re.search(r"FIC101 .* stiction +- +26\.9 +29\.8 ", text), text  # % of span


def test_install_keeps_debians_prometheus_config_and_names_the_scada_address() -> None:
    doc = (REPO / "docs" / "install.md").read_text()
    assert not re.search(r"^\s*(install|cp)\b.*deploy/prometheus/prometheus\.yml\s+"
                         r"/etc/prometheus/prometheus\.yml", doc, re.M)
    assert "cp -p /etc/prometheus/prometheus.yml /etc/prometheus/prometheus.yml.orig" in doc
    assert "which the SCADA or DCS cannot\nreach" in doc
    assert "`modbus_server.listen` to the box's\naddress on the control network" in doc


def _central_section() -> str:
    doc = (REPO / "docs" / "fleet.md").read_text()
    return doc[doc.index("### The central server"):doc.index("## Splitting a site")]


def test_the_central_servers_steps_are_commands() -> None:
    section = _central_section()
    commands = [line.strip() for block in re.findall(r"```console\n(.*?)```", section, re.S)
                for line in block.splitlines()]
    for expected in (
            "install -d -m 0755 /etc/vmalert/rules",
            "install -m 0644 deploy/prometheus/rules/*.yml deploy/fleet/central/rules/*.yml "
            "/etc/vmalert/rules/",
            "install -m 0644 deploy/fleet/central/vmalert.service "
            "/etc/systemd/system/vmalert.service",
            "systemctl enable --now vmalert",
            "apt-get install prometheus-alertmanager",
            "systemctl enable --now vmauth"):
        assert any(c.startswith(expected) for c in commands), expected
    for path in re.findall(r"deploy/[\w./*-]+", section):
        assert list(REPO.glob(path.rstrip("."))), path


def test_the_tls_proxy_lets_only_remote_write_through() -> None:
    cfg = yaml.safe_load((CENTRAL / "vmauth.yml").read_text())
    assert cfg["users"]
    for user in cfg["users"]:
        assert user["username"] and user["password"]
        assert [(m["src_paths"], m["url_prefix"]) for m in user["url_map"]] == [
            (["/api/v1/write"], "http://127.0.0.1:8428")]


def test_the_vmauth_unit_verifies(tmp_path: Path) -> None:
    tool = require_tool("systemd-analyze", "systemd")
    unit = CENTRAL / "vmauth.service"
    root = fake_root(tmp_path, unit)
    r = run([tool, "verify", f"--root={root}", unit.name])
    assert r.returncode == 0, r.stdout + r.stderr
    assert not r.stderr.strip(), r.stderr
    assert "-tls" in unit.read_text() and "-auth.config=/etc/vmauth/vmauth.yml" in unit.read_text()
