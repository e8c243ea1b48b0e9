"""Elementwise kernels of the expression language's ExprTk functions that numpy lacks.

OpenVCAD compiles its expression strings with ExprTk; these follow ExprTk's definitions
(``exprtk.hpp``, ``details::numeric``) on float64 arrays, so that a design means the same
in fgslice. Each kernel takes arrays or Python floats (constants are folded at compile
time by calling the kernel on floats) and, where it has an ``out`` parameter, may write
its result into ``out``, which can be one of its own arguments.
"""

from __future__ import annotations

import numpy as np

_MACHINE_EPSILON = float(np.finfo(np.float64).eps)


def erfc(x, out=None):
    """Complementary error function 1 - erf(x), accurate for large x (scipy, imported on
    first use)."""
    from scipy.special import erfc as scipy_erfc

    return scipy_erfc(x, out=out)


def sinc(x):
    """ExprTk's sinc: sin(x)/x where |x| >= machine epsilon, else 1 (NaN included)."""
    x = np.asarray(x, dtype=np.float64)
    large = np.absolute(x) >= _MACHINE_EPSILON
    return np.where(large, np.sin(x) / np.where(large, x, 1.0), 1.0)


def root(x, n):
    """ExprTk's root(x, n): x^(1/n); for x < 0 the real root -(|x|^(1/n)) when n is an odd
    integer, else NaN."""
    x = np.asarray(x, dtype=np.float64)
    inverse = np.divide(1.0, n)
    odd = np.equal(n, np.trunc(n)) & np.not_equal(np.fmod(n, 2.0), 0.0)
    negative = np.where(odd, -np.power(np.absolute(x), inverse), np.nan)
    return np.where(x < 0.0, negative, np.power(x, inverse))


def roundn(x, n):
    """ExprTk's roundn(x, n): x rounded to floor(n) decimals (clamped to 0..16), halves
    away from zero; NaN when n is NaN."""
    scale = np.power(10.0, np.clip(np.floor(n), 0.0, 16.0))
    scaled = np.multiply(x, scale)
    rounded = np.where(np.less(x, 0.0), np.ceil(scaled - 0.5), np.floor(scaled + 0.5))
    return rounded / scale
