"""Weights of the tests' votes (written by ``python -m bench calibrate --write``;
see bench/calibrate.py for the data and the fit). Do not edit by hand."""

BIAS = -0.1953
FOR = {  # added when the test votes +1 (says stiction)
    "si_op": 0.5746,
    "si_pv": 0.2738,
    "bicoherence": 0.3831,
    "horch": 0.0000,
    "ellipse": 0.0000,
    "kano": 0.3047,
    "stick_slip": 0.6712,
    "hammerstein": 0.7184,
    "fast_cycle": 2.2880,
}
AGAINST = {  # subtracted when the test votes -1 (says not stiction)
    "si_op": 0.3224,
    "si_pv": 0.4532,
    "bicoherence": 0.3495,
    "horch": 1.0534,
    "ellipse": 0.0051,
    "kano": 0.0000,
    "stick_slip": 0.0000,
    "hammerstein": 0.6431,
    "fast_cycle": 0.5101,
}
