"""Pliant: simulate, control and learn soft robots with the finite element method."""

import os as _os

import numba as _numba

# OpenMP before TBB for the compiled kernels (unless the user chose a layer): TBB's workers keep
# the cores busy between parallel regions, which slows the single-threaded sparse solves that
# follow each kernel. Measured on the Diamond step: 2.30 ms with TBB, 1.76 ms with OpenMP.
if "NUMBA_THREADING_LAYER" not in _os.environ:
    _numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]
# OpenMP threads that wait at a barrier spin for a bounded time, then sleep (unless the user
# chose): GNU OpenMP's default spins for about a millisecond, which on a machine whose cores
# are busy with other work takes the time slices the working threads need. Diamond step with
# 4 cables, steps/s, quiet / 2 cores shared with 2 busy processes: default spinning 440 / 81,
# sleeping at once (OMP_WAIT_POLICY=PASSIVE) 335 / 167, 50000 spins 436 / 145.
if "OMP_WAIT_POLICY" not in _os.environ:
    _os.environ.setdefault("GOMP_SPINCOUNT", "50000")

__version__ = "0.1.0"
