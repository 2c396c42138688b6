"""The training's least squares (imgform_rs.training.lstsq): exact sums, a solve that
agrees with LAPACK's, and filters that do not depend on the machine's BLAS kernels."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imgform_rs.training.lstsq import (
    EXACT,
    QUANTUM,
    NormalEquations,
    block_rows,
    cholesky_solve,
    parts,
)


def equations_of(x: np.ndarray, y: np.ndarray) -> NormalEquations:
    eq = NormalEquations(1, x.shape[1], y.shape[1])
    eq.add(0, x, y)
    return eq


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 400), st.integers(1, 12))
def test_the_sums_do_not_depend_on_the_order_of_the_samples(seed, n, nf):
    # Floating-point sums of products change in their last bits when the samples
    # are reordered (as BLAS kernels reorder them); exact sums cannot.
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, nf)).astype(np.float32)
    y = rng.random((n, 2)).astype(np.float32)
    order = rng.permutation(n)
    a, b = equations_of(x, y), equations_of(x[order], y[order])
    assert a.xtx.tobytes() == b.xtx.tobytes()
    assert a.xty.tobytes() == b.xty.tobytes()
    np.testing.assert_array_equal(a.xtx[0], a.xtx[0].T)


def test_the_sums_are_the_exact_sums_of_the_rounded_values():
    rng = np.random.default_rng(5)
    x = rng.random((300, 3)).astype(np.float32)
    xtx = equations_of(x, x[:, :1]).xtx[0]
    q = [[int(v) for v in row] for row in np.round(x.astype(np.float64) * 2.0**QUANTUM)]
    for i in range(3):
        for j in range(3):
            exact = sum(row[i] * row[j] for row in q)
            # Three exact partial sums, combined with at most two roundings.
            assert abs(xtx[i, j] - exact) <= 2 * np.spacing(float(exact))


def test_parts_rebuild_the_rounded_integers_and_blocks_stay_exact():
    x = np.array([0.0, 1.0, -1.0, 0.123456789, 2.0**-30, 1.9999999])
    high, low = parts(x)
    q = np.round(x * 2.0**QUANTUM)
    np.testing.assert_array_equal(high * 2.0**12 + low, q)
    assert np.abs(low).max() <= 2**11
    largest = np.abs(high).max()
    assert block_rows(largest) * largest**2 <= EXACT
    assert block_rows(0.0) == EXACT and block_rows(1e30) == 1


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.integers(1, 4))
def test_the_batched_cholesky_agrees_with_lapack(seed, n, m):
    rng = np.random.default_rng(seed)
    g = rng.standard_normal((m, n + 3, n))
    a = np.swapaxes(g, 1, 2) @ g + 0.1 * np.eye(n)
    b = rng.standard_normal((m, n, 2))
    np.testing.assert_allclose(cholesky_solve(a, b), np.linalg.solve(a, b), rtol=1e-8, atol=1e-8)


def test_a_system_that_is_not_positive_definite_is_refused():
    a = np.array([[[1.0, 2.0], [2.0, 1.0]]])
    with pytest.raises(ValueError, match="system 0 is not positive definite"):
        cholesky_solve(a, np.ones((1, 2, 1)))


def test_values_that_are_not_finite_are_refused():
    x = np.ones((4, 2))
    x[2, 1] = np.nan
    with pytest.raises(ValueError, match="system 3: features or targets are not finite"):
        NormalEquations(4, 2, 1).add(3, x, np.ones((4, 1)))


def test_the_solution_fits_a_linear_relation_and_skips_small_systems():
    rng = np.random.default_rng(1)
    x = rng.random((2000, 4))
    w = np.array([[0.5, -0.25, 0.125, 1.0], [1.0, 0.0, -1.0, 0.5]])
    eq = NormalEquations(3, 4, 2)
    eq.add(0, x, x @ w.T)
    eq.add(2, x[:10], x[:10] @ w.T)
    got = eq.solve(ridge=1e-9, min_samples=500)
    assert got.dtype == np.float32 and got.shape == (3, 2, 4)
    np.testing.assert_allclose(got[0], w, atol=1e-5)
    assert not got[1:].any()


# Trains the quick set in a fresh interpreter with the BLAS kernels `OPENBLAS_CORETYPE`
# names; prints a hash of a plain float64 product (which the kernels round
# differently) and of the weights.
PROBE = """
import hashlib, numpy as np
from imgform_rs.training.demosaic import train
x = np.random.default_rng(0).random((20000, 53))
print(hashlib.sha256((x.T @ x).tobytes()).hexdigest())
print(hashlib.sha256(train("fusion", small=True)).hexdigest())
"""


def train_with_kernels(core: str) -> list[str]:
    env = {**os.environ, "OPENBLAS_CORETYPE": core}
    run = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return run.stdout.split()


def test_the_trained_weights_do_not_depend_on_the_blas_kernels():
    # The shipped weights must come out bit for bit on any machine. NumPy's
    # OpenBLAS picks its kernels by CPU; OPENBLAS_CORETYPE makes two kernel sets
    # that every x86-64 machine with AVX2 runs (Haswell: AVX2, Nehalem: SSE4.2).
    pytest.importorskip("skimage.data")
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("OPENBLAS_CORETYPE names x86-64 kernels")
    avx2, sse = train_with_kernels("Haswell"), train_with_kernels("Nehalem")
    if avx2[0] == sse[0]:
        pytest.skip("this NumPy's BLAS does not switch kernels by OPENBLAS_CORETYPE")
    assert avx2[1] == sse[1]
