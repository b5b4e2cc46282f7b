"""The stiction index (He et al. 2007) on analytic triangles and sines."""

from __future__ import annotations

import numpy as np
import pytest
from analytic_signals import SINE, TRIANGLE, T

from stiction.detectors.stiction_index import stiction_index

RNG = np.random.default_rng(42)


# ------------------------------------------------------------------------ detection
@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_si_of_triangle_and_sine(noise: float) -> None:
    tri = stiction_index(TRIANGLE + RNG.normal(0, noise, T.size), 200.0)
    sin = stiction_index(SINE + RNG.normal(0, noise, T.size), 200.0)
    assert tri.si is not None
    assert sin.si is not None
    assert tri.si >= 0.9
    assert sin.si <= 0.1
    assert tri.half_periods >= 25


def test_si_not_resolved_when_both_shapes_fit_within_the_noise() -> None:
    # amplitude 1 under noise SD 2: the triangle's and the sine's misfits differ by ~0.003
    # per sample, which noise of variance 4 drowns; under noise SD 0.1 they stand out
    rng = np.random.default_rng(5)
    for _ in range(10):
        for base in (TRIANGLE, SINE):
            assert not stiction_index(base + rng.normal(0, 2.0, T.size), 200.0).resolved
    tri = stiction_index(TRIANGLE + rng.normal(0, 0.1, T.size), 200.0)
    sin = stiction_index(SINE + rng.normal(0, 0.1, T.size), 200.0)
    assert tri.resolved and sin.resolved
    assert tri.si is not None and tri.si >= 0.9
    assert sin.si is not None and sin.si <= 0.2
