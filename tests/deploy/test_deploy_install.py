"""docs/install.md, followed step by step: every command of its ```sh blocks (the steps that
need no systemd and no root) runs here, in order, with /opt, /etc and /var/lib moved into a
temporary directory. The ```console blocks (systemctl, journalctl, apt-get, a running
service) are the parts this cannot do; tests/deploy/test_deploy_static.py verifies the unit.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from deploy_support import REPO, require, run

DOC = REPO / "docs" / "install.md"
MOVED = ("/opt/stiction-gateway", "/etc/stiction-gateway", "/var/lib/stiction-gateway")


def doc_commands() -> list[str]:
    """The shell commands of the page's ```sh blocks, in order (comments dropped)."""
    out: list[str] = []
    for block in re.findall(r"^```sh\n(.*?)^```", DOC.read_text(), re.S | re.M):
        for raw in block.splitlines():
            line = raw.split(" #", 1)[0].strip()
            if line and not line.startswith("#"):
                out.append(line)
    return out


def test_install_page_has_the_expected_steps() -> None:
    """Guards the test below against silently running a shorter page."""
    cmds = doc_commands()
    assert [c.split()[0] for c in cmds] == [
        "python3",  # pip wheel
        "python3",  # venv
        "/opt/stiction-gateway/bin/pip",
        "/opt/stiction-gateway/bin/stiction-gateway",  # --help
        "install",
        "install",
        "sed",
        "/opt/stiction-gateway/bin/stiction-gateway",  # check-config
        "install",  # the unit file
    ]


def _checkout(dest: Path) -> Path:
    """A copy of the repository's tracked files (what a user has after `git clone`)."""
    files = subprocess.run(
        ["git", "-C", str(REPO), "ls-files", "-z"], capture_output=True, check=True
    ).stdout.split(b"\0")
    for name in filter(None, files):
        src = REPO / name.decode()
        if src.is_file():
            (dest / name.decode()).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name.decode())
    return dest


def _require_gateway_cli() -> Path:
    """The page needs two things from the gateway branch: configs/example.yaml and the
    check-config command."""
    gw = Path(sys.executable).parent / "stiction-gateway"
    require((REPO / "configs" / "example.yaml").is_file(), "configs/example.yaml not there yet")
    r = run([str(gw), "check-config", "--help"])
    require(r.returncode == 0, "stiction-gateway has no check-config command yet")
    return gw


@pytest.mark.slow
def test_follow_the_install_page(tmp_path: Path) -> None:
    _require_gateway_cli()
    root = tmp_path / "root"
    checkout = _checkout(tmp_path / "stiction-gateway")
    for d in MOVED:
        (root / d.lstrip("/")).parent.mkdir(parents=True, exist_ok=True)
    (root / "etc/systemd/system").mkdir(parents=True)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    for step in doc_commands():
        cmd = step
        for d in (*MOVED, "/etc/systemd/system"):
            cmd = cmd.replace(d, f"{root}{d}")
        # python3 = a Python >= 3.11 with pip: the one running the tests
        cmd = re.sub(r"^python3 ", f"{shlex.quote(sys.executable)} ", cmd)
        r = run(["bash", "-euo", "pipefail", "-c", cmd], timeout=240, cwd=checkout, env=env)
        assert r.returncode == 0, f"{cmd}\n{r.stdout}\n{r.stderr}"

    # what the steps left behind is what the service expects
    assert (root / "opt/stiction-gateway/bin/stiction-gateway").is_file()
    cfg = yaml.safe_load((root / "etc/stiction-gateway/gateway.yaml").read_text())
    assert cfg["gateway"]["state_file"] == f"{root}/var/lib/stiction-gateway/gateway.state"
    unit = (root / "etc/systemd/system/stiction-gateway.service").read_text()
    assert (
        "ExecStart=/opt/stiction-gateway/bin/stiction-gateway run"
        " --config /etc/stiction-gateway/gateway.yaml" in unit
    )


@pytest.mark.slow
def test_check_config_refuses_a_broken_config(tmp_path: Path) -> None:
    """The install page promises check-config names the problem and exits non-zero."""
    gw = _require_gateway_cli()
    example = (REPO / "configs" / "example.yaml").read_text()
    bad = tmp_path / "gateway.yaml"
    bad.write_text(example.replace("poll_interval_s", "poll_intervall_s", 1))
    r = run([str(gw), "check-config", str(bad)])
    assert r.returncode != 0
    assert "poll_intervall_s" in r.stdout + r.stderr
