"""The engineer's findings in the running gateway: read at start and on SIGHUP, and every
verdict the store publishes recorded in the verdict history (:mod:`gateway.core.findings`).

Reading never fails the gateway: a bad row is logged (file, line, what is wrong) and
skipped; a file that cannot be read at all (missing, unreadable, no header) is logged and
the findings read before are kept, so neither a start nor a reload ends in a broken state.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
from collections.abc import Callable

from ..config.findings import FINDINGS, FindingsFile, read_findings
from ..config.model import Config
from ..core.findings import UNKNOWN, FindingsBook
from ..core.store import ResultStore

__all__ = ["MAX_PROBLEMS_LOGGED", "agreement_table", "load_findings", "observe",
           "read_configured", "reload_findings"]

log = logging.getLogger("gateway.findings")
MAX_PROBLEMS_LOGGED = 20


def observe(store: ResultStore, book: FindingsBook) -> FindingsBook:
    """Record in ``book``'s history every assessment ``store`` publishes (and restores);
    returns ``book``."""

    def on_change(i: int) -> None:
        res = store.results[i]
        if res is not None:
            book.record(store.loops[i], res.t, str(res.assessment.verdict))

    store.subscribe(on_change)
    return book


def read_configured(config: Config, today: dt.date | None = None) -> FindingsFile | None:
    """The config's findings file, read and checked (None: the config names none)."""
    if config.findings is None:
        return None
    return read_findings(config.findings, [lp.name for lp in config.loops],
                         today=today or dt.date.today())


def load_findings(book: FindingsBook, read: FindingsFile | None,
                  log_line: Callable[..., None] = log.warning) -> None:
    """Apply a read findings file to ``book``, logging its problems (at most
    :data:`MAX_PROBLEMS_LOGGED` lines) and what was taken."""
    before = book.findings
    book.apply(read)
    if read is None:
        return
    for line in read.problems[:MAX_PROBLEMS_LOGGED]:
        log_line("findings: %s%s", line, "" if not read.readable else " (row skipped)")
    more = len(read.problems) - MAX_PROBLEMS_LOGGED
    if more > 0:
        log_line("findings: and %d more problem(s): stiction-gateway check-config lists them",
                 more)
    if not read.readable:
        log.error("findings: %s not read; %s", read.source,
                  f"keeping the {len(before)} finding(s) read before" if before
                  else "no findings until it can be read (send SIGHUP after fixing it)")
        return
    loops = len({f.loop for f in book.findings})
    log.info("findings: %s: %d finding(s) of %d loop(s)%s", read.source, len(book.findings),
             loops, f", {len(read.problems)} row(s) skipped" if read.problems else "")


async def reload_findings(config: Config, book: FindingsBook) -> None:
    """Read ``config``'s findings again (in a thread, so polls go on) and apply them;
    never raises."""
    try:
        read = await asyncio.to_thread(read_configured, config)
    except Exception:  # a bug: still never the end of the daemon, nor a broken state
        log.exception("findings: reading %s failed; keeping what was read before",
                      config.findings)
        return
    load_findings(book, read)


def agreement_table(config: Config, book: FindingsBook, history_note: str) -> str:
    """What ``stiction-gateway findings`` prints: the agreement of the verdicts on the
    findings' days with the findings, the precision of the ``stiction`` calls, and every
    finding with the verdict it met."""
    view = book.view
    kinds = list(FINDINGS)
    verdicts = sorted({v for v, _f in view.counts}, key=lambda v: (v == UNKNOWN, v))
    width = max([len("verdict on the day"), *map(len, verdicts)])
    loops = len({f.loop for f in book.findings})
    lines = [f"{config.findings}: {len(book.findings)} finding(s) of {loops} loop(s); "
             f"{history_note}", ""]
    head = "".join(f"{k:>10}" for k in [*kinds, "total"])
    lines.append(f"{'verdict on the day':<{width}}{head}")
    for v in verdicts:
        row = [view.counts.get((v, k), 0) for k in kinds]
        lines.append(f"{v:<{width}}" + "".join(f"{n:>10}" for n in [*row, sum(row)]))
    col = [sum(view.counts.get((v, k), 0) for v in verdicts) for k in kinds]
    lines.append(f"{'total':<{width}}" + "".join(f"{n:>10}" for n in [*col, sum(col)]))
    calls = sum(view.counts.get(("stiction", k), 0) for k in kinds)
    hit = view.counts.get(("stiction", "stiction"), 0)
    found = col[kinds.index("stiction")]
    lines.append("")
    lines.append(f"`stiction` calls the crew found sticking: {hit} of {calls}"
                 + (f" ({100 * hit / calls:.0f} %)" if calls else "")
                 + f"; sticking valves the gateway had called: {hit} of {found}"
                 + (f" ({100 * hit / found:.0f} %)" if found else ""))
    compared = book.compared()
    if compared:
        lines += ["", f"{'loop':<16} {'date':<10} {'finding':<9} {'fd %':>5} {'fs %':>5} "
                      f"{'verdict that day':<20} by, note"]
    for f, verdict in compared:
        fd = "" if f.fd is None else f"{f.fd:g}"
        fs = "" if f.fs is None else f"{f.fs:g}"
        who = ", ".join(x for x in (f.by, f.note) if x)
        lines.append(f"{f.loop:<16} {f.date.isoformat():<10} {f.finding:<9} {fd:>5} {fs:>5} "
                     f"{verdict:<20} {who}".rstrip())
    return "\n".join(lines) + "\n"
