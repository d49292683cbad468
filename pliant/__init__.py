"""Pliant: simulate, control and learn soft robots with the finite element method.

The core is at hand from the package itself (``from pliant import Model, TetBody,
CableActuator, ImplicitEuler``): the model and its state, meshes, collision shapes, bodies and
materials, actuators, effectors, contacts, loads and supports, the solvers, the robots, the
environments' registry (``make``, ``ENVS``) and the SOFA loader (``load_scene``). Each name is
imported on first use (PEP 562), so that ``import pliant`` stays as light as it was and does
not import gymnasium or torch, which only the environments and the learners need.

Importing pliant sets how the compiled and BLAS code uses threads, through
:func:`pliant.configure_threads` with its defaults (numba prefers OpenMP, OpenMP threads sleep
at barriers, OpenBLAS runs one thread), before a script's first kernel can start the pools:
each default is the user's to override, by ``NUMBA_THREADING_LAYER``, ``OMP_WAIT_POLICY``,
``PLIANT_BLAS_THREADS=n`` (or ``keep``, or ``OPENBLAS_NUM_THREADS``) or by calling
``pliant.configure_threads(...)`` again (see :mod:`pliant.threads`).
"""

from pliant.threads import configure_threads

configure_threads()

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
    "SurfaceContact": "pliant.constraints",
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

__all__ = ["__version__", "configure_threads", *_FACE]


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
