"""The library's face: the names ``stiction`` promises (the API the gateway, the CLI and
users build on) are all there and documented, whatever the rooms behind them."""

from __future__ import annotations

import subprocess
import sys

import stiction

PROMISED = {"Assessment", "ChoudhuryValve", "Evidence", "HeValve", "KanoValve",
            "ParameterError", "PhysicalParams", "PhysicalValve", "Sizes", "StictionError",
            "ValveModel", "Verdict", "analyze", "k_from_physical"}


def test_the_public_names_are_there_and_documented() -> None:
    assert set(stiction.__all__) == PROMISED
    for name in stiction.__all__:
        assert (getattr(stiction, name).__doc__ or "").strip(), f"stiction.{name}"


def test_the_cli_runs_as_a_module_and_as_a_command() -> None:
    out = subprocess.run([sys.executable, "-m", "stiction.cli", "--help"], capture_output=True,
                         text=True, check=True, timeout=60).stdout
    assert out.startswith("usage: stiction") and "analyze" in out and "reproduce" in out
