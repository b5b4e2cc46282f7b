"""Site adaptation (issue 36 item 3): the OP-PV shape network's probability at the share of
sticky valves a site's own windows imply, and the calls again with it.

The network's probability (:mod:`.network`) is calibrated on held-out simulation, where
about one window in five was a sticky valve. A plant where more valves stick, or fewer,
moves that share, and with it what a score means. The windows of one site (the files of
one batch, a gateway's loops' latest windows) are an unlabelled sample of it: label-shift
EM (Saerens, Latinne and Decaestecker 2002; :func:`stiction.diagnosis.site.label_shift`,
the simulation's share counted as :data:`~stiction.diagnosis.site.PRIOR_WEIGHT` windows)
estimates the site's share from their probabilities (:func:`estimate`, :func:`site_of`),
and Bayes' rule moves each probability to it (:func:`at_site`). On the 80 plant records as
one batch (44 % sticky; estimated 0.38): 21 of 35 sticky records found instead of 16, none
of the 45 others called (docs/accuracy.md). Where sticky valves are rare the share falls
and so do the calls (on subsets of the plant records at 5-10 % sticky, 80-87 % of the
network's calls were right, against 100 % unadapted: lab/shape/README.md).

Two ways to use it, both pure:

- :func:`stiction.analyze` with ``site=`` a :class:`Site` (a gateway's share from its
  previous round, a batch's from a first pass): the exact call, sized where it is
  ``stiction``; the assessment's ``site`` is ``"adapted"``, ``site_share`` the share.
- :func:`adapt`: the assessments of a batch called again at their site's share without
  their data (:mod:`.call`: the network's and the decision's probabilities and the tests'
  votes are in their evidence). A window that becomes ``stiction`` this way is not sized
  (its reason says to analyse it again with the site); one that stops being ``stiction``
  loses its size. Windows the network did not read, and those the valve's travel decided,
  keep their call.

Without either, a window is scored with the simulation's share alone (``site`` ``"none"``:
"scored without site adaptation"); one window alone moves the share by a tenth at most, so
a single file is always scored so.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable, Sequence

import numpy as np

from .._assessment import SITE_NONE, Assessment, Evidence, Verdict
from . import network, shape
from .call import Thresholds, call, shipped
from .reasons import DECISION
from .site import PRIOR_WEIGHT, label_shift, shifted
from .travel import BY_TRAVEL

__all__ = ["ADAPTED", "NONE", "Site", "adapt", "at_site", "at_site_evidence", "estimate",
           "site_of"]

NONE = SITE_NONE
ADAPTED = "adapted"
JUDGED = frozenset({Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                    Verdict.NOT_OSCILLATING})
"""The verdicts :func:`adapt` may call again (the others are not the network's)."""
_CONF = re.compile(r"confidence of stiction [\d.]+")


@dataclasses.dataclass(frozen=True)
class Site:
    """A site's ``share`` of sticky windows, estimated from ``windows`` windows the network
    read; ``source`` the simulation's share the probabilities were calibrated at."""

    share: float
    windows: int
    source: float

    def sentence(self) -> str:
        return (f"At this site's share of sticky valves ({self.share:.2f}, estimated from "
                f"{self.windows} windows; {self.source:.2f} in the simulation)")


def _source() -> float:
    prior = shape.load().meta["sim_prior"]
    if not isinstance(prior, float):
        raise ValueError(f"the weights' meta has no simulated share: {prior!r}")
    return prior


def estimate(probabilities: Iterable[float | None]) -> Site:
    """The site of windows with these network probabilities (None or NaN: not read)."""
    p = np.array([q for q in probabilities if q is not None and np.isfinite(q)], dtype=float)
    source = _source()
    _, share = label_shift(p, source, prior_weight=PRIOR_WEIGHT)
    return Site(share, int(p.size), source)


def at_site(probability: float, site: Site) -> float:
    """A network probability moved to the site's share."""
    return float(shifted(probability, site.source, site.share))


def _value(a: Assessment, test: str) -> float | None:
    return next((e.value for e in a.evidence if e.test == test), None)


def site_of(assessments: Sequence[Assessment]) -> Site:
    """The site of a batch of assessments (each one window of a loop): EM over the network
    probabilities in their evidence."""
    return estimate(_value(a, network.NAME) for a in assessments)


def _by_travel(a: Assessment) -> bool:
    return any(e.test == "travel" and e.note.startswith(BY_TRAVEL) for e in a.evidence)


def adapt(assessments: Sequence[Assessment], site: Site | None = None,
          at: Thresholds | None = None) -> list[Assessment]:
    """Each assessment called again at the site's share (``site``: :func:`site_of` the
    batch when None; ``at``: the shipped thresholds when None). Module doc."""
    at = shipped() if at is None else at
    site = site_of(assessments) if site is None else site
    return [_again(a, site, at) for a in assessments]


def _again(a: Assessment, site: Site, at: Thresholds) -> Assessment:
    marked = dataclasses.replace(a, site=ADAPTED, site_share=site.share)
    net, dec = _value(a, network.NAME), _value(a, DECISION)
    if net is None or dec is None or a.verdict not in JUDGED or _by_travel(a):
        return marked
    moved = at_site(net, site)
    votes = {e.test: e.vote for e in a.evidence
             if e.test not in (network.NAME, DECISION, "travel")}
    c = call(dec, moved, votes, too_fast=False, at=at)
    verdict = c.verdict
    if verdict != Verdict.STICTION and not a.oscillating and c.confidence <= 0.5 and \
            c.unbacked is None:
        verdict = Verdict.NOT_OSCILLATING
    evidence = tuple(at_site_evidence(e, moved) for e in a.evidence)
    said = f"{site.sentence()} {network.WHAT} reads {moved:.2f} (alone {net:.2f})."
    if verdict == a.verdict == Verdict.NOT_OSCILLATING:
        reason = f"{_CONF.sub(f'confidence of stiction {c.confidence:.2f}', a.reason)}. {said}"
    else:
        body = _body(a.reason)
        if verdict == Verdict.STICTION and a.verdict != Verdict.STICTION:
            body = (f"{body} Size: not sized here: the call came at the site's share; "
                    "analyse the window again with this site to size it.").strip()
        reason = f"{_head(verdict, c.confidence)} {said} {body}".strip()
    out = dataclasses.replace(marked, verdict=verdict, confidence=c.confidence,
                              evidence=evidence, reason=reason)
    if verdict != Verdict.STICTION:
        out = dataclasses.replace(out, fd=None, fs=None, jump=None, fd_op=None, fs_op=None,
                                  cycles_used=0, multi_jump=False)
    return out


def at_site_evidence(e: Evidence, moved: float) -> Evidence:
    """The network's evidence at a site: its value stays the window's own probability (what
    :func:`site_of` reads, so that a batch adapted twice reads the same share), its vote and
    note are the probability ``moved`` to the site's share; other evidence as it is."""
    if e.test != network.NAME or e.value is None:
        return e
    return Evidence(e.test, e.value, network.vote_of(moved),
                    f"{network.WHAT}: {moved:.2f} at the site's share ({e.value:.2f} alone)")


def _head(verdict: Verdict, conf: float) -> str:
    if verdict == Verdict.STICTION:
        return f"stiction, confidence {conf:.2f}."
    if verdict == Verdict.NO_STICTION:
        return f"not stiction, confidence of stiction {conf:.2f}."
    if verdict == Verdict.NOT_OSCILLATING:
        return f"no regular oscillation in OP or PV; confidence of stiction {conf:.2f}."
    return f"undetermined, confidence of stiction {conf:.2f}."


def _body(reason: str) -> str:
    """What the reason said after its head, without its size (the tests, the network, what
    weighed)."""
    i = reason.find(". ")
    body = "" if i < 0 else reason[i + 2:]
    j = body.find("Size: ")
    return (body if j < 0 else body[:j]).strip()
