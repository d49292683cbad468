"""Pliant: simulate, control and learn soft robots with the finite element method.

The core is at hand from the package itself (``from pliant import Model, TetBody,
CableActuator, ImplicitEuler``): the model and its state, meshes, collision shapes, bodies and
materials, actuators, effectors, contacts, loads and supports, the solvers, the robots, the
environments' registry (``make``, ``ENVS``) and the SOFA loader (``load_scene``). Each name is
imported on first use (PEP 562), so that ``import pliant`` stays as light as it was and does
not import gymnasium or torch, which only the environments and the learners need.

Importing pliant sets how the compiled and BLAS code uses threads, before NumPy, SciPy or numba
start any (each choice is the user's to override, and is measured where it is made below):
numba's threading layer prefers OpenMP (``NUMBA_THREADING_LAYER`` overrides), OpenMP threads
sleep at barriers (``OMP_WAIT_POLICY``, default ``PASSIVE``), and OpenBLAS runs one thread
(``PLIANT_BLAS_THREADS=n``, ``=keep``, or ``OPENBLAS_NUM_THREADS`` override).
"""

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

# The package face: public name -> the module that defines it (imported on first use).
_FACE = {
    "Model": "pliant.model",
    "State": "pliant.model",
    "TetBody": "pliant.fem",
    "RodBody": "pliant.fem",
    "RodSection": "pliant.fem",
    "Membrane": "pliant.fem",
    "RigidBody": "pliant.fem",
    "KinematicBody": "pliant.fem",
    "DrivenNodes": "pliant.fem",
    "Corotational": "pliant.fem",
    "NeoHookean": "pliant.fem",
    "StVenantKirchhoff": "pliant.fem",
    "NodalForces": "pliant.fem",
    "SurfacePressure": "pliant.fem",
    "SurfaceTraction": "pliant.fem",
    "FollowerForce": "pliant.fem",
    "RestShapeSprings": "pliant.fem",
    "OnLine": "pliant.fem",
    "OnPlane": "pliant.fem",
    "Projection": "pliant.fem",
    "CableActuator": "pliant.constraints",
    "CavityActuator": "pliant.constraints",
    "RotationActuator": "pliant.constraints",
    "PositionEffector": "pliant.constraints",
    "RigidEffector": "pliant.constraints",
    "Contacts": "pliant.constraints",
    "Plane": "pliant.geometry",
    "Box": "pliant.geometry",
    "Sphere": "pliant.geometry",
    "Capsule": "pliant.geometry",
    "TriangleMesh": "pliant.geometry",
    "EmbeddedPoints": "pliant.constraints",
    "InverseControl": "pliant.constraints",
    "DirectControl": "pliant.constraints",
    "ImplicitEuler": "pliant.solvers",
    "RigidSolver": "pliant.solvers",
    "RigidWorld": "pliant.solvers",
    "StaticSolver": "pliant.solvers",
    "Solver": "pliant.solvers",
    "CondensingSolver": "pliant.solvers",
    "BatchedImplicitEuler": "pliant.solvers",
    "TetMesh": "pliant.mesh",
    "load_mesh": "pliant.mesh",
    "build_robot": "pliant.robots",
    "ROBOTS": "pliant.robots",
    "make": "pliant.envs",
    "ENVS": "pliant.envs",
    "load_scene": "pliant.sofa",
}
# Where the face's name differs from the module's.
_RENAMED = {"build_robot": "build"}

__all__ = ["__version__", *_FACE]


def __getattr__(name: str):
    module = _FACE.get(name)
    if module is None:
        raise AttributeError(f"module 'pliant' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), _RENAMED.get(name, name))
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_FACE})
