"""Least squares whose result is the same on every machine.

The learned demosaicers' filters solve, per class, normal equations summed over
millions of samples. Summed in floating point, the last bits of those sums depend on
the order of the additions, and that order is the BLAS library's choice by CPU:
NumPy's OpenBLAS sums ``x.T @ x`` one way with its AVX-512 kernels and another with
its AVX2 ones (``OPENBLAS_CORETYPE`` picks them), and LAPACK's solve does the same.
After the rounding to float32 the filters then differ here and there, so shipped
weights trained on one machine were not reproduced bit for bit on another.

Here nothing depends on the order of a sum:

- features and targets are rounded to multiples of ``2**-QUANTUM`` (float32's
  resolution at full scale for data in [0, 1]), and each such integer is split
  into a high and a low part of ``SPLIT`` bits, so that every product of parts is
  an integer far below ``2**53`` and blocks of samples are summed in float64
  *exactly*, in whatever order BLAS adds them (:func:`block_rows`);
- blocks are added to the totals in the order of the data;
- the systems are solved by a Cholesky factorisation written as element-wise
  NumPy operations over the batch of systems (no LAPACK, no reduction), each
  value rounded once per IEEE operation, which every CPU does alike.
"""

from __future__ import annotations

import math

import numpy as np

#: Features and targets are rounded to multiples of ``2**-QUANTUM``.
QUANTUM = 24
#: Bits of the low part of each integer (:func:`parts`).
SPLIT = 12
#: Integers up to this size are exact in float64.
EXACT = 2**53


def parts(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a`` in units of ``2**-QUANTUM``, rounded to the nearest (ties to even),
    as ``high * 2**SPLIT + low`` with ``|low| <= 2**(SPLIT - 1)``: two float64
    arrays of integers."""
    q = np.round(np.asarray(a, dtype=np.float64) * 2.0**QUANTUM)
    high = np.round(q * 2.0**-SPLIT)
    return high, q - high * 2.0**SPLIT


def block_rows(largest: float) -> int:
    """How many samples whose parts are at most ``largest`` in magnitude a block
    may hold for every partial sum of their products to be exact."""
    return max(1, int(EXACT // max(largest * largest, 1.0)))


def exact_products(x: tuple[np.ndarray, np.ndarray], y: tuple[np.ndarray, np.ndarray]):
    """``x.T @ y`` of two split arrays, in units of ``2**-2 QUANTUM``: the four
    products of parts are exact, their weighted sum rounds element by element."""
    (xh, xl), (yh, yl) = x, y
    high, low = xh.T @ yh, xl.T @ yl
    cross = xh.T @ yl + xl.T @ yh
    return (high * 2.0 ** (2 * SPLIT) + cross * 2.0**SPLIT) + low


class NormalEquations:
    """The normal equations of ``systems`` least-squares fits with ``features``
    inputs and ``outputs`` targets each, summed exactly block by block."""

    def __init__(self, systems: int, features: int, outputs: int):
        self.xtx = np.zeros((systems, features, features))
        self.xty = np.zeros((systems, features, outputs))
        self.count = np.zeros(systems, dtype=np.int64)

    def add(self, k: int, x: np.ndarray, y: np.ndarray) -> None:
        """Adds samples ``x`` (n, features) with targets ``y`` (n, outputs) to
        system ``k``. Raises ``ValueError`` for values that are not finite."""
        xs, ys = parts(x), parts(y)
        largest = max(np.abs(p).max(initial=0.0) for p in (*xs, *ys))
        if not math.isfinite(largest):
            raise ValueError(f"system {k}: features or targets are not finite")
        step = block_rows(largest)
        for start in range(0, len(x), step):
            xb = tuple(p[start : start + step] for p in xs)
            yb = tuple(p[start : start + step] for p in ys)
            self.xtx[k] += exact_products(xb, xb)
            self.xty[k] += exact_products(xb, yb)
        self.count[k] += len(x)

    def solve(self, ridge: float, min_samples: int) -> np.ndarray:
        """The solutions (systems, outputs, features) as float32: zero for the
        systems of fewer than ``min_samples`` samples, else of the equations
        with ``ridge`` times the mean of the diagonal added to it (plus 1e-12,
        so that an all-zero system stays solvable)."""
        n = self.xtx.shape[1]
        out = np.zeros((len(self.xtx), self.xty.shape[2], n), dtype=np.float32)
        solved = np.flatnonzero(self.count >= min_samples)
        if len(solved) == 0:
            return out
        # Back to the data's units: a power of two, exact.
        unit = 2.0 ** (-2 * QUANTUM)
        a, b = self.xtx[solved] * unit, self.xty[solved] * unit
        for system in a:
            # fsum: the trace rounded once, whatever the order.
            lift = ridge * math.fsum(np.diagonal(system).tolist()) / n + 1e-12
            system[np.arange(n), np.arange(n)] += lift
        out[solved] = np.swapaxes(cholesky_solve(a, b), 1, 2).astype(np.float32)
        return out


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solves the symmetric positive definite systems ``a`` (m, n, n) for the
    right-hand sides ``b`` (m, n, r), all m at once, by element-wise operations
    in a fixed order. Raises ``ValueError`` when a system is not positive
    definite."""
    n = a.shape[1]
    low = np.zeros_like(a)
    for j in range(n):
        column = a[:, j:, j].copy()
        for k in range(j):
            column -= low[:, j:, k] * low[:, j, k, None]
        pivot = column[:, 0]
        if not np.all(pivot > 0):
            raise ValueError(f"system {int(np.argmin(pivot))} is not positive definite")
        d = np.sqrt(pivot)
        low[:, j, j] = d
        low[:, j + 1 :, j] = column[:, 1:] / d[:, None]
    z = np.empty_like(b)
    for i in range(n):
        t = b[:, i].copy()
        for k in range(i):
            t -= low[:, i, k, None] * z[:, k]
        z[:, i] = t / low[:, i, i, None]
    w = np.empty_like(b)
    for i in reversed(range(n)):
        t = z[:, i].copy()
        for k in range(i + 1, n):
            t -= low[:, k, i, None] * w[:, k]
        w[:, i] = t / low[:, i, i, None]
    return w
