"""Weights of the tests' votes (written by ``python -m bench calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -0.2125
FOR = {  # added when the test votes +1 (says stiction)
    "shape": 0.7222,
    "bicoherence": 0.9351,
    "horch": 0.5944,
    "ellipse": 1.0000,
    "kano": 1.0070,
    "stick_slip": 1.1054,
    "hammerstein": 0.9955,
    "fast_cycle": 1.5287,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "shape": 1.0296,
    "bicoherence": 0.6517,
    "horch": 1.0483,
    "ellipse": 0.5997,
    "kano": 0.3690,
    "stick_slip": 1.0000,
    "hammerstein": 0.9948,
    "fast_cycle": 1.0411,
}
