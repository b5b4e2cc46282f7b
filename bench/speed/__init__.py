"""How fast and how big: the analysis, polling, the simulator, memory, the plant step, the
findings, the offline CLI, a fleet."""
