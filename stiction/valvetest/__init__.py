"""Step tests of a valve in manual: dead band, resolution, slip and response times.

A room of its own (docs/architecture.md): arrays in, a :class:`StepTestReport` out, no IO.
Reference: ANSI/ISA-75.25.01 (Test Procedure for Control Valve Response Measurement from
Step Inputs) and ISA-TR75.25.02 for the test and the response times; the definitions of
dead band and resolution of ISA-51.1 as EnTech's Control Valve Dynamic Specification
(v3.0, 1998) applies them; Ruel (Control, 2000) for reading stick-slip from small steps in
manual. Each module's docstring says which definition it uses:

* :mod:`.holds`: OP split into holds and steps, or the recording refused
  (:class:`NotAStepTest`, naming what a step test needs);
* :mod:`.response`: the response (PV or the valve's position) identified, and how far the
  valve moved at each step;
* :mod:`.bands`: dead band, resolution and slip from which steps moved it;
* :mod:`.timing`: dead time, T63, T86 and overshoot of each step;
* :mod:`.reading`: which steps moved the valve, which did not, which cannot be read;
* :mod:`.sequence`: the OP sequences to play (a few small steps, as the simulated PLC and
  an operator play them; the thorough staircase of a simulator).

The valve's response may be read from PV (through the process: its gain, lag and dead time
are identified from the recording) or from the valve position where a positioner reports
it (``source="position"``): the analysis is the same.
"""

from __future__ import annotations

from .analyze import (
    SOURCES,
    StepResult,
    StepTestDetails,
    StepTestReport,
    analyze_step_test,
    step_test_details,
)
from .holds import NotAStepTest
from .sequence import hold_series, operator_levels, step_test_levels

__all__ = ["SOURCES", "NotAStepTest", "StepResult", "StepTestDetails", "StepTestReport",
           "analyze_step_test", "hold_series", "operator_levels", "step_test_details",
           "step_test_levels"]
