"""Pliant: simulate, control and learn soft robots with the finite element method."""

import os as _os

import numba as _numba

# OpenMP before TBB for the compiled kernels (unless the user chose a layer): TBB's workers keep
# the cores busy between parallel regions, which slows the single-threaded sparse solves that
# follow each kernel. Measured on the Diamond step: 2.30 ms with TBB, 1.76 ms with OpenMP.
if "NUMBA_THREADING_LAYER" not in _os.environ:
    _numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]
# OpenMP threads that wait at a barrier sleep rather than spin (unless the user chose): GNU
# OpenMP's default spins for about a millisecond, which on a machine whose cores are shared
# takes the time slices the working threads need, worst of all when the other work spins too.
# Trunk step with 8 cables, ms, with another Pliant process on the 2 cores: spinning 19.3,
# sleeping 2.4. On a quiet machine sleeping costs about a quarter of the Diamond's step rate
# (measured 335 against 440 steps/s): set OMP_WAIT_POLICY=ACTIVE on a dedicated machine.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _limit_blas_threads() -> None:
    """NumPy's and SciPy's OpenBLAS on one thread (unless OPENBLAS_NUM_THREADS or
    PLIANT_BLAS_THREADS says otherwise; PLIANT_BLAS_THREADS=keep leaves them alone).

    Pliant's dense algebra is small (constraint problems of tens of rows, reduced systems of
    tens of modes, QPs), where OpenBLAS's threads cost more than they give, and their
    busy-waiting takes the time slices the compiled kernels need. Measured on the reduced
    Multigait environment (42 modes, 150 elements; a product of 42 x 1800 by 1800 x 42 and a
    42 x 42 Cholesky solve a step), 2 cores shared with other work: 6 environment steps in 24 s
    with two OpenBLAS threads, 0.54 s with one. The full-FEM environments (Diamond, Trunk,
    TrunkPush, CartStemContact, Multigait) ran at the same rate either way, within the
    machine's noise. CHOLMOD (cvxopt's OpenBLAS) is single-threaded already."""
    wanted = _os.environ.get("PLIANT_BLAS_THREADS")
    if wanted == "keep" or (wanted is None and "OPENBLAS_NUM_THREADS" in _os.environ):
        return
    try:
        threads = max(1, int(wanted)) if wanted is not None else 1
    except ValueError:
        threads = 1
    import scipy.linalg  # noqa: F401  (loads SciPy's OpenBLAS beside NumPy's, to limit both)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads, user_api="blas")


_limit_blas_threads()

# ProxQP's reproducible (baseline) build, loaded before anything else imports proxsuite.
from pliant import _proxsuite  # noqa: E402, F401

__version__ = "0.1.0"
