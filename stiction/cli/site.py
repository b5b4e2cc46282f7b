"""Site adaptation of a batch (issue 36): the files of one ``stiction analyze`` command (or
``--manifest``) are one site's loops, an unlabelled sample of how common sticky valves are
there. Label-shift EM over the OP-PV shape network's probabilities of their windows
(:func:`stiction.diagnosis.adapt.site_of`) estimates that share, and every file is called
again at it (:func:`stiction.diagnosis.adapt.adapt`). ``--no-site`` scores each file alone,
at the simulation's share; so is a single file, always (one window moves the share by a
tenth at most), and each window of ``--every`` (one loop over time is not a site). The
text output and ``--json`` say which (``site``)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from ..diagnosis.adapt import adapt, site_of
from .loop import rejudged

__all__ = ["ALONE", "adapt_rows", "add_option", "said"]

ALONE = ("scored without site adaptation: one file alone, at the simulation's share of "
         "sticky valves (several files or --manifest adapt to their site's)")


def add_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--no-site", dest="site", action="store_false",
                   help="several files: score each alone, at the simulation's share of "
                   "sticky valves, instead of at the share the files' own windows imply "
                   "(site adaptation, the default; docs/accuracy.md)")


def adapt_rows(rows: Sequence[Any], args: argparse.Namespace) -> tuple[list[Any], str | None]:
    """The batch's rows called again at their site's share; the line that says so (None:
    not adapted, and why is in each row)."""
    if not getattr(args, "site", True) or getattr(args, "every", None) is not None:
        return list(rows), None
    analysed = [r.analysed.assessment for r in rows if r.analysed is not None]
    site = site_of(analysed)
    if len(analysed) < 2 or site.windows == 0:
        return list(rows), None
    said = (f"site adaptation: {site.share:.2f} of this batch's valves estimated sticky "
            f"from the {site.windows} windows the shape network read (the simulation: "
            f"{site.source:.2f}); --no-site scores each file alone")
    return rejudged(rows, lambda a: adapt([a], site)[0]), said


def said(shown: dict[str, Any]) -> str:
    """The text output's line on the site (a single file's, or a row's)."""
    if shown.get("site") == "adapted":
        return (f"adapted: called at this site's share of sticky valves, "
                f"{shown.get('site_share') or 0.0:.2f}")
    return ALONE
