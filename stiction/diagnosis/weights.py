"""Weights of the tests' votes (written by ``python -m bench calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -0.1661
FOR = {  # added when the test votes +1 (says stiction)
    "shape": 0.7248,
    "bicoherence": 0.9393,
    "horch": 0.6815,
    "ellipse": 1.0000,
    "kano": 1.0119,
    "stick_slip": 1.0984,
    "hammerstein": 1.0369,
    "fast_cycle": 1.5151,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "shape": 1.0328,
    "bicoherence": 0.6525,
    "horch": 1.0252,
    "ellipse": 0.7278,
    "kano": 0.3647,
    "stick_slip": 1.0000,
    "hammerstein": 1.1444,
    "fast_cycle": 1.0426,
}
