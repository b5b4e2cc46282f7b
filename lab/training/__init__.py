"""The decision's fit, folds and thresholds (``fit``), what is printed of them (``report``),
and the weighted vote's calibration (``calibrate``)."""
