"""The list the crew works from, in the running gateway: every loop ranked worst first after
each analysis round (:mod:`gateway.core.ranking`), and the site's calibration of the
confidence fitted again on the crew's findings when they or the confidences of their days
change (:mod:`gateway.core.sitecal`), off the event loop.

The analysis scheduler calls :meth:`CrewList.calibrate` on each loop's assessment before the
verdict hysteresis and :meth:`CrewList.after_round` after each round; the gateway calls
:meth:`CrewList.bind` after the state file was restored and after every reload, and
:meth:`CrewList.refit` after the findings were read. One log line each time the calibration
in force changes.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable

from stiction import Assessment

from ..config.model import Config
from ..core.findings import FindingsBook
from ..core.ranking import rerank, weigh
from ..core.sitecal import SiteBook, SiteView
from ..core.store import ResultStore
from .findings import reload_findings

__all__ = ["CrewList", "calibration_line"]

log = logging.getLogger("gateway.analysis")


def calibration_line(view: SiteView, stiction_at: float) -> str:
    """The journal's line for a calibration put in force."""
    cal = view.calibration
    if cal.used:
        site, ship = cal.site, cal.shipped
        calls = ""
        if site is not None and ship is not None:
            calls = (f"; `stiction` calls on the findings: {_share(ship.hits, ship.calls)} "
                     f"shipped, {_share(site.hits, site.calls)} held out with the site's")
        return (f"site calibration: this site's in force, {cal.why}: confidence "
                f"{stiction_at:.2f} reads {cal.apply(stiction_at):.2f}{calls}")
    return f"site calibration: shipped in force ({cal.why})"


def _share(hits: int, calls: int) -> str:
    return f"{hits} of {calls} sticky" if calls else "none"


class CrewList:
    """Ranks the store each round and keeps the site's calibration fitted."""

    def __init__(self, site: SiteBook, findings: FindingsBook, *,
                 wall: Callable[[], float] = time.time) -> None:
        self.site = site
        self.findings = findings
        self.wall = wall
        self.config: Config | None = None
        self.fits = 0
        self._refit: asyncio.Task[None] | None = None

    async def start(self, store: ResultStore, config: Config) -> None:
        """At start, the state file restored: the list at once, then the calibration."""
        self.bind(store, config)
        await self.refit()

    def bind(self, store: ResultStore, config: Config) -> None:
        """A (re)built runtime: the loops' weights, the settings, and the list at once."""
        self.config = config
        self.site.settings = config.analysis
        self.site.has_findings = config.findings is not None
        weigh(store, config.loops)
        rerank(store)

    async def reload(self, store: ResultStore, config: Config) -> None:
        """After a reload (applied or refused): the runtime in force ranked, the findings
        of its config read again, the calibration fitted."""
        self.bind(store, config)
        await reload_findings(config, self.findings)
        await self.refit()

    def calibrate(self, loop: str, a: Assessment, t: float) -> Assessment:
        return self.site.calibrate(loop, a, t)

    def after_round(self, store: ResultStore) -> None:
        rerank(store)
        if self.site.stale(self.findings.findings) and (
                self._refit is None or self._refit.done()):
            self._refit = asyncio.get_running_loop().create_task(self.refit(),
                                                                 name="site calibration")

    async def refit(self) -> None:
        """Fit the site's calibration on the findings now (in a thread) and put it in
        force; never raises."""
        if self.config is None:
            return
        findings = self.findings.findings
        has_file = self.config.findings is not None
        version = self.site.history.version
        before = self.site.view
        try:
            view = await asyncio.to_thread(self.site.fit, findings, has_file=has_file,
                                           now=self.wall())
        except Exception:  # a bug: the calibration in force stays
            log.exception("site calibration: fitting failed; the calibration in force stays")
            return
        self.site.publish(view, findings, has_file=has_file, version=version)
        self.fits += 1
        if (view.state, view.calibration.why) != (before.state, before.calibration.why):
            log.info("%s", calibration_line(view, self.site.thresholds[0]))
