"""``python -m bench corpus``: the old name of ``python -m lab corpus`` (lab/commands.py)."""

from __future__ import annotations

from lab.commands import corpus


def main() -> None:
    corpus()
