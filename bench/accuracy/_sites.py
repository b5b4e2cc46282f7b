"""Simulated sites whose valves differ from the development corpus, for ``python -m bench
site_calibration``: the realistic generator's loops (stiction.scenarios.realistic: loads,
setpoint changes, noise, quantisation, units), with

* ``asymmetric``: sticky valves whose packing grips harder one way (He's model with the
  static and dynamic friction of opening 1.5-3 times those of closing) and overshoots less
  (K 1.0-1.5; the corpus's He valves have K = 1.99); the good loops as the generator draws
  them;
* ``slow``: every loop sampled 8 times slower than the generator draws it (a historian, or
  a gateway polling every 10-60 s: a fast loop's cycle spans a few samples);
* ``both``: the two at once;
* ``deadband``: besides the sticky valves, 16 with a band of lost motion and no slip
  (Choudhury's model with J = 0: a worn linkage, a loose positioner), which the crew finds
  as ``deadband``, not sticking; the other loops as drawn;
* ``ramps``: a plant whose loads ramp and turn (batch feeds, a level drawn down and
  refilled): 24 of the good loops under a triangle or sawtooth load, which OP and PV alone
  cannot tell from a sticky valve (the corpus holds such loops as a cause of their own).

Each site mixes 24 sticky valves with 16 loops tuned too tight, 8 under a periodic load,
8 carrying a sticky loop's cycle from elsewhere, 8 under a ramping load and 8 quiet ones
(72 loops; ``deadband``: the 16 valves with lost motion, 8 tuned too tight and no
propagated cycle), drawn from seeds no corpus uses (31-34). Simulated once and cached in
``lab/.cache`` (keyed by the generator's and this module's source).
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
from collections.abc import Callable, Sequence
from typing import Any
from unittest import mock

import numpy as np
from numpy.typing import ArrayLike

from lab import _cache
from stiction.models.valves import ChoudhuryValve, HeState
from stiction.scenarios import realistic
from stiction.scenarios.draws import Draw, draw

__all__ = ["MIX", "SITES", "AsymmetricValve", "site_records"]

SITES = ("asymmetric", "slow", "both", "deadband", "ramps")
MIX = (("stiction", 24), ("tuning", 16), ("disturbance", 8), ("propagated", 8),
       ("ramp-load", 8), ("noise", 8))
DEADBAND_MIX = (("stiction", 24), ("deadband", 16), ("tuning", 8), ("disturbance", 8),
                ("ramp-load", 8), ("noise", 8))
RAMPS_MIX = (("stiction", 24), ("ramp-load", 24), ("tuning", 8), ("disturbance", 8),
             ("noise", 8))
SEEDS = {"asymmetric": 31, "slow": 32, "both": 33, "deadband": 34, "ramps": 35}
SLOW = 8.0


@dataclasses.dataclass(frozen=True)
class AsymmetricValve:
    """He's semiphysical model (He & Wang 2014, eq 6) with one static and dynamic friction
    per direction of travel: the net force e = u - x moves the valve when |e| exceeds the fs
    of its sign, by K (e - sign(e) fd) of that sign. Arrays, one valve each."""

    fs_up: ArrayLike
    fd_up: ArrayLike
    fs_down: ArrayLike
    fd_down: ArrayLike
    k: ArrayLike

    def initial_state(self, u0: ArrayLike) -> HeState:
        return HeState(np.array(u0, dtype=np.float64, copy=True))

    def step(self, state: HeState, u: ArrayLike) -> HeState:
        x = state.x
        e = np.asarray(u, dtype=np.float64) - x
        up = e > 0
        fs = np.where(up, self.fs_up, self.fs_down)
        fd = np.where(up, self.fd_up, self.fd_down)
        moved = x + np.asarray(self.k) * (e - np.sign(e) * fd)
        return HeState(np.where(np.abs(e) > fs, moved, x))

    def position(self, state: HeState) -> np.ndarray:
        return state.x


def _asymmetric(draws: Sequence[Draw]) -> AsymmetricValve:
    fs = np.array([(x.s + x.j) / 2.0 for x in draws])
    fd = np.array([(x.s - x.j) / 2.0 for x in draws])
    ratio = np.array([x.rng.uniform(1.5, 3.0) for x in draws])
    k = np.array([x.rng.uniform(1.0, 1.5) for x in draws])
    # the closing side as drawn, the opening side gripping `ratio` times harder
    return AsymmetricValve(fs * ratio, fd * ratio, fs, fd, k)


def _mix(site: str) -> tuple[tuple[str, int], ...]:
    return {"deadband": DEADBAND_MIX, "ramps": RAMPS_MIX}.get(site, MIX)


def _draws(site: str) -> list[Draw]:
    seed = SEEDS[site]
    out = []
    for cause, count in _mix(site):
        # (valves that never move are dropped: spare ones)
        for i in range(count * (3 if cause in ("stiction", "deadband") else 1)):
            if cause == "deadband":  # a stiction draw whose valve has lost motion, no slip
                d = draw("stiction", 1000 + i, seed)
                d.valve = "deadband"
            else:
                d = draw(cause, i, seed)
            if site in ("slow", "both"):
                d.ts *= SLOW
            if cause == "stiction" and site in ("asymmetric", "both"):
                d.valve = "asymmetric"
            out.append(d)
    return out


def _simulated(site: str) -> list[dict[str, Any]]:
    valve = realistic._valve

    def patched(kind: str, draws: Sequence[Draw]) -> Any:
        if kind == "asymmetric":
            return _asymmetric(draws)
        if kind == "deadband":  # Choudhury's model without slip: a band of lost motion
            return ChoudhuryValve(np.array([x.s for x in draws]), np.zeros(len(draws)))
        return valve(kind, draws)

    with mock.patch.object(realistic, "_valve", patched):
        recs = realistic._run(_draws(site), SEEDS[site])
    out: list[dict[str, Any]] = []
    for cause, count in _mix(site):
        real = "stiction" if cause == "deadband" else cause
        mine = sorted((r for r in recs if r.cause == real
                       and (r.index >= 1000) == (cause == "deadband")),
                      key=lambda r: r.index)[:count]
        out += [{"cause": cause, "index": r.index, "ts": r.ts, "process": r.process,
                 "op": r.op, "pv": r.pv, "op_range": r.op_range,
                 "sticky": cause == "stiction", "description": r.description} for r in mine]
    return out


def site_records(site: str, log: Callable[[str], None] = print) -> list[dict[str, Any]]:
    """The site's records (cached): dicts of cause, ts, process, op, pv, op_range, sticky."""
    key = hashlib.sha256((inspect.getsource(realistic) + inspect.getsource(_simulated)
                          + inspect.getsource(_draws) + inspect.getsource(_asymmetric)
                          + repr(_mix(site))
                          + site).encode()).hexdigest()[:12]
    path = _cache.root() / f"site-{site}-{key}.pickle"
    if path.exists():
        return list(_cache.load(path))
    log(f"  simulating the {site} site (once; cached in {path.parent})")
    recs = _simulated(site)
    path.parent.mkdir(parents=True, exist_ok=True)
    _cache.dump(recs, path)
    return recs
