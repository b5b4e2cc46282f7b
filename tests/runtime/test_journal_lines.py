"""Issue 32 item 10: the journal's verdict lines are whole (a reason was cut mid-word at 200
characters: "...over 65 sa...") and say the sizes in the unit the registers hold."""

from __future__ import annotations

import logging
import re

import pytest

from gateway.runtime.logs import clip
from gateway.runtime.scheduler import log_verdict_change
from stiction import Assessment, Verdict

REASON = ("stiction, confidence 0.99. For: a sticky valve explains 98% of PV, a linear one "
          "89%; better in levels (82%) and in increments (76%), cycle after cycle; PV stood "
          "still while OP ramped in 10 intervals (51% of the window; median OP travel 22.4): "
          "the valve stuck over 65 samples. Against: the OP-PV cross-correlation. Size: fd "
          "26.9 % of span, fs 29.9 % of span, from OP at the PV jumps over 4 cycles (He & "
          "Wang 2014). END")


def test_a_verdict_line_is_whole_and_names_the_registers_unit(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    a = Assessment(Verdict.STICTION, REASON, fd=0.269, fs=0.299, jump=0.0597, fd_op=26.9,
                   fs_op=29.9)
    log_verdict_change("FIC101", None, a)
    (line,) = [r.getMessage() for r in caplog.records]
    assert len(REASON) > 400
    assert line == ("loop FIC101: verdict stiction (was none), fd 26.9, fs 29.9, J 6.0 % of "
                    f"span (as its registers): {REASON}")


@pytest.mark.parametrize("limit", [20, 41, 60, 200])
def test_clip_never_cuts_inside_a_word(limit: int) -> None:
    text = "the valve stuck over 65 samples while OP travelled 22.4 % of span " * 5
    got = clip(text, limit)
    assert len(got) <= limit and got.endswith(" ...")
    words = set(text.split())
    assert all(w in words for w in got[:-4].split()), got
    assert clip("a  b\n c") == "a b c"
    assert re.fullmatch(r"x{16} \.\.\.", clip("x" * 50, 20))  # one long word: cut, marked
