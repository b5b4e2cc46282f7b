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
from collections.abc import Callable, Mapping

from ..config.findings import FINDINGS, FindingsFile, read_findings
from ..config.model import Config
from ..core.findings import UNKNOWN, FindingsBook
from ..core.store import ResultStore

__all__ = ["MAX_PROBLEMS_LOGGED", "agreement_table", "before_after", "load_findings",
           "observe", "precision", "read_configured", "reload_findings"]

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
    lines += ["", precision(view.counts)]
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
    lines += before_after(book)
    return "\n".join(lines) + "\n"


def precision(counts: Mapping[tuple[str, str], int]) -> str:
    """How often a `stiction` call was confirmed, and how many of the sticking valves found
    had been called: counted only where a verdict existed on the finding's day (issue 38
    item 12: "0 of 1 (0 %)" read as a miss where the gateway had not yet judged the loop)."""
    calls = sum(n for (v, _k), n in counts.items() if v == "stiction")
    hit = counts.get(("stiction", "stiction"), 0)
    found = sum(n for (_v, k), n in counts.items() if k == "stiction")
    unknown = counts.get((UNKNOWN, "stiction"), 0)
    judged = found - unknown
    first = (f"`stiction` calls the crew found sticking: {hit} of {calls} "
             f"({100 * hit / calls:.0f} %)" if calls else
             "`stiction` calls the crew found sticking: no `stiction` verdict on a finding's day")
    second = (f"sticking valves the gateway had called: {hit} of {judged} "
              f"({100 * hit / judged:.0f} %)" if judged else
              "sticking valves the gateway had called: none to count" if not found else
              "sticking valves the gateway had called: no verdict existed on their day")
    if unknown and judged:
        second += (f", and {unknown} found where no verdict existed that day (before the "
                   "gateway's history of the loop: not counted)")
    elif unknown:
        second += f" ({unknown} found before the gateway's history of the loop)"
    return f"{first}; {second}"


def before_after(book: FindingsBook, most: int = 3) -> list[str]:
    """Per finding, the verdict of its valve before (on the finding's day) and after (from
    the next day on: each change, at most ``most``, and the latest): did the repair clear
    the call, did stiction come back? From the verdict history."""
    if not book.findings:
        return []
    lines = ["", "before and after each finding (the verdict on its day; the verdicts since, "
                 "from the next day on):",
             f"{'loop':<16} {'date':<10} {'finding':<9} {'before':<20} after"]
    history = book.history
    for f, before in book.compared():
        h = history.loops.get(f.loop)
        day = f.date.toordinal()
        if h is None or not h.days or history.day_of(h.t) <= day:
            after = "no verdict since"
        else:
            changes = [(d, v) for d, v in zip(h.days, h.verdicts, strict=True) if d > day + 1]
            first = history.verdict_on(f.loop, f.date + dt.timedelta(days=1))
            steps = [f"{first} the next day"]
            steps += [f"{v} from {dt.date.fromordinal(d).isoformat()}"
                      for d, v in changes[:most]]
            if len(changes) > most:
                steps.append(f"{len(changes) - most} change(s) more")
            seq = [first, *(v for _d, v in changes), h.verdict]
            cleared = next((k for k, v in enumerate(seq) if v != "stiction"), None)
            came_back = f.finding in ("stiction", "deadband") and cleared is not None \
                and "stiction" in seq[cleared:]
            after = ", ".join(steps) + f"; now {h.verdict}" + (
                " (stiction came back)" if came_back else "")
        lines.append(f"{f.loop:<16} {f.date.isoformat():<10} {f.finding:<9} {before:<20} "
                     f"{after}")
    return lines
