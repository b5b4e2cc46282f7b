"""The text of ``stiction analyze``: the table of a batch, one line per loop (or per window
of ``--every``), with the reason in short and what each verdict shown means; and numbers as an
engineer reads them (:func:`number`: a week's period is ``75680 s``, not ``7.568e+04``)."""

from __future__ import annotations

import dataclasses
import re
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from .._assessment import Verdict

__all__ = ["Row", "duration", "legend", "number", "short_reason", "table"]


@dataclasses.dataclass(frozen=True)
class Row:
    """One file of the batch, or one window of a file (``--every``: its first and last
    samples' stamps): what ``--json`` shows of it alone, or why it was not analysed."""

    file: Path | str
    shown: Mapping[str, Any] | None = None
    error: str | None = None
    window: tuple[str, str] | None = None
    analysed: Any = dataclasses.field(default=None, repr=False, compare=False)
    """The file's analysis (:class:`.loop.Analysed`), for the ranking's calibration and the
    meeting's page."""

    def to_dict(self) -> dict[str, Any]:
        """The JSON array's object: ``file`` (and ``from``, ``to``) and the single-file
        ``--json`` keys, or ``file`` and ``error``."""
        head: dict[str, Any] = {"file": str(self.file)}
        if self.window is not None:
            head.update({"from": self.window[0], "to": self.window[1]})
        if self.shown is None:
            return {**head, "error": self.error}
        return {**head, **self.shown}


_OPENING = re.compile(r"^(?:stiction|not stiction|undetermined), confidence(?: of stiction)? "
                      r"\d+\.\d+(?:[.:,]\s*|$)")
_DETAIL = re.compile(r"(?:Tests: .*?|Weighed most in the decision: .*?|Nothing weighed much "
                     r"either way in the decision|No test ran)\.(?=\s+[A-Z]|\s*$)\s*")
_TESTS = re.compile(r"Tests: .*?\.(?=\s+[A-Z]|\s*$)")


def short_reason(reason: str) -> str:
    """The reason without its opening (the verdict and confidence, columns of their own) and
    without what each test voted and what weighed most (the evidence, in full in --json and
    --csv); what is left says the rest: the size, the caveats ("too fast to see its shape:
    sample faster"), the stretch to analyse alone. A reason that is nothing but the tests
    keeps what they voted."""
    text = _OPENING.sub("", reason)
    text = re.sub(r"^but ", "", text)
    short = _DETAIL.sub("", text).strip()
    if short:
        return short
    tests = _TESTS.search(text)
    return tests.group(0) if tests else text.strip()


def number(x: float, digits: int = 4) -> str:
    """``x`` to ``digits`` significant digits, without an exponent from 0.001 up to a
    million (``75680``, not ``7.568e+04``)."""
    text = f"{x:.{digits}g}"
    if "e" in text and 1e-3 <= abs(x) < 1e6:
        return f"{x:.0f}" if abs(x) >= 1 else f"{x:.{digits}f}".rstrip("0")
    return text


def duration(seconds: float) -> str:
    """A period as seconds, and in minutes, hours or days where it is that long."""
    text = f"{number(seconds)} s"
    for unit, size in (("d", 86_400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{text} ({seconds / size:.3g} {unit})"
    return text


def _cells(row: Row, files: bool, ranked: bool) -> list[str]:
    rank = [str((row.shown or {}).get("rank", "-"))] if ranked else []
    lead = rank + ([str(row.file)] if files else []) + (list(row.window) if row.window else [])
    if row.shown is None:
        error = row.error or ""
        prefix = f"{row.file}: "
        return [*lead, "error", "-", "-", "-", "-", "-",
                error[len(prefix):] if error.startswith(prefix) else error]
    s = row.shown
    size = s.get("size") or {}

    def num(x: Any) -> str:
        return "-" if x is None else number(x, 3)

    period = "-" if s.get("period_s") is None else f"{s['period_s']:.0f} s"
    conf = "-" if s.get("confidence") is None else f"{s['confidence']:.2f}"
    return [*lead, str(s["verdict"]), conf, num(size.get("fd")), num(size.get("fs")),
            size.get("unit", "-"), period, short_reason(str(s["reason"]))]


def table(rows: Sequence[Row], *, width: int | None = None) -> str:
    """One line per loop (per window with ``--every``: its first and last stamps) under a
    header, columns aligned, the reason in short (:func:`short_reason`); on a terminal
    (``width``) the reason wraps onto lines of its own under its column, else it runs on.
    The file is left out where every row is a window of one file; a batch ranked worst first
    (:mod:`.ranking`) has its rank in a first column ``#``."""
    windows = any(r.window is not None for r in rows)
    files = not windows or len({str(r.file) for r in rows}) > 1
    ranked = any(r.shown is not None and "rank" in r.shown for r in rows)
    head = [*(["#"] if ranked else []), *(["file"] if files else []),
            *(["from", "to"] if windows else []),
            "verdict", "conf", "fd", "fs", "unit", "period", "reason"]
    lines = [head, *(_cells(r, files, ranked) for r in rows)]
    widths = [max(len(line[j]) for line in lines) for j in range(len(head) - 1)]
    lead = len(head) - 7  # the file and the window's columns
    left = {*range(lead + 1), lead + 4}
    indent = sum(widths) + 2 * len(widths)
    room = None if width is None else max(30, width - indent - 1)
    out = []
    for line in lines:
        cells = [c.ljust(w) if j in left else c.rjust(w)
                 for j, (c, w) in enumerate(zip(line, widths, strict=False))]
        parts = [line[-1]] if room is None else textwrap.wrap(line[-1], room) or [""]
        out.append("  ".join([*cells, parts[0]]).rstrip())
        out += [" " * indent + p for p in parts[1:]]
    return "\n".join(out)


def legend(rows: Iterable[Row]) -> list[str]:
    """What each verdict in the table means (:attr:`stiction.Verdict.advice`), each once."""
    shown = dict.fromkeys(str(r.shown["verdict"]) for r in rows if r.shown is not None)
    return ["what each verdict means:", *(f"  {v}: {Verdict(v).advice}" for v in shown)] \
        if shown else []
