"""Pliant: simulate, control and learn soft robots with the finite element method."""

import os as _os

import numba as _numba

# OpenMP before TBB for the compiled kernels (unless the user chose a layer): TBB's workers keep
# the cores busy between parallel regions, which slows the single-threaded sparse solves that
# follow each kernel. Measured on the Diamond step: 2.30 ms with TBB, 1.76 ms with OpenMP.
if "NUMBA_THREADING_LAYER" not in _os.environ:
    _numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]
# OpenMP threads that wait at a barrier sleep rather than spin (unless the user chose): on a
# machine whose cores are busy with other work, spinning threads take the time slices the
# working ones need. Measured on the Diamond step with 2 cores shared by 4 other processes:
# 33-45 steps/s spinning (the default), 178-185 sleeping.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.1.0"
