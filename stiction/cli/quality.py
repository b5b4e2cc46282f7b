"""Quality columns of an export: the historian's own word on each sample (PHD's
``Confidence``, OPC's ``Quality`` code, a ``Good``/``Bad`` text), so that a sample it marks bad
is a gap, not data (a PV that reads 0 for the half hour its transmitter was lost is no
reading of the process).

A column is a quality column by its name: ``Quality``, ``QualityDetail``, ``OPCQuality`` or
``Confidence``, alone or after the name of the column it qualifies (``FIC101.PV Quality``,
``FIC101.PV_Confidence``). One named after a column qualifies that column;
one named by the word alone qualifies the column just left of it (PHD and most exports write
each value, then its quality). A sample is bad (:func:`bad`) where its quality cell says
``Bad...`` (any case), or where its number is:

* under ``Confidence`` (PHD, 0-100): 0 or below;
* under a quality column whose numbers exceed 255: an OPC UA status code of severity bad
  (2^31 and above, or negative as a signed 32-bit number);
* under one whose numbers reach 64 but not 255: an OPC DA quality code below 64 (192 good, 64
  to 191 uncertain: kept);
* under one whose numbers all stay below 64: any but 0 (Wonderware's ``Quality``, 0 good).
"""

from __future__ import annotations

import collections
import re
from collections.abc import Sequence

import numpy as np

from .table import Table

__all__ = ["bad", "is_quality", "of"]

_WORD = r"(?:qualitydetail|opcquality|quality|confidence)"
_NAME = re.compile(rf"^(?:(?P<of>.+?)[._ /:-])?(?P<word>{_WORD})$", re.IGNORECASE)
OPC_UA_BAD = 2 ** 31
OPC_DA_GOOD = 64


def _parts(name: str) -> tuple[str | None, str] | None:
    """``(the column it names or None, its word)`` of a quality column's name, else None."""
    m = _NAME.match(name.strip())
    return None if m is None else (m["of"], m["word"].casefold())


def is_quality(name: str) -> bool:
    """Whether a column of this name is a quality column."""
    return _parts(name) is not None


def of(header: Sequence[str], col: int) -> int | None:
    """The quality column of column ``col``: one named after it, else a quality column named
    by its word alone just right of it; None when it has none."""
    name = header[col].strip().casefold()
    if is_quality(name):
        return None
    for j, h in enumerate(header):
        got = _parts(h)
        if got is not None and got[0] is not None and got[0].strip().casefold() == name:
            return j
    nxt = col + 1
    if nxt < len(header) and (got := _parts(header[nxt])) is not None and got[0] is None:
        return nxt
    return None


def bad(table: Table, q: int) -> tuple[np.ndarray, str]:
    """The rows whose quality (column ``q``) is bad, and what said so, for the note."""
    word = (_parts(table.header[q]) or (None, "quality"))[1]
    values = np.full(table.size, np.nan)
    texts = np.zeros(table.size, dtype=bool)
    said: collections.Counter[str] = collections.Counter()
    i = 0
    for part in table.cells(q).chunks():
        for cell in part:
            c = cell.strip()
            try:
                values[i] = float(c)
            except ValueError:
                if c.casefold().startswith("bad"):
                    texts[i] = True
                    said[c] += 1
            i += 1
    numeric, rule = _numeric(values, word)
    name = table.header[q]
    parts = [f"{c!r} {n}" for c, n in said.most_common(3)]
    if numeric.any():
        parts.append(f"{int(numeric.sum())} {rule}")
    return texts | numeric, f"column {name!r}: " + ", ".join(parts)


def _numeric(values: np.ndarray, word: str) -> tuple[np.ndarray, str]:
    """The rows whose quality number is bad, and the rule that says so."""
    x = np.nan_to_num(values, nan=0.0)
    finite = np.isfinite(values)
    if word == "confidence":
        return finite & (x <= 0), "with confidence 0 or below (PHD: bad)"
    top = float(np.nanmax(np.abs(values))) if finite.any() else 0.0
    if top > 255:
        return finite & ((x >= OPC_UA_BAD) | (x < 0)), "of OPC UA status bad (2^31 or above)"
    if top >= OPC_DA_GOOD:
        return finite & (x < OPC_DA_GOOD), f"of OPC quality below {OPC_DA_GOOD} (bad)"
    return finite & (x != 0), "of quality other than 0 (0 is good)"
