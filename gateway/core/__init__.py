"""The gateway's core: the rules, with no IO (numpy only; every function that needs the time
takes ``now``), testable with literal arrays.

:mod:`.points` quality, raw -> engineering values and plausibility; :mod:`.windows` the
per-loop ring buffers, loop groups, window signatures; :mod:`.ticks` process clock, tick
grid, missed ticks, backoff, up/down, stale; :mod:`.store` the result store; :mod:`.jobs`
what an analysis worker runs.
"""
