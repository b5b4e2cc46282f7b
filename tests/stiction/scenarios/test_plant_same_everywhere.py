"""Issue 35: the demo's plant of interacting loops ran a different trajectory on processors
with AVX-512 (AMD EPYC): numpy's vector ``exp`` there differs in the last bit from the C
library's, the plant's first-order lags took their poles from it, and the sticky valve's
limit cycle grew that bit into another run, with other verdicts, in which the demo's promise
failed. The plant is now the same bit for bit whichever of numpy's processor paths runs:
simulated here and in a process with the AVX-512 paths turned off
(``NPY_DISABLE_CPU_FEATURES``; on a machine without them both runs take the same path)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from stiction.scenarios.plant import simulate_plants
from stiction.scenarios.plants import NAMED_PLANTS

SCRIPT = """
import sys
import numpy as np
from stiction.scenarios.plant import simulate_plants
from stiction.scenarios.plants import NAMED_PLANTS
(rec,) = simulate_plants([NAMED_PLANTS["sticky-feeds-two"]], duration=2400.0, ts=1.0,
                         seed=4)
np.save(sys.argv[1], np.array([rec.pv[n] for n in sorted(rec.pv)]))
"""
NO_AVX512 = "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR X86_V4"


def test_the_demo_plant_is_the_same_on_every_processor_path(tmp_path: Path) -> None:
    (rec,) = simulate_plants([NAMED_PLANTS["sticky-feeds-two"]], duration=2400.0, ts=1.0,
                             seed=4)
    here = np.array([rec.pv[n] for n in sorted(rec.pv)])
    out = tmp_path / "pv.npy"
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": NO_AVX512}
    subprocess.run([sys.executable, "-c", SCRIPT, str(out)], check=True, env=env)
    there = np.load(out)
    assert np.ptp(here) > 1.0  # the sticky valve cycles: a run that can diverge
    assert np.array_equal(here, there), float(np.abs(here - there).max())
