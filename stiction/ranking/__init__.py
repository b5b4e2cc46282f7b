"""The list a maintenance crew works from: each loop's suspicion (the confidence of stiction
times what its cycle costs), the loops ranked worst first (:mod:`.suspicion`), and a site's
own calibration of the confidence fitted on the crew's findings (:mod:`.calibration`)."""

from __future__ import annotations

from .calibration import (
    MIN_EACH,
    Scores,
    SiteCalibration,
    fit_site,
    platt_fit,
    recalibrate,
    shipped,
)
from .suspicion import (
    AMPLITUDE_REF,
    JUDGED,
    Ranked,
    Suspect,
    amplitude_weight,
    rank,
    rank_arrays,
    suspicion,
    swing,
    verdict_order,
)

__all__ = ["AMPLITUDE_REF", "JUDGED", "MIN_EACH", "Ranked", "Scores", "SiteCalibration",
           "Suspect", "amplitude_weight", "fit_site", "platt_fit", "rank", "rank_arrays",
           "recalibrate",
           "shipped", "suspicion", "swing", "verdict_order"]
