"""A bad config file is refused before anything opens: ``check-config`` and ``run`` print
every problem (the golden case tests/cases/bad-file) and exit 2, binding no port."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from gateway.cli import main

CASE = Path(__file__).resolve().parents[1] / "cases" / "bad-file"


@pytest.mark.parametrize("command", ["check-config", "run"])
def test_bad_file_is_refused_listing_every_problem(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str) -> None:
    path = tmp_path / "gateway.yaml"
    path.write_text((CASE / "gateway.yaml").read_text())
    argv = ["check-config", str(path)] if command == "check-config" else \
        ["run", "--config", str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    expected = (CASE / "expected.err").read_text().strip().splitlines()
    assert err == [line.replace("gateway.yaml", str(path), 1) for line in expected]


def test_no_port_is_bound_by_a_refused_start(tmp_path: Path) -> None:
    """Start-up with a bad file stops before opening anything: the ports stay free."""
    path = tmp_path / "bad.yaml"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = int(s.getsockname()[1])
    text = (CASE / "gateway.yaml").read_text()
    path.write_text(text.replace('modbus_server: {listen: "127.0.0.1:0"}',
                                 f'modbus_server: {{listen: "127.0.0.1:{port}"}}'))
    assert f"127.0.0.1:{port}" in path.read_text()
    assert main(["run", "--config", str(path)]) == 2
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))  # would fail if the gateway had bound it
