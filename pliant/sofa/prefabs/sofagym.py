"""SofaGym's shared scene helpers (``sofagym.header``, ``sofagym.utils``) that its
environments' scenes import, written for Pliant from what they are documented to add.

``addHeader`` sets up the root as SofaGym's scenes expect (frictional contact pipeline,
constraint-based loop, animation manager, gravity and time step); ``addVisu`` adds cameras and
lights only, which Pliant does not draw. The beam and rigid-mesh builders of ``sofagym.utils``
need models Pliant lacks (Cosserat rods; rigid bodies given by a mesh and a density): they
stop the load with a :class:`SceneError` naming what is missing.
"""

from __future__ import annotations

from pliant.sofa.prefabs.splib import AnimationManager
from pliant.sofa.prefabs.stlib import ContactHeader
from pliant.sofa.tree import SceneError, SceneNode


def addHeader(  # noqa: N802 (SofaGym's names)
    rootNode: SceneNode,  # noqa: N803
    alarmDistance: float = 2.0,  # noqa: N803
    contactDistance: float = 0.5,  # noqa: N803
    tolerance: float = 1e-6,
    maxIterations: int = 500,  # noqa: N803
    gravity=(0.0, -981.0, 0.0),
    dt: float = 0.03,
    mu: str | float = "0.8",
    genericConstraintSolver: bool = True,  # noqa: N803
) -> None:
    """The root of a SofaGym scene: the contact pipeline with friction `mu` and the given
    distances, the constraint-based animation loop (with SOFA's constraint solver, which
    Pliant replaces by its exact one), the animation manager, gravity and time step."""
    ContactHeader(rootNode, alarmDistance, contactDistance, frictionCoef=float(mu))
    if genericConstraintSolver:
        rootNode.addObject(
            "GenericConstraintSolver", tolerance=tolerance, maxIterations=maxIterations
        )
    AnimationManager(rootNode)
    rootNode.gravity = list(gravity)
    rootNode.dt = dt


def addVisu(rootNode: SceneNode, config, position, direction, cutoff: float = 250.0) -> None:  # noqa: N802, N803
    """Cameras and spot lights: nothing Pliant simulates."""


def _lacks(what: str):
    def refuse(*_args, **_kwargs):
        raise SceneError(f"sofagym.utils.{what}: Pliant has no {_LACKS[what]}")

    refuse.__name__ = what
    return refuse


_LACKS = {
    "createCosserat": "Cosserat rod (SOFA's Cosserat plugin)",
    "addRigidObject": "rigid body given by a mesh and a density (its rigid bodies are boxes)",
    "addEdgeCollision": "collision model on a Cosserat rod's edges",
}


def header_members() -> dict:
    return {"addHeader": addHeader, "addVisu": addVisu}


def utils_members() -> dict:
    return {name: _lacks(name) for name in _LACKS}
