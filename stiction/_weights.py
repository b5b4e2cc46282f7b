"""Weights of the tests' votes (written by ``python -m bench calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -0.0681
FOR = {  # added when the test votes +1 (says stiction)
    "shape": 0.7076,
    "bicoherence": 0.7355,
    "horch": 0.4157,
    "ellipse": 1.0000,
    "kano": 1.0070,
    "stick_slip": 0.8166,
    "hammerstein": 0.9846,
    "fast_cycle": 1.4262,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "shape": 1.0428,
    "bicoherence": 0.6321,
    "horch": 1.0033,
    "ellipse": 0.6589,
    "kano": 0.4874,
    "stick_slip": 1.0000,
    "hammerstein": 0.9374,
    "fast_cycle": 1.0384,
}
