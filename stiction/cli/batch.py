"""``stiction analyze a.csv b.csv ...`` or ``--manifest LIST``: a whole unit in one command.

Every file is analysed as ``stiction analyze FILE`` analyses it alone (:func:`.loop.
analyze_file`, the same options, the same dict :func:`.loop.view`); a file that cannot be
read, or a manifest row that cannot be used, is listed with its error and the others are
analysed. Outputs: one row per loop on a terminal (file, verdict, confidence, fd, fs, unit,
period, the reason in short), ``--json`` one JSON array of each file's ``--json`` object with
its ``file`` (``{"file": ..., "error": ...}`` for a file not analysed), ``--csv OUT`` the
same objects flattened for a spreadsheet (:func:`flatten`), ``--plot DIR`` one PNG per file.
Exit 0 if any loop was analysed, else 2; the errors are counted on stderr, and a progress
bar runs there when it is a terminal."""

from __future__ import annotations

import argparse
import csv
import json
import re
import shutil
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

from .._errors import ParameterError, StictionError
from . import ranking, site
from ._common import UsageError, param_option, pyplot
from .every import every
from .loop import LoopOptions, analyze_file
from .manifest import COLUMNS, Loop, read_manifest
from .plot import plot_analysis
from .report import Row, legend, short_reason, table

__all__ = ["COLUMNS", "Row", "flatten", "run", "short_reason", "spreadsheet_text", "table",
           "write_csv"]


def run(args: argparse.Namespace) -> int:
    """The batch: every file of the command line, then every loop of ``--manifest``; with
    ``--every``, every window of each."""
    base = LoopOptions.from_args(args)
    loops = [Loop(str(p), p, base) for p in args.files]
    if args.manifest is not None:
        loops += read_manifest(args.manifest, base)
    if args.csv is not None and not args.csv.parent.is_dir():
        raise UsageError(f"--csv {args.csv}: no folder {args.csv.parent}")
    if args.every is not None and args.plot is not None:
        raise UsageError("--plot draws one window: give --from/--to for the one to draw "
                         "instead of --every")
    plots = None if args.plot is None else _plot_names(args.plot, loops)
    bar = Progress(len(loops)) if sys.stderr.isatty() else None
    rows: list[Row] = []
    notes: list[str] = []
    for i, loop in enumerate(loops):
        if bar is not None:
            bar.show(i, loop.label)
        got, said = _one(loop, None if plots is None else plots[i], args.every)
        rows += got
        notes += said if len(loops) == 1 else []
    if bar is not None:
        bar.clear()
    rows, adapted = site.adapt_rows(rows, args)  # at the batch's share of sticky valves
    rows, said = ranking.finish(rows, loops, args)  # worst first, --findings, --report
    ranking.warn([*([adapted] if adapted else []), *said])
    if args.json:
        print(json.dumps([r.to_dict() for r in rows]))
    else:
        tty = sys.stdout.isatty()
        print(table(rows, width=shutil.get_terminal_size((120, 24)).columns if tty else None))
        print("\n".join([*legend(rows), *(f"warning: {n}" for n in notes)]))
    if args.csv is not None:
        write_csv(args.csv, rows)
    for done in (args.plot, args.csv, args.report):
        if done is not None and not args.json:
            print(f"wrote {done}")
    failed = sum(r.error is not None for r in rows)
    if failed == len(rows):
        print(f"stiction: error: none of {len(rows)} files analysed", file=sys.stderr)
        return 2
    if failed:
        print(f"stiction: {failed} of {len(rows)} files not analysed (their errors are listed)",
              file=sys.stderr)
    return 0


def _one(loop: Loop, plot: Path | None, length: float | None) -> tuple[list[Row], list[str]]:
    """One loop analysed (every window of it with ``length``), or its error (the message
    ``stiction analyze FILE`` would print); and the notes of reading it, once."""
    if loop.error is not None:
        return [Row(loop.label, error=loop.error)], []
    try:
        if length is not None:
            windows, notes = every(loop.path, loop.options, length)
            return [Row(loop.label, w.analysed.shown, window=(w.start, w.stop))
                    for w in windows], notes
        got = analyze_file(loop.path, loop.options)
        if plot is not None:
            plot_analysis(plot, got.details, got.ts, got.op_range, got.clock)
    except ParameterError as exc:
        return [Row(loop.label, error=f"{param_option(exc.name)}: {exc}")], []
    except (UsageError, StictionError) as exc:
        return [Row(loop.label, error=str(exc))], []
    except Exception as exc:  # a bug on one file: the unit's other loops are still analysed
        return [Row(loop.label, error=f"internal error ({type(exc).__name__}: {exc}); please "
                                      "report it with this file")], []
    return [Row(loop.label, got.shown, analysed=got)], []


def _plot_names(folder: Path, loops: Sequence[Loop]) -> list[Path]:
    """One PNG per file in ``folder`` (made if missing), named by the file's stem; a stem
    that repeats gets ``-2``, ``-3``, ..."""
    pyplot()  # refused now, not after the files, when matplotlib is missing
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"--plot {folder}: with several files, --plot names a folder (one "
                         "PNG per file); this is a file")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--plot {folder}: cannot make the folder: {exc.strerror or exc}"
                         ) from exc
    seen: dict[str, int] = {}
    out = []
    for loop in loops:
        stem = loop.path.stem if loop.error is None else "error"
        seen[stem] = seen.get(stem, 0) + 1
        out.append(folder / (f"{stem}.png" if seen[stem] == 1 else f"{stem}-{seen[stem]}.png"))
    return out


class Progress:
    """A progress bar on stderr (a terminal), overwritten in place and cleared at the end."""

    WIDTH = 24

    def __init__(self, total: int, stream: TextIO | None = None) -> None:
        self.total = total
        self.stream = sys.stderr if stream is None else stream
        self.last = 0

    def show(self, done: int, label: str) -> None:
        filled = self.WIDTH * done // max(self.total, 1)
        text = f"analysing {done + 1:>{len(str(self.total))}}/{self.total} " \
               f"[{'#' * filled}{'.' * (self.WIDTH - filled)}] {label}"[:119]
        self.stream.write("\r" + text.ljust(self.last))
        self.stream.flush()
        self.last = len(text)

    def clear(self) -> None:
        self.stream.write("\r" + " " * self.last + "\r")
        self.stream.flush()


# --------------------------------------------------------------------------- the CSV
FIRST = ("file", "error", "verdict", "confidence", "size.unit", "size.fd", "size.fs",
         "size.jump", "period_s", "reason")
"""The CSV's first columns, always there; the other keys follow as they first appear."""


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """A ``--json`` object as one spreadsheet row: nested objects as ``size.fd``,
    ``weighed.kano``, ``stretch.from``; the evidence by test as ``evidence.kano.value``,
    ``.vote``, ``.note``; a list of texts (the warnings) joined by `` | ``; an object that
    is null (no size, no stretch) leaves its columns empty."""
    out: dict[str, Any] = {}
    for key, value in d.items():
        name = prefix + key
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        elif key == "evidence" and isinstance(value, list):
            for e in value:
                out.update(flatten({k: v for k, v in e.items() if k != "test"},
                                   f"{name}.{e['test']}."))
        elif isinstance(value, list):
            out[name] = " | ".join(str(v) for v in value)
        elif value is not None or key not in ("size", "stretch"):
            out[name] = value
    return out


FORMULA_FIRST = ("=", "+", "-", "@", "\t", "\r")
"""A cell whose text starts with one of these a spreadsheet may evaluate as a formula (OWASP,
"CSV injection"); written after an apostrophe, as text, unless it is a plain number."""
_PLAIN_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def spreadsheet_text(text: str) -> str:
    """``text`` as a spreadsheet shows it without evaluating it: one that starts like a
    formula (:data:`FORMULA_FIRST`) gets a leading apostrophe, the mark of a text cell; a
    plain number (``-0.25``, ``+3``, ``-1e-05``) stays a number."""
    if text[:1] in FORMULA_FIRST and _PLAIN_NUMBER.fullmatch(text) is None:
        return "'" + text
    return text


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return spreadsheet_text(repr(value) if isinstance(value, float) else str(value))


def write_csv(path: Path, rows: Sequence[Row]) -> None:
    """The rows flattened (:func:`flatten`) to ``path``: UTF-8 with a byte-order mark, as a
    spreadsheet reads it; floats written in full (``repr``), null and absent keys empty,
    a text that a spreadsheet would evaluate written as text (:func:`spreadsheet_text`)."""
    flat = [flatten(r.to_dict()) for r in rows]
    columns = list(FIRST)
    if any(r.window is not None for r in rows):
        columns[2:2] = ["from", "to"]
    for f in flat:
        columns += [k for k in f if k not in columns]
    try:
        with path.open("w", newline="", encoding="utf-8-sig") as fh:
            w = csv.writer(fh)
            w.writerow([spreadsheet_text(c) for c in columns])
            w.writerows([_cell(f.get(c)) for c in columns] for f in flat)
    except OSError as exc:
        raise UsageError(f"--csv {path}: cannot write: {exc.strerror or exc}") from exc
