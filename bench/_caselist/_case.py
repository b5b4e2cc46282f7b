"""The case files' one helper: ``@case(issue, finding)`` registers a function; running the
file as ``python FILE NAME`` calls it and prints its answer as one JSON line, ``--list``
prints the cases. A case returns ``(said, ok)``: what the tree answered in a few words and
whether it is what the finding asks for. Case files import only ``stiction``, ``gateway``,
``plcsim`` (the tree under test, first on PYTHONPATH), numpy and the standard library."""

from __future__ import annotations

import contextlib
import io
import json
from collections.abc import Callable
from pathlib import Path

SHARED = Path(__file__).resolve().parents[3] / "shared"
"""../shared beside the checkout (the data of the development records)."""
REPO = Path(__file__).resolve().parents[2]
"""This checkout (the cases' own files; the tree under test is on PYTHONPATH)."""

Case = Callable[[], tuple[str, bool]]
_CASES: dict[str, tuple[str, str, Case]] = {}


def case(issue: str, finding: str) -> Callable[[Case], Case]:
    def register(fn: Case) -> Case:
        _CASES[fn.__name__] = (issue, finding, fn)
        return fn
    return register


def run(argv: list[str]) -> None:
    if argv[:1] == ["--list"]:
        for name, (issue, finding, _) in _CASES.items():
            print(json.dumps([name, issue, finding]))
        return
    (name,) = argv
    said, ok = _CASES[name][2]()
    print(json.dumps({"said": said, "ok": bool(ok)}))


def cli(*argv: str) -> tuple[int, str, str]:
    """`stiction ARGV` as a user runs it: exit status, stdout, stderr."""
    from stiction.cli import main  # noqa: PLC0415

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv))
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()
