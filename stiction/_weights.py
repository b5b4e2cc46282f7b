"""Weights of the tests' votes (written by ``python -m bench calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -0.2264
FOR = {  # added when the test votes +1 (says stiction)
    "shape": 0.7906,
    "bicoherence": 0.8834,
    "horch": 0.4465,
    "ellipse": 1.0000,
    "kano": 1.0083,
    "stick_slip": 0.9541,
    "hammerstein": 0.9857,
    "fast_cycle": 1.4673,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "shape": 1.0403,
    "bicoherence": 0.7824,
    "horch": 0.9806,
    "ellipse": 0.6227,
    "kano": 0.4592,
    "stick_slip": 1.0000,
    "hammerstein": 0.9237,
    "fast_cycle": 1.0341,
}
