"""Signal helpers every other room builds on: oscillation detection (ACF period and
regularity) and the cycle of a window (:mod:`.oscillation`, :mod:`.cycle`), robust smoothing
(:mod:`.smooth`), least-squares fits of many segments at once (:mod:`.segments`), PV's
switching points (:mod:`.switching`), the noise level (:mod:`.noise`) and fast order
statistics (:mod:`.arrays`). Pure functions of arrays; nothing here knows about stiction
tests or verdicts."""
