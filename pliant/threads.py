"""How Pliant's compiled and BLAS code uses threads: one documented function,
:func:`configure_threads`.

``import pliant`` calls it once with its defaults, because two of its settings only take effect
before the thread pools they govern start, which the first compiled kernel or the first NumPy
call of any script may do: OpenMP reads ``OMP_WAIT_POLICY`` when it starts, and numba chooses
its threading layer at the first parallel kernel. Each default is the user's to override, by
an environment variable set before ``import pliant`` or by calling the function again (the
BLAS and PyTorch thread counts change at any time; the other two only until the first parallel
kernel runs). Entry points that choose threads (``pliant train --torch-threads``) call it.
"""

from __future__ import annotations

import os

import numba

from pliant.errors import ThreadSettingError

# OpenMP before TBB for the compiled kernels (unless the user chose a layer): TBB's workers keep
# the cores busy between parallel regions, which slows the single-threaded sparse solves that
# follow each kernel. Measured on the Diamond step: 2.30 ms with TBB, 1.76 ms with OpenMP.
THREADING_LAYERS = ("omp", "tbb", "workqueue")
# OpenMP threads that wait at a barrier sleep rather than spin (unless the user chose): GNU
# OpenMP's default spins for about a millisecond, which on a machine whose cores are shared
# takes the time slices the working threads need, worst of all when the other work spins too.
# Trunk step with 8 cables, ms, with another Pliant process on the 2 cores: spinning 19.3,
# sleeping 2.4. On a quiet machine sleeping costs about a quarter of the Diamond's step rate
# (measured 335 against 440 steps/s): set OMP_WAIT_POLICY=ACTIVE on a dedicated machine.
WAIT_POLICY = "PASSIVE"
# NumPy's and SciPy's OpenBLAS on one thread. Pliant's dense algebra is small (constraint
# problems of tens of rows, reduced systems of tens of modes, QPs), where OpenBLAS's threads
# cost more than they give, and their busy-waiting takes the time slices the compiled kernels
# need. Measured on the reduced Multigait environment (42 modes, 150 elements; a product of
# 42 x 1800 by 1800 x 42 and a 42 x 42 Cholesky solve a step), 2 cores shared with other work:
# 6 environment steps in 24 s with two OpenBLAS threads, 0.54 s with one. The full-FEM
# environments (Diamond, Trunk, TrunkPush, CartStemContact, Multigait) ran at the same rate
# either way, within the machine's noise. CHOLMOD (cvxopt's OpenBLAS) is single-threaded
# already.
BLAS_THREADS = 1


def configure_threads(
    *,
    threading_layers: tuple[str, ...] | None = None,
    omp_wait_policy: str | None = None,
    blas_threads: int | str | None = None,
    torch_threads: int | None = None,
) -> dict:
    """Set how the compiled kernels, OpenBLAS and PyTorch use threads; returns what was set.

    An argument left out takes Pliant's default, unless the environment says otherwise:

    - `threading_layers`: numba's threading layers in order of preference (default OpenMP,
      then TBB, then numba's own; ``NUMBA_THREADING_LAYER`` wins over the default). Effective
      until the first parallel kernel runs.
    - `omp_wait_policy`: ``"PASSIVE"`` (waiting threads sleep, the default) or ``"ACTIVE"``
      (they spin: faster on a dedicated machine); default ``OMP_WAIT_POLICY`` if set.
      Effective until OpenMP starts (the first parallel kernel).
    - `blas_threads`: NumPy's and SciPy's OpenBLAS threads, a count or ``"keep"`` (leave them
      alone); default ``PLIANT_BLAS_THREADS`` if set, else ``"keep"`` where
      ``OPENBLAS_NUM_THREADS`` is set, else 1. Effective at once, and again at each call.
    - `torch_threads`: PyTorch's threads (imports PyTorch); left alone by default.

    Raises ThreadSettingError for a setting that is not one of these.
    """
    applied: dict = {}
    if threading_layers is not None:
        layers = list(threading_layers)
        if not layers or not set(layers) <= set(THREADING_LAYERS):
            raise ThreadSettingError(
                f"threading_layers: a non-empty ordering of {THREADING_LAYERS}, got"
                f" {threading_layers!r}"
            )
        numba.config.THREADING_LAYER_PRIORITY = layers
    elif "NUMBA_THREADING_LAYER" not in os.environ:
        numba.config.THREADING_LAYER_PRIORITY = list(THREADING_LAYERS)
    applied["threading_layers"] = tuple(numba.config.THREADING_LAYER_PRIORITY)

    if omp_wait_policy is not None:
        if str(omp_wait_policy).upper() not in ("PASSIVE", "ACTIVE"):
            raise ThreadSettingError(
                f"omp_wait_policy: 'PASSIVE' or 'ACTIVE', got {omp_wait_policy!r}"
            )
        os.environ["OMP_WAIT_POLICY"] = str(omp_wait_policy).upper()
    else:
        os.environ.setdefault("OMP_WAIT_POLICY", WAIT_POLICY)
    applied["omp_wait_policy"] = os.environ["OMP_WAIT_POLICY"]

    threads = _blas_threads(blas_threads)
    if threads != "keep":
        import scipy.linalg  # noqa: F401  (loads SciPy's OpenBLAS beside NumPy's, to limit both)
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=threads, user_api="blas")
    applied["blas_threads"] = threads

    if torch_threads is not None:
        if (
            isinstance(torch_threads, bool)
            or not isinstance(torch_threads, int)
            or torch_threads < 1
        ):
            raise ThreadSettingError(f"torch_threads: an integer >= 1, got {torch_threads!r}")
        import torch

        torch.set_num_threads(torch_threads)
        applied["torch_threads"] = torch_threads
    return applied


def _blas_threads(wanted: int | str | None) -> int | str:
    """The OpenBLAS thread count asked for (an argument, else the environment's, else 1), or
    "keep"; an unreadable PLIANT_BLAS_THREADS reads as 1, as a typo must not stop an import."""
    if wanted is not None:
        if wanted == "keep":
            return "keep"
        if not _count(wanted):
            raise ThreadSettingError(f"blas_threads: an integer >= 1 or 'keep', got {wanted!r}")
        return wanted
    text = os.environ.get("PLIANT_BLAS_THREADS")
    if text == "keep" or (text is None and "OPENBLAS_NUM_THREADS" in os.environ):
        return "keep"
    try:
        return max(1, int(text)) if text is not None else BLAS_THREADS
    except ValueError:
        return BLAS_THREADS


def _count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1
