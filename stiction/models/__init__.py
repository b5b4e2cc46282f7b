"""Valve models as explicit-state step functions (:mod:`.valves`), the closed-loop simulator
that runs many loops at once (:mod:`.simulate`) and the valve signature test
(:mod:`.signature`). Used by the scenarios, the simulated PLC and the tests; never by the
diagnosis."""
