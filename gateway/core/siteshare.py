"""The gateway's loops as one site (issue 36 item 3): the share of sticky valves its own
windows imply, and each loop's call at it.

The shape network's probability (:mod:`stiction.diagnosis.network`) is calibrated where one
window in five was a sticky valve (the simulation). A gateway's loops are an unlabelled
sample of its plant: before each analysis round, label-shift EM over the network's readings
of the loops' latest windows (:func:`stiction.diagnosis.adapt.site_of`: the readings in the
published assessments' evidence, which keep the window's own probability) estimates the
plant's share, and the round's assessments are called again at it
(:func:`stiction.diagnosis.adapt.adapt`) before the site's calibration from the crew's
findings and the verdict hysteresis. After a restart the share comes from the state file's
restored results, before the first round. Fewer than :data:`MIN_WINDOWS` windows read, or
``analysis.site_adaptation: false``: each loop is scored alone, and its reason says so.

:mod:`stiction.diagnosis.adapt` (with the network and SciPy's signal package under it) is
imported at the first round, not at start: ``check-config`` and the start stay as fast.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from stiction import Assessment

from .store import ResultStore

if TYPE_CHECKING:
    from stiction.diagnosis.adapt import Site

__all__ = ["MIN_WINDOWS", "SiteShare"]

MIN_WINDOWS = 2
"""Windows the network read before a share is estimated (one window moves it by a tenth
at most)."""
log = logging.getLogger("gateway.analysis")


class SiteShare:
    """The site's share in force (``site``: None until estimated, or when turned off)."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self.site: Site | None = None

    def estimate(self, store: ResultStore) -> Site | None:
        """The share from the store's latest assessments (a round's start)."""
        before = self.site
        if not self.enabled:
            self.site = None
            return None
        from stiction.diagnosis.adapt import site_of  # noqa: PLC0415 (module doc)

        found = site_of([r.assessment for r in store.results if r is not None])
        self.site = found if found.windows >= MIN_WINDOWS else None
        if self.site is not None and (before is None or abs(before.share - self.site.share)
                                      >= 0.05):
            log.info("site adaptation: %.2f of the loops' valves estimated sticky from %d "
                     "windows the shape network read (the simulation: %.2f)",
                     self.site.share, self.site.windows, self.site.source)
        return self.site

    def apply(self, a: Assessment) -> Assessment:
        """One loop's assessment at the site's share (as it is without one)."""
        if self.site is None:
            return a
        from stiction.diagnosis.adapt import adapt  # noqa: PLC0415 (module doc)

        return adapt([a], self.site)[0]
