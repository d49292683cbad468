"""SOFA's own scenes (``sofa-reference`` beside the reference meshes) read by Pliant's scene
loader, which ``pliant bench`` times beside the figures SOFA gave on them."""

from __future__ import annotations

from pathlib import Path

# In SOFA's Trunk-and-cube scene the trunk reaches the cube by step 40 and pushes it on.
TRUNK_CUBE_WARMUP = 40

# SOFA's own scenes (sofa-reference beside the meshes) and the SPEC §5 figure each was timed as:
# both run 100 steps from rest, the first factorisation included, as SOFA's batch runner does
# (pliant.bench.timing.time_steps(from_rest=True): a new solver for each timed run). SOFA's
# trunk_cables.scn pulls one cable, L0, by 10 mm; the bench's "trunk+cables" row pulls the same.
SOFA_SCENES = {"diamond_plain.scn": "diamond", "trunk_cables.scn": "trunk+cables"}


def sofa_scene(meshes: Path, name: str):
    """A scene of ``sofa-reference`` beside the meshes read by the scene loader, or None where
    the folder is absent."""
    from pliant.sofa import load_scene

    path = Path(meshes).parent / "sofa-reference" / name
    return load_scene(path, mesh_dirs=[meshes]) if path.is_file() else None


def trunk_cables_cube(meshes: Path):
    """SOFA's own Trunk-and-cube scene (``sofa-reference/trunk_cables_cube.scn`` beside the
    meshes), read by the scene loader: the scene SOFA's 16.2 steps/s were measured on. None
    where the reference folder is absent."""
    return sofa_scene(meshes, "trunk_cables_cube.scn")
