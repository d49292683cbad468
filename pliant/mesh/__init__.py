"""Tetrahedral meshes: parametric robot bodies (gmsh), file I/O (meshio), quality checks."""

from pliant.mesh.io import load_mesh, save_mesh
from pliant.mesh.locate import locate_points
from pliant.mesh.quality import fix_orientation, remove_unused_nodes, validate_mesh
from pliant.mesh.shapes import PneuNetLayout, box_beam, diamond, pneunet, soft_finger, trunk
from pliant.mesh.tetmesh import TetMesh

__all__ = [
    "PneuNetLayout",
    "TetMesh",
    "box_beam",
    "diamond",
    "fix_orientation",
    "load_mesh",
    "locate_points",
    "pneunet",
    "remove_unused_nodes",
    "save_mesh",
    "soft_finger",
    "trunk",
    "validate_mesh",
]
