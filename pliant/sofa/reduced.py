"""SOFA's reduced-order models (the ModelOrderReduction plugin) read as the full model they
reduce.

A reduced scene (SofaGym's MultiGaitRobot) keeps the full body's node, mesh and force fields
and maps a small state onto it: a ``Vec1d`` MechanicalObject of mode amplitudes, a
``ModelOrderReductionMapping`` from it to the body's MechanicalObject through the modes file
(the displacement is the modes times the amplitudes), ``HyperReducedTetrahedronFEMForceField``
/ ``HyperReducedTriangleFEMForceField`` (SOFA's FEM integrated on a reduced integration domain
with ECSW weights: an approximation of the full sum over the elements) and a
``MechanicalMatrixMapperMOR`` that assembles the reduced matrices.

Pliant reads such a scene as the model it approximates: the body's MechanicalObject is its
state, the hyper-reduced force fields are their full FEM (same law, every element), the
mapping and the matrix mapper are dropped, and the amplitudes' MechanicalObject keeps its first
values (zeros: a script that reads them, as SofaGym's MultiGait state does, reads zeros). This
is a departure: the motion is the full model's, not the reduction's, and a step costs the full
model's. The modes, domains and weights files are not read (SofaGym's repository does not hold
the MultiGait's modes: SOFA itself cannot load that scene from it). :func:`full_order`
rewrites the scene's tree before it is read and says what it changed; the loader warns with
:class:`ReducedOrderWarning`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pliant.sofa.tree import SceneNode

if TYPE_CHECKING:
    from pliant.sofa.loader import _Builder

MAPPING = "ModelOrderReductionMapping"
MATRIX_MAPPER = "MechanicalMatrixMapperMOR"
# The amplitudes' MechanicalObject, once read so: its data stay readable (a SofaGym state
# lists them), nothing moves it.
AMPLITUDES = "ReducedOrderAmplitudes"
# Each hyper-reduced force field and the full one it integrates on part of the elements.
FULL = {
    "HyperReducedTetrahedronFEMForceField": "TetrahedronFEMForceField",
    "HyperReducedTriangleFEMForceField": "TriangleFEMForceField",
}
# Their data about the reduction (modes, domain, weights, training): not read.
REDUCTION_DATA = frozenset(
    {
        "prepareECSW",
        "performECSW",
        "nbModes",
        "modesPath",
        "RIDPath",
        "weightsPath",
        "nbTrainingSet",
        "periodSaveGIE",
    }
)


class ReducedOrderWarning(UserWarning):
    """A SOFA scene's reduced-order model was read as the full model it reduces."""


def has_reduction(root: SceneNode) -> bool:
    return any(o.type == MAPPING or o.type in FULL for n in root.walk() for o in n.objects)


def full_order(builder: _Builder) -> list[str]:
    """Rewrite the reduced-order components of `builder`'s scene as the full model (see the
    module text); the changes, one line each (empty: none)."""
    changes = []
    for node in list(builder.root.walk()):
        for obj in list(node.objects):
            if obj.type == MAPPING:
                amplitudes = builder.link_dofs(node, str(obj.attrs.get("input", "")))
                node.objects.remove(obj)
                if amplitudes is not None:  # kept for scripts that read it, inert
                    object.__setattr__(amplitudes, "type", AMPLITUDES)
                changes.append(
                    f"{obj.path}: the mapping from the mode amplitudes dropped; {node.path}'s"
                    " MechanicalObject is the body's state (the amplitudes keep their first"
                    " values)"
                )
            elif obj.type == MATRIX_MAPPER:
                node.objects.remove(obj)
            elif obj.type in FULL:
                full = FULL[obj.type]
                changes.append(f"{obj.path}: {obj.type} read as {full} on every element")
                object.__setattr__(obj, "type", full)
                for key in REDUCTION_DATA & obj.attrs.keys():
                    del obj.attrs[key]
    return changes
