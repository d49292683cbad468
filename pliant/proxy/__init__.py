"""Beam-skeleton proxies of FEM soft robots (thesis §4.1): a lattice of Cosserat rods whose
rest curvature is the actuation, skinned with the FEM robot's surface and calibrated on it.

The proxy is a :class:`pliant.model.Model` of a :class:`pliant.fem.rod.RodBody`, stepped by
the same solvers as the FEM robots; only its actuation differs: a
:class:`~pliant.proxy.actuation.CurvatureActuation` sets the rods' rest curvature before each
step, so that the solvers, contacts and constraints see an ordinary rod.
"""

from pliant.proxy.actuation import Bending, CurvatureActuation
from pliant.proxy.builders import Proxy, multigait_proxy, trunk_proxy
from pliant.proxy.skinning import Skinning

__all__ = [
    "Bending",
    "CurvatureActuation",
    "Proxy",
    "Skinning",
    "multigait_proxy",
    "trunk_proxy",
]
