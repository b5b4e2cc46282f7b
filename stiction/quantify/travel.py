"""Stiction measured from the valve's own travel: OP against the position a smart positioner
reports, not inferred from PV.

A sticky valve holds after every reversal of OP until OP has travelled through its dead band
and stick band, then jumps. With the position read, both are seen directly, per reversal of
the valve (a move whose direction differs from the one before it):

* **band** (``S`` of Choudhury, Thornhill & Shah 2005 and of Kano et al. 2004: dead band plus
  stick band; ``fs + fd`` in He's model with K = 1, ``2 fs - J`` for any K): the OP travel
  from the OP at which the valve last moved one way to the OP at which it first moved back.
  Read from OP's local trend (a line through the six samples up to each move, so OP's noise
  is not read as travel) less half the OP travel of one sample: the valve moves only at sample
  instants, so OP passes the threshold by half a sample's travel on average (as
  :mod:`stiction.quantify.hewang` corrects its fs).
* **slip** (``J`` of Choudhury's and Kano's models; ``K (fs - fd)`` in He's, He, Wang,
  Pottmann & Qin 2007, He & Wang 2014 eq 7): how far the valve jumped when it broke free:
  its travel over the samples in which it moved faster than OP, from its level before (the
  mean of up to six samples since it last moved) to its level after (a line through up to
  six samples up to its next move), less K times half a sample's OP travel (the part of OP
  beyond the threshold it followed, times He's overshoot factor, as
  :mod:`stiction.quantify.hewang` corrects its J). Where OP moves more in one sample than a
  tenth of the slip, the slip is known only to that sample's travel.

In He's terms (He & Wang 2014 eqs 6-8): just after a jump the net force OP - position is
``fs - J`` and the next jump the other way comes at ``-fs``, so ``band = 2 fs - J``; hence
``fs = (band + slip) / 2`` and ``fd = fs - slip / K`` (K He's overshoot factor; with K = 1:
``fd = (band - slip) / 2``, ``fs = (band + slip) / 2``). The position must be in OP's units
(the valve's gain 1: % of span both, the gateway's point scale makes it so); the band is
independent of any offset between the two, the slip of none.

A move is the position (its running median of five samples: noise shrinks, a jump passes
unchanged) leaving, by more than ``6`` white-noise SDs of the raw position
(:func:`noise_sd`), the level it last moved to (a hysteresis tracker, so a valve that
follows a slow ramp in steps smaller than its noise still moves). From the moves:

* fewer than two valve reversals while OP, since the valve last moved (over at least 30 % of
  the window), ran 20 of its noise SDs, twice the band a following valve reads and, when
  the span is known, 5 % of it (the thresholds of
  :mod:`stiction.diagnosis.responding`): the positioner does not follow OP
  (``not_responding``);
* at least two valve reversals: the band and slip are their medians; the valve **sticks**
  when the band exceeds what a valve following OP reads (``follow_limit``: two move thresholds
  plus two samples' OP travel and four OP noise SDs, at least 0.1 % of ``span`` when known),
  else it **follows** (no stiction, whatever PV does: an oscillation is then from elsewhere);
* otherwise (a calm loop, a position without usable samples) the travel cannot tell, and
  the caller keeps what OP and PV say.

**A position** is evidence only after it has shown it is one (issue 35: read inverted, PV
wired in its place, as a 0-1 fraction or a few samples late, it gave confident verdicts the
other way): where the valve sticks or follows, the reading is :data:`NOT_A_POSITION`
(the caller keeps OP and PV's verdict, and says why) unless

* it moves **with OP's direction**: at least ``WITH_OP`` of its moves (after the first) go
  the way OP, read on its trend, went since the move before (a valve moves only where OP
  pushes it; measured 0.94-1.0 on He's, Choudhury's and Kano's valves, 0-0.29 inverted or
  PV in its place);
* **in OP's scale**: its travel over its moves per OP unit OP travelled between them lies in
  ``SCALE`` (a sticky valve jumps a part of the band OP crossed, a following one all of it:
  0.05-1.05 measured; a 0-1 fraction of a percentage 0.001-0.01);
* **without a lag** over ``MAX_LAG`` samples (:func:`_lag`): read that much later than OP,
  a following valve shows a band of OP's travel over the lag. A lag is told where OP, read
  so much earlier, clearly matches the position; it only rejects a sticky reading whose band
  the lag explains (read so, the valve follows). A sticky valve's position read late is still
  used: its band is then larger by OP's travel over the lag.

The caller checks a valve that did not respond against PV
(:func:`stiction.diagnosis.travel.frozen_reading`).

Kano, Maruta, Kugemoto & Shimizu (2004) detect stiction from the valve position the same way
(stuck intervals while OP moves); Choudhury et al. (2005) define S and J as read here.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike

from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.arrays import median, medians
from ..signal.noise import noise_sd

__all__ = ["FOLLOWS", "NOT_A_POSITION", "NOT_RESPONDING", "STICKS", "UNUSABLE", "Shown",
           "Travel", "measure_travel", "shown_as_position"]

STICKS = "sticks"
FOLLOWS = "follows"
NOT_RESPONDING = "not_responding"
UNUSABLE = "unusable"  # the travel cannot tell: the caller keeps OP/PV's diagnosis
NOT_A_POSITION = "not_a_position"  # it did not show it is the valve's position: OP/PV's too

MOVE_SDS = 6.0  # a move: the position leaves its last level by this many noise SDs
MIN_SAMPLES = 64
MAX_MISSING = 0.1  # share of samples without a position (or OP) that may be filled
TREND = 6  # OP samples in the line that reads OP at a move
MIN_SPAN_BAND = 0.001  # a band below 0.1 % of span is a valve that follows
OP_NOISE = 20.0  # a valve that does not follow: OP ran this many of its noise SDs
MIN_SPAN_TRAVEL = 0.05  # ... and 5 % of span, when known
STILL_SHARE = 0.3  # ... over at least this share of the window since the valve last moved
MEDIAN = 5  # samples of the running median the position's moves are read from
WITH_OP = 0.7  # a position: at least this share of its moves go the way OP went since the last
SCALE = (0.02, 3.0)  # ... and it travels this share of OP's travel between its moves
MAX_LAG = 2  # ... and read up to this many samples earlier it does not follow where it sticks
LAG_READ = 10  # the lags tried
LAG_SPREAD = 0.5  # a lag: OP read so much earlier leaves at most this share of the difference

Moves = tuple[list[int], list[int]]
"""The samples at which the valve moved and the direction of each move (+1/-1)."""


@dataclasses.dataclass(frozen=True)
class Shown:
    """What the position showed of being one: ``with_op`` the share of its moves (after the
    first) that went the way OP went since its previous move, ``scale`` its travel over its
    moves per OP unit OP travelled between them; ``why`` it is not the valve's position
    (None: it showed it is), a phrase."""

    moves: int
    with_op: float
    scale: float
    why: str | None


def shown_as_position(op: FloatArray, filt: FloatArray, moves: Moves) -> Shown:
    """Whether the position moves with OP's direction, in OP's scale (module doc, "a
    position"), from its ``moves`` and OP read on its trend (a line through ``TREND``
    samples up to each move)."""
    at, way = moves
    u = np.array([_line_at(op[max(0, i - TREND + 1):i + 1], at_end=True)[0] for i in at])
    du, dx = np.diff(u), np.diff(filt[np.asarray(at, dtype=np.intp)])
    with_op = float(np.mean(np.sign(du) == np.asarray(way[1:]))) if du.size else 0.0
    travel = float(np.abs(du).sum())
    scale = float(np.abs(dx).sum()) / travel if travel > 0 else float("inf")
    why = None
    if with_op < WITH_OP:
        why = (f"{1 - with_op:.0%} of its {du.size} moves went against OP's travel since the "
               "one before (inverted, or not the valve's position: PV wired in?)")
    elif not SCALE[0] <= scale <= SCALE[1]:
        why = (f"it travels {scale:.3g} times as far as OP between its moves (not in OP's "
               "units: a 0-1 fraction of a percentage, or another scale?)")
    return Shown(len(at), with_op, scale, why)


@dataclasses.dataclass(frozen=True)
class Travel:
    """What the valve's travel says, in OP units (``band``, ``slip``, ``fd``, ``fs``).

    ``status`` is :data:`STICKS`, :data:`FOLLOWS`, :data:`NOT_RESPONDING` or :data:`UNUSABLE`;
    ``note`` one sentence saying why; ``reversals`` the valve reversals measured,
    ``sticking`` how many of them showed a band beyond ``follow_limit``; ``bands`` and
    ``slips`` each reversal's reading (empty when none was measured)."""

    status: str
    note: str
    band: float | None = None
    slip: float | None = None
    fd: float | None = None
    fs: float | None = None
    reversals: int = 0
    sticking: int = 0
    follow_limit: float | None = None
    bands: FloatArray = dataclasses.field(default_factory=lambda: np.empty(0), repr=False)
    slips: FloatArray = dataclasses.field(default_factory=lambda: np.empty(0), repr=False)
    shown: Shown | None = None  # what the position showed of being one, where it moved
    still_from: int = 0  # the sample after the valve's last move

    @property
    def decides(self) -> bool:
        """Whether the travel decides the verdict (else OP and PV do)."""
        return self.status not in (UNUSABLE, NOT_A_POSITION)

    @property
    def share_sticking(self) -> float:
        """Share of the measured reversals that stuck (0 without any)."""
        return self.sticking / self.reversals if self.reversals else 0.0


def _filled(op: FloatArray, pos: FloatArray) -> tuple[FloatArray, FloatArray] | str:
    """Both series with short gaps filled linearly, or why the position is unusable."""
    ok = np.isfinite(op) & np.isfinite(pos)
    n_ok = int(np.count_nonzero(ok))
    if n_ok < MIN_SAMPLES or n_ok < (1.0 - MAX_MISSING) * op.size:
        what = "no" if n_ok == 0 else f"only {n_ok} of {op.size}"
        return f"{what} samples with both OP and the position"
    if n_ok == op.size:
        return op, pos
    x = np.arange(op.size)
    return np.interp(x, x[ok], op[ok]), np.interp(x, x[ok], pos[ok])


def running_median(x: FloatArray, width: int = MEDIAN) -> FloatArray:
    """Centred running median of ``width`` (odd) samples, the ends padded with their
    values: white noise shrinks, a jump or a ramp passes unchanged."""
    if x.size < width:
        return x.copy()
    half = width // 2
    padded = np.concatenate((np.full(half, x[0]), x, np.full(half, x[-1])))
    windows = np.lib.stride_tricks.sliding_window_view(padded, width)
    return medians(windows)


def _moves(pos: FloatArray, h: float) -> tuple[list[int], list[int]]:
    """Sample indices and directions (+1/-1) where the position leaves, by more than
    ``h``, the level it last moved to."""
    at: list[int] = []
    way: list[int] = []
    ref = float(pos[0])
    for i, x in enumerate(pos.tolist()):
        if x - ref > h:
            at.append(i)
            way.append(1)
            ref = x
        elif ref - x > h:
            at.append(i)
            way.append(-1)
            ref = x
    return at, way


def _line_at(y: FloatArray, at_end: bool) -> tuple[float, float]:
    """A least-squares line through ``y``: its value at the last (``at_end``) or the first
    sample, and its slope per sample."""
    if y.size < 2:
        return float(y[-1] if at_end else y[0]), 0.0
    t = np.arange(y.size, dtype=np.float64) - (y.size - 1) / 2.0
    slope = float(np.dot(t, y - y.mean()) / np.dot(t, t))
    return float(y.mean() + slope * (t[-1] if at_end else t[0])), slope


def _level_after(raw: FloatArray, i: int, end: int) -> float:
    """The valve's level at sample ``i`` read from a line through the raw samples from it
    up to ``end`` (at most ``TREND``): unbiased whether it rests there or moves on."""
    return _line_at(raw[i:min(i + TREND, end)], at_end=False)[0]


def _jump(raw: FloatArray, filt: FloatArray, op: FloatArray, *, i: int, d: int, h: float,
          before: float, end: int) -> float:
    """The valve's jump at move ``i`` (direction ``d``): over the samples in which it moves
    faster than OP (a slow positioner's travel too), from its level ``before`` to its level
    after (:func:`_level_after`, up to the next move ``end``)."""
    j = i
    while j + 1 < end and d * (filt[j + 1] - filt[j]) > abs(op[j + 1] - op[j]) + h / 2:
        j += 1
    return d * (_level_after(raw, j, end) - before)


def _reversals(op: FloatArray, raw: FloatArray, filt: FloatArray, moves: Moves, *,
               h: float, k: float) -> tuple[FloatArray, FloatArray, int]:
    """Per valve reversal, the band (OP travel between the last move one way and the first
    move back) and the slip (the jump of that first move back), OP units; and the sample
    after the valve's last move (0: it never moved).

    The last move one way is read at the tracker's last trigger, plus the valve's travel
    from there to where it rested (a valve that follows OP goes on up to ``h`` after the
    trigger, OP with it): its level at the trigger against the mean of the raw samples
    before the move back."""
    at, way = moves
    bands: list[float] = []
    slips: list[float] = []
    for m in range(1, len(at)):
        d, last, brk = way[m], at[m - 1], at[m]
        if d == way[m - 1]:
            continue
        rest = float(raw[max(last + 1, brk - TREND):brk].mean()) if brk > last + 1 \
            else float(raw[last])
        u_last = _line_at(op[max(0, last - TREND + 1):last + 1], at_end=True)[0] + \
            rest - _level_after(raw, last, brk)
        u_break, rate = _line_at(op[max(0, brk - TREND + 1):brk + 1], at_end=True)
        end = at[m + 1] if m + 1 < len(at) else raw.size
        bands.append(d * (u_break - u_last) - abs(rate) / 2.0)
        slips.append(_jump(raw, filt, op, i=brk, d=d, h=h, before=rest, end=end)
                     - k * abs(rate) / 2.0)
    return np.asarray(bands), np.asarray(slips), at[-1] + 1 if at else 0


def measure_travel(op: ArrayLike, position: ArrayLike, *, k: float = 1.0,
                   span: float | None = None) -> Travel:
    """Stiction measured from OP against the valve's position (module doc).

    Parameters
    ----------
    op, position
        Equal-length 1-D sequences, both in OP units (position as % of span when OP is);
        NaN marks a missing sample (up to 10 % are filled linearly).
    k
        He's overshoot factor K in [1, 2] for ``fd = fs - slip / K``; band and slip do not
        depend on it.
    span
        OP travel of the valve's full span, when known: a band below 0.1 % of it is a valve
        that follows.

    Returns
    -------
    Travel
        The status, the band and slip (medians over the valve's reversals) and fd, fs in He's
        terms when the valve sticks, all in OP units.
    """
    op_a = np.asarray(op, dtype=np.float64)
    pos_a = np.asarray(position, dtype=np.float64)
    if op_a.ndim != 1 or pos_a.shape != op_a.shape:
        raise ParameterError("position", f"must be 1-D with the length of op ({op_a.size}), "
                                         f"has shape {pos_a.shape}")
    if not 1.0 <= k <= 2.0:
        raise ParameterError("k", f"must lie in [1, 2], was {k!r}")
    filled = _filled(op_a, pos_a)
    if isinstance(filled, str):
        return Travel(UNUSABLE, f"position unusable: {filled}")
    op_f, pos_f = filled
    sd_u, sd_x = noise_sd(op_f), noise_sd(pos_f)
    scale = max(float(np.ptp(op_f)), float(np.ptp(pos_f)), 1e-12)
    h = max(MOVE_SDS * sd_x, 1e-6 * scale)
    filt = running_median(pos_f)
    moves = _moves(filt, h)
    bands, slips, still_from = _reversals(op_f, pos_f, filt, moves, h=h, k=k)
    t = _judge(op_f, bands, slips, still_from=still_from, h=h, sd_u=sd_u, k=k, span=span)
    if t.status not in (STICKS, FOLLOWS):
        return t
    shown = shown_as_position(op_f, filt, moves)
    lag = None if shown.why is not None else _lag(op_f, pos_f)
    if lag is not None and t.status == STICKS:  # a band that the lag does not explain stays
        bands = _reversals(np.concatenate((np.full(lag, op_f[0]), op_f[:-lag])), pos_f, filt,
                           moves, h=h, k=k)[0]
        lag = lag if bands.size >= 2 and median(bands) <= (t.follow_limit or 0.0) else None
    why = shown.why if lag is None else (
        f"it lags OP by about {lag} samples, more than {MAX_LAG} (read so much earlier it "
        "follows OP: a band it shows is that lag, not friction)")
    if why is None:
        return dataclasses.replace(t, shown=shown)
    return Travel(NOT_A_POSITION, f"not used as the valve's position: {why}",
                  reversals=t.reversals, follow_limit=t.follow_limit, shown=shown)


def _lag(op: FloatArray, raw: FloatArray) -> int | None:
    """The position's lag behind OP, in samples, where it is clear: the shift at which OP,
    read that much earlier, is closest to the position (the least variance of their
    difference), where that is over ``MAX_LAG``, short of ``LAG_READ`` (a sticky valve's
    position trails OP by a part of its cycle, and the variance falls on up to the longest
    shift tried) and leaves at most ``LAG_SPREAD`` of the difference unshifted; else None."""
    n = op.size
    spread = [float(np.var(op[: n - lag] - raw[lag:])) for lag in range(LAG_READ + 1)]
    lag = int(np.argmin(spread))
    if lag <= MAX_LAG or lag == LAG_READ or spread[lag] > LAG_SPREAD * spread[0]:
        return None
    return lag


def _judge(op: FloatArray, bands: FloatArray, slips: FloatArray, *, still_from: int,
           h: float, sd_u: float, k: float, span: float | None) -> Travel:
    """The status from the reversals' readings (module doc)."""
    rate = median(np.abs(np.diff(op))) if op.size > 1 else 0.0
    limit = max(2.0 * h + 2.0 * rate + 4.0 * sd_u, 0.0 if span is None else MIN_SPAN_BAND * span)
    if bands.size < 2:
        tail = op[still_from:]
        need = max(OP_NOISE * sd_u, 2.0 * limit, 0.0 if span is None else MIN_SPAN_TRAVEL * span)
        if tail.size >= STILL_SHARE * op.size and float(np.ptp(tail)) >= need:
            return Travel(NOT_RESPONDING, f"OP travelled {np.ptp(tail):.3g} OP units over "
                          f"{tail.size} samples while the valve's position held within its "
                          f"noise", reversals=int(bands.size), follow_limit=limit,
                          still_from=still_from)
        return Travel(UNUSABLE, f"the valve reversed {bands.size} times: too few to measure "
                      f"its band", reversals=int(bands.size), follow_limit=limit)
    band, slip = median(bands), max(median(slips), 0.0)
    sticking = int(np.count_nonzero(bands > limit))
    common = {"reversals": int(bands.size), "sticking": sticking, "follow_limit": limit,
              "bands": bands, "slips": slips}
    if band <= limit:
        return Travel(FOLLOWS, f"the valve follows OP: band {band:.3g} OP units over "
                      f"{bands.size} reversals, within what a moving valve reads ({limit:.3g})",
                      band=max(band, 0.0), slip=slip, **common)  # type: ignore[arg-type]
    slip = min(slip, band)
    fs = (band + slip) / 2.0
    return Travel(STICKS, f"OP travels {band:.3g} OP units after a reversal before the valve "
                  f"moves, then it jumps {slip:.3g} (median of {bands.size} reversals)",
                  band=band, slip=slip, fd=fs - slip / k, fs=fs,
                  **common)  # type: ignore[arg-type]
