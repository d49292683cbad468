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

__version__ = "0.1.0"
