"""What reading an export and analysing it hold in memory, checked against what the machine
has free before the work starts, so that a year of 1 s samples is refused with the way round
it instead of swapping the box to a halt.

Measured (``python -m bench cli_reading``; a three-column ``stiction simulate --historian``
export of about 37 bytes a row): reading holds at its peak about :data:`READ_BYTES_PER_ROW`
bytes a row (the time column's text for messages, 8 bytes per number and per time stamp, the
grid's work; about four times the file), and keeps about 85 once read; the analysis of one
window then holds about :data:`ANALYSIS_BYTES_PER_SAMPLE` bytes a sample at its peak (the
detectors' spectra, fits and copies). A window of a week at 1 s (604,800 samples) thus needs
about 200 MB; a year at 1 s (31.5 million) about 10 GB in one verdict, or a day's worth at a
time with ``--every 1d``.
"""

from __future__ import annotations

import os
from pathlib import Path

from ._common import UsageError

__all__ = ["ANALYSIS_BYTES_PER_SAMPLE", "READ_BYTES_PER_ROW", "affordable", "available",
           "readable"]

READ_BYTES_PER_ROW = 150
"""Reading's peak per row of a three-column export (more columns: about 10 bytes more each)."""
ANALYSIS_BYTES_PER_SAMPLE = 320
"""The analysis' peak per sample of the window judged (measured 260-330 from 0.2 to 1.8
million samples)."""
_GB = 1e9


def available() -> int | None:
    """Bytes this process may still take: the system's available memory, within the
    cgroup's limit where one is set (a container, a systemd unit's ``MemoryMax=``); None
    where neither can be read."""
    free = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    free = int(line.split()[1]) * 1024
                    break
    except OSError:
        try:
            free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            free = None
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            room = int(limit) - used
            free = room if free is None else min(free, room)
    except (OSError, ValueError):
        pass
    return free


def _rows(path: Path) -> int:
    """About how many rows the file holds, from its size and its first lines' length."""
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(1 << 16)
    lines = max(head.count(b"\n"), 1)
    return int(size / max(len(head) / lines, 1.0))


def readable(path: Path) -> None:
    """Refuse a file whose reading would take more memory than is free."""
    try:
        rows = _rows(path)
    except OSError:
        return  # the reader says what is wrong with the file
    free = available()
    need = rows * READ_BYTES_PER_ROW
    if free is not None and need > free:
        raise UsageError(
            f"{path}: about {rows:,} rows: reading them needs about {need / _GB:.1f} GB "
            f"({READ_BYTES_PER_ROW} bytes a row), more than the {free / _GB:.1f} GB free; "
            "export a shorter stretch, or at a longer sample time")


def affordable(samples: int, ts: float, path: Path) -> None:
    """Refuse a window whose analysis would take more memory than is free, naming the way
    round: one verdict per day (``--every 1d``) or a stretch (``--from``/``--to``)."""
    free = available()
    need = samples * ANALYSIS_BYTES_PER_SAMPLE
    if free is not None and need > free:
        days = samples * ts / 86_400.0
        raise UsageError(
            f"{path}: one window of {samples:,} samples ({days:.3g} days at {ts:g} s): its "
            f"analysis needs about {need / _GB:.1f} GB ({ANALYSIS_BYTES_PER_SAMPLE} bytes a "
            f"sample), more than the {free / _GB:.1f} GB free; give --every 1d (a verdict per "
            "day) or --from/--to (one stretch)")
