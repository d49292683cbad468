"""Hexahedral bodies of SOFA scenes: HexahedronFEMForceField on a SparseGridTopology or a
RegularGridTopology, loaded through the SOFA loader and checked against the same model built
with Pliant's API."""

from __future__ import annotations

import textwrap
from pathlib import Path

import meshio
import numpy as np
import pytest
import trimesh

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.fem.body import nodes_in_box
from pliant.fem.hexbody import HexBody
from pliant.fem.material import Corotational
from pliant.mesh.hexmesh import regular_grid, sparse_grid
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler
from pliant.viz.video import VtuSeriesWriter

SCENES = Path(__file__).parent / "sofa_scenes"


@pytest.fixture(scope="module")
def bar(tmp_path_factory) -> tuple[Path, trimesh.Trimesh]:
    """The closed surface of a 60 x 10 x 10 bar, as an STL file."""
    folder = tmp_path_factory.mktemp("bar")
    surface = trimesh.creation.box(extents=(60.0, 10.0, 10.0))
    surface.apply_translation((30.0, 5.0, 5.0))
    surface.export(folder / "bar.stl")
    return folder, surface


def test_a_sparse_grid_cable_scene_steps_as_the_api_model(bar) -> None:
    """hex_cable_bar.py (SparseGridTopology, HexahedronFEMForceField, FixedConstraint, a cable
    pulled by a controller) and the same model built with HexBody, sparse_grid and a
    CableActuator on trilinearly embedded points end at the same positions to round-off."""
    folder, surface = bar
    scene = load_scene(SCENES / "hex_cable_bar.py", mesh_dirs=[folder])
    body = scene.model.body
    assert isinstance(body, HexBody) and body.n_elements == 24
    solver = scene.solver()
    by_scene, state = [], scene.model.rest_state()
    for _ in range(4):
        state = solver.step(state)
        by_scene.append(state.positions)

    mesh, weights = sparse_grid(surface.vertices, surface.faces, (7, 3, 3))
    api = HexBody(
        mesh,
        Corotational(500.0, 0.3, "large", inversion="tolerate"),
        mass="uniform",
        total_mass=0.05,
        fixed_nodes=nodes_in_box(mesh.points, [[-1.0, -1.0, -1.0], [1.0, 11.0, 11.0]]),
        stiffness_weights=weights,
        gravity=(0.0, -9810.0, 0.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
    )
    points = np.array([[x, 8.0, 5.0] for x in (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)])
    cable = CableActuator(
        EmbeddedPoints(mesh, points, tolerance=api.extent, outside="keep"),
        mesh.points,
        pull_point=np.array([0.0, 8.0, 5.0]),
        change_reference=scene.model.actuators[0].change_reference,
    )
    model = Model(api, actuators=[cable])
    api_solver, state = ImplicitEuler(model, 0.01, tangent="fresh"), model.rest_state()
    motion = 0.0
    for k, positions in enumerate(by_scene):
        cable.value = 0.5 * (k + 1)
        state = api_solver.step(state)
        motion = np.abs(state.positions - mesh.points).max()
        np.testing.assert_allclose(positions, state.positions, rtol=0, atol=1e-9 * motion)
    assert motion > 1.0  # the cable bends the bar
    assert np.all(weights == 0.5)  # every cell of a one-cell-thick bar is crossed


def _grid_scene(tmp_path: Path, fem: str, grid: str) -> Path:
    script = tmp_path / "grid.py"
    script.write_text(
        textwrap.dedent(
            f"""
            def createScene(rootNode):
                body = rootNode.addChild('M1')
                body.addObject('StaticSolver')
                body.addObject('MechanicalObject')
                body.addObject('UniformMass', vertexMass=1)
                body.addObject({grid})
                body.addObject('FixedProjectiveConstraint', indices=list(range(16)))
                body.addObject({fem})
            """
        )
    )
    return script


GRID = "'RegularGridTopology', nx=4, ny=4, nz=6, xmin=-9, xmax=-6, ymin=0, ymax=3, zmin=0, zmax=5"


def test_a_regular_grid_numbers_its_nodes_as_sofa(tmp_path) -> None:
    """SOFA's HexahedronFEMForceField example: nx ny nz and xmin ... zmax; nodes numbered x
    fastest, so indices 0 to 15 are the bottom layer, held; the body matches regular_grid."""
    fem = "'HexahedronFEMForceField', youngModulus=4000, poissonRatio=0.3, method='polar'"
    scene = load_scene(_grid_scene(tmp_path, fem, GRID))
    body = scene.model.body
    mesh = regular_grid((4, 4, 6), (-9.0, 0.0, 0.0), (-6.0, 3.0, 5.0))
    np.testing.assert_array_equal(body.rest_positions, mesh.points)
    np.testing.assert_array_equal(body.fixed_nodes, np.arange(16))
    assert body.material.rotation == "polar"
    assert body.node_masses.sum() == pytest.approx(96.0)


@pytest.mark.parametrize(
    ("fem", "grid", "message"),
    [
        ("'HexahedronFEMForceField', method='small'", GRID, "method 'small' is not supported"),
        ("'HexahedronFEMForceField'", "'MeshTopology'", "needs a RegularGridTopology"),
        ("'HexahedronFEMForceField'", "'SparseGridTopology', n=[3, 3, 3]", "no surface"),
    ],
    ids=["small", "no-grid", "no-surface"],
)
def test_what_a_hexahedral_scene_lacks_is_a_scene_error(tmp_path, fem, grid, message) -> None:
    with pytest.raises(SceneError, match=message):
        load_scene(_grid_scene(tmp_path, fem, grid))


def test_tetrahedra_on_a_grid_are_cut_as_sofa_cuts_them(tmp_path) -> None:
    """A TetrahedronFEMForceField on a RegularGridTopology (SoftRobots' PositionConstraint
    example): six tetrahedra per cell, filling the box, the cuts of neighbouring cells
    meeting on their shared faces (the boundary is the grid's, two triangles per quad)."""
    fem = "'TetrahedronFEMForceField', youngModulus=4000, poissonRatio=0.3"
    body = load_scene(_grid_scene(tmp_path, fem, GRID)).model.body
    grid = regular_grid((4, 4, 6), (-9.0, 0.0, 0.0), (-6.0, 3.0, 5.0))
    assert body.n_elements == 6 * grid.n_hexes
    assert body.volumes.sum() == pytest.approx(3.0 * 3.0 * 5.0, rel=1e-12)
    assert len(body.boundary_triangles) == 2 * len(grid.boundary_quads())


def test_a_hexahedral_body_is_written_for_paraview(tmp_path) -> None:
    """`pliant run` writes a body's cells as VTU frames: hexahedra as VTK hexahedra."""
    body = HexBody(regular_grid((3, 2, 2), (0, 0, 0), (2, 1, 1)), Corotational(1.0, 0.3), density=1)
    kind, cells, rows = body.vtk_cells()
    with VtuSeriesWriter(tmp_path, "bar", cells, kind) as series:
        frame = series.write(0.0, body.rest_positions[rows])
    np.testing.assert_array_equal(meshio.read(frame).cells_dict["hexahedron"], body.hexes)


def test_a_hexahedral_block_falls_onto_the_floor(tmp_path) -> None:
    """The grid's own nodes collide (a PointCollisionModel on the body's node): the block
    falls under gravity and rests on the floor at the contact distance."""
    corners = [[-50.0, -50.0, -0.5], [50.0, -50.0, -0.5], [50.0, 50.0, -0.5], [-50.0, 50.0, -0.5]]
    trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]]).export(tmp_path / "floor.stl")
    script = tmp_path / "contact.py"
    script.write_text(
        textwrap.dedent(
            """
            def createScene(root):
                root.gravity = [0.0, 0.0, -9810.0]
                root.dt = 0.01
                root.addObject("FreeMotionAnimationLoop")
                root.addObject("GenericConstraintSolver")
                root.addObject("CollisionPipeline")
                root.addObject("LocalMinDistance", alarmDistance=1.0, contactDistance=0.2)
                root.addObject("CollisionResponse", responseParams="mu=0.3")
                body = root.addChild("Block")
                body.addObject("EulerImplicitSolver")
                body.addObject("RegularGridTopology", n=[3, 3, 2], min=[-5, -5, 0], max=[5, 5, 5])
                body.addObject("MechanicalObject", name="dofs")
                body.addObject("UniformMass", totalMass=0.01)
                body.addObject("HexahedronFEMForceField", youngModulus=100, poissonRatio=0.3)
                body.addObject("PointCollisionModel")
                floor = root.addChild("Floor")
                floor.addObject("MeshSTLLoader", name="loader", filename="floor.stl")
                floor.addObject("MechanicalObject", src="@loader")
                floor.addObject("TriangleCollisionModel", moving=0, simulated=0)
            """
        )
    )
    scene = load_scene(script)
    assert scene.model.contacts is not None
    state = scene.simulate(15)
    assert state.positions[:, 2].min() == pytest.approx(-0.3, abs=1e-3)
