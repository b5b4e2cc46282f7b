"""Bounded scalar minimisation: Brent's method as ``scipy.optimize.fminbound`` runs it.

The same iterates and the same result, bit for bit (the same arithmetic in the same order),
without SciPy's per-iteration NumPy scalar operations and result object: the time-constant
fit of the switching points calls it twice per sized window, some ten function evaluations
each, and there the wrapper cost as much as the evaluations.
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["fminbound"]

_SQRT_EPS = math.sqrt(2.2e-16)
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


def _sign(x: float) -> float:
    """``np.sign(x) + (x == 0)``: 1 for 0 and positive, -1 for negative."""
    return -1.0 if x < 0 else 1.0


def fminbound(func: Callable[[float], float], x1: float, x2: float, *, xtol: float = 1e-5,
              maxfun: int = 500) -> float:
    """The ``x`` in ``[x1, x2]`` minimising ``func`` (finite bounds, ``x1 <= x2``):
    ``scipy.optimize.fminbound(func, x1, x2, xtol=xtol, maxfun=maxfun)``, the same value."""
    a, b = float(x1), float(x2)
    fulc = a + _GOLDEN * (b - a)
    nfc = xf = fulc
    rat = e = 0.0
    fx = func(xf)
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * abs(xf) + xtol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        golden = True
        if abs(e) > tol1:  # a parabolic step, if acceptable
            golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r = e
            e = rat
            if abs(p) < abs(0.5 * q * r) and p > q * (a - xf) and p < q * (b - xf):
                rat = (p + 0.0) / q
                x = xf + rat
                if (x - a) < tol2 or (b - x) < tol2:
                    rat = tol1 * _sign(xm - xf)
            else:
                golden = True
        if golden:
            e = (a - xf) if xf >= xm else (b - xf)
            rat = _GOLDEN * e
        x = xf + _sign(rat) * max(abs(rat), tol1)
        fu = func(x)
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if fu <= fnfc or nfc == xf:
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif fu <= ffulc or fulc == xf or fulc == nfc:  # noqa: PLR1714, SIM109
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = _SQRT_EPS * abs(xf) + xtol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            break
    return xf
