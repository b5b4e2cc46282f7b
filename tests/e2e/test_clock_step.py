"""Issue 31, finding 1, against real processes: ``stiction-gateway run`` restarted with its
wall clock stepped back an hour (libfaketime preloaded), across a clean stop and across a
SIGKILL (the scenario is bench/attacks/_clock.py's, which ``python -m bench hostile`` also runs on
the baseline). The downtime is a gap in the window, never joined; the sequence numbers
SCADA reads never go backwards. Main (3dfa8c7) restored both with no gap, and after the
kill SCADA read 10 where it had read 13 before.

libfaketime is Debian's package ``libfaketime`` (.ci/run installs it): the test skips
without it, and fails under ``CI=true``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from deploy_support import require

from bench.attacks._clock import clock_case, faketime, summary
from gateway.outputs.statefile.restore import UNKNOWN_DOWNTIME_ROWS

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(150)]
REPO = Path(__file__).resolve().parents[2]


def test_a_wall_clock_stepped_back_across_restarts_is_a_gap_and_seq_never_goes_back(
        tmp_path: Path) -> None:
    """Run 1 on time, SIGTERM; 1 s later run 2 with the clock 1 h back: its window holds
    run 1's samples, a gap of at least UNKNOWN_DOWNTIME_ROWS, then its own; one WARNING line
    and stiction_state_clock_back_seconds say so. Run 2 is SIGKILLed just before its next
    state write; run 3 starts with the clock 2 h back: the first sequence number SCADA reads
    is above the last one it read before the kill, and the outage is a gap again, which
    the analysis never bridges."""
    env2, env3 = faketime(3600), faketime(7200)
    require(env2 is not None and env3 is not None,
            "libfaketime not found (Debian package 'libfaketime'; .ci/run installs it)")
    assert env2 is not None and env3 is not None
    out = clock_case(REPO, tmp_path, env2, env3)
    s = summary(out, UNKNOWN_DOWNTIME_ROWS)
    print(f"\nclock stepped back: {s}")
    assert out["exit1"] == out["exit3"] == 0
    assert out["runs1"][0][0] == "GOOD" and len(out["runs1"]) == 1, out["runs1"]
    broken = [what for what, ok in (
        (f"clean stop: gap {s['gap_clean']} ({out['runs2'][:3]})",
         s["gap_clean"] >= UNKNOWN_DOWNTIME_ROWS and out["runs2"][0] == out["runs1"][0]),
        (f"kill: gap {s['gap_kill']} ({out['runs3']})", s["gap_kill"] >= UNKNOWN_DOWNTIME_ROWS),
        (f"sequence numbers went back: run 1 {out['seq1']}, run 2 {out['seq2']}, "
         f"run 3 {out['seq3']}", not s["seq_back"]),
        (f"the analysis sees {s['segment']} samples, {s['since_restart']} since the last "
         f"restart", 0 < s["segment"] <= s["since_restart"]),
        (f"no warning line:\n{out['log2']}", s["warned"]),
        (f"stiction_state_clock_back_seconds {s['clock_back']}",
         s["clock_back"] is not None and 3600 - 120 < s["clock_back"] < 3600),  # less the
        # time from run 1's last write to run 2's restore (17 s at a load of 15)
    ) if not ok]
    assert not broken, "\n".join(broken)  # every count, so that a failure shows them all
