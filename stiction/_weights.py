"""Weights of the tests' votes (written by ``python -m bench.calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -1.0
FOR = {  # added when the test votes +1 (says stiction)
    "si_op": 1.0,
    "si_pv": 1.0,
    "bicoherence": 1.0,
    "horch": 1.0,
    "stick_slip": 1.0,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "si_op": 1.0,
    "si_pv": 1.0,
    "bicoherence": 1.0,
    "horch": 1.0,
    "stick_slip": 1.0,
}
