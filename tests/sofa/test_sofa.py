"""SOFA parity: the scene loader, SOFA's outside-point embedding, SoftRobots' rate limit.

The reference: SOFA + SoftRobots ran the scenes of ../shared/sofa-reference/ and exported the
node positions after 1 s (100 steps of 0.01 s), printed to about 6 significant digits
(5e-4 mm). Pliant, given the same scene through :mod:`pliant.sofa`, must end at every node
within 1e-3 mm of them.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.fem.body import TetBody
from pliant.fem.loads import SurfacePressure
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import ImplicitEuler, StaticSolver

REFERENCE = Path("../shared/sofa-reference")
MESHES = Path("../shared/meshes")
needs_reference = pytest.mark.skipif(
    not (REFERENCE / "diamond_plain_0.vtk").is_file() or not MESHES.is_dir(),
    reason="SOFA's reference outputs are not beside the repository (../shared)",
)


DOCS = [Path(__file__).parents[2] / "docs" / name for name in ("sofa.md", "sofa-reference.md")]


@needs_reference
@pytest.mark.parametrize(
    "code",
    [c for page in DOCS for c in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)],
    ids=["port", "choice", "stlib", "sofagym", "rigid-only", "sofagym-env", "supports"],
)
def test_docs_examples_run(code: str) -> None:
    exec(compile(code, "docs/sofa*.md", "exec"), {})


def sofa_positions(path: Path) -> np.ndarray:
    """The POINTS of a legacy ASCII VTK file written by SOFA's VTKExporter."""
    words = path.read_text().split()
    at = words.index("POINTS")
    n = int(words[at + 1])
    return np.array(words[at + 3 : at + 3 + 3 * n], dtype=float).reshape(n, 3)


# ---------------------------------------------------------------------------------------------
# Same scene, same numbers


@needs_reference
@pytest.mark.parametrize("scene", ["diamond_plain", "trunk_cables"])
def test_scenes_end_where_sofa_does(scene: str) -> None:
    """Every node within 1e-3 mm of SOFA's exported position after 100 steps (measured:
    5.0e-4 mm on both, the file's print precision)."""
    loaded = load_scene(REFERENCE / f"{scene}.scn", mesh_dirs=[MESHES])
    state = loaded.simulate(100)
    reference = sofa_positions(REFERENCE / f"{scene}_0.vtk")
    error = np.linalg.norm(state.positions - reference, axis=1)
    assert error.max() <= 1e-3, f"max node error {error.max():.2e} mm"


@needs_reference
@pytest.mark.parametrize(
    ("choice", "low", "high"),
    # Measured on the Trunk with cables (max node error, mm; the tip moves 39 mm): the polar
    # rotation 14.2, points projected onto the mesh 0.88, the change measured from the last
    # step 0.10. Each choice alone moves the result well beyond SOFA's print precision.
    [
        ({"rotation": "polar"}, 5.0, 30.0),
        ({"outside": "project"}, 0.3, 3.0),
        ({"change_reference": "last"}, 0.03, 0.3),
    ],
)
def test_each_sofa_choice_matters_on_the_trunk(choice, low, high) -> None:
    loaded = load_scene(REFERENCE / "trunk_cables.scn", mesh_dirs=[MESHES], **choice)
    error = np.linalg.norm(
        loaded.simulate(100).positions - sofa_positions(REFERENCE / "trunk_cables_0.vtk"), axis=1
    )
    assert low < error.max() < high, f"{choice}: max node error {error.max():.3g} mm"


@needs_reference
@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({}, "tolerate"),  # SOFA's: no inversion check in its "large" force field
        ({"inversion": "refuse"}, "refuse"),
        ({"sofa_compatible": False}, "refuse"),
        ({"rotation": "polar"}, "refuse"),  # a polar frame cannot tolerate inversion
    ],
)
def test_inverted_elements_follow_the_choice(options, expected) -> None:
    loaded = load_scene(REFERENCE / "diamond_plain.scn", mesh_dirs=[MESHES], **options)
    assert loaded.model.body.material.inversion == expected


@needs_reference
def test_the_polar_rotation_misses_the_plain_diamond() -> None:
    """The rotation alone makes the plain Diamond's gap: 1.29 mm with the polar one (measured),
    5e-4 mm with SOFA's."""
    loaded = load_scene(REFERENCE / "diamond_plain.scn", mesh_dirs=[MESHES], rotation="polar")
    error = np.linalg.norm(
        loaded.simulate(100).positions - sofa_positions(REFERENCE / "diamond_plain_0.vtk"), axis=1
    )
    assert 0.5 < error.max() < 3.0, f"max node error {error.max():.3g} mm"


@needs_reference
def test_a_python_scene_script_loads_like_its_xml_twin(tmp_path) -> None:
    mesh = (MESHES / "Diamond_siliconeV0.vtu").resolve()
    script = tmp_path / "diamond.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import Sofa.Core


            def createScene(rootNode):
                rootNode.dt = 0.01
                rootNode.gravity = [0, 0, -9810]
                rootNode.addObject("RequiredPlugin", pluginName="SoftRobots")
                body = rootNode.addChild("Body")
                body.addObject("EulerImplicitSolver", rayleighStiffness=0, rayleighMass=0)
                body.addObject("SparseLDLSolver")
                body.addObject(
                    "MeshVTKLoader", name="loader", filename="{mesh}",
                    rotation=[90, 0, 0], translation=[0, 0, 35],
                )
                body.addObject("MeshTopology", src="@loader")
                body.addObject("MechanicalObject", name="dofs")
                body.addObject("UniformMass", totalMass=0.5)
                body.addObject(
                    "TetrahedronFEMForceField", youngModulus=180, poissonRatio=0.45
                )
                body.addObject("BoxROI", name="boxROI", box=[-15, -15, -40, 15, 15, 10])
                body.addObject("FixedProjectiveConstraint", indices="@boxROI.indices")
                return rootNode
            """
        )
    )
    from_script = load_scene(script).simulate(5)
    from_xml = load_scene(REFERENCE / "diamond_plain.scn", mesh_dirs=[MESHES]).simulate(5)
    assert np.array_equal(from_script.positions, from_xml.positions)


@needs_reference
def test_the_trunk_pushes_the_cube_of_the_collision_scene() -> None:
    """trunk_cables_cube.scn: its collision pipeline becomes Contacts (the floor a plane, the
    STL's vertices the contact points, alarm distance the margin, mu the friction) and its
    Rigid3 cube a RigidBody (10 g, inertia m a^2/6); the Trunk, pulled by cable L1, pushes
    the cube along the floor (-x), and the cube stays on it."""
    scene = load_scene(REFERENCE / "trunk_cables_cube.scn", mesh_dirs=[MESHES])
    model = scene.model
    contacts, (cube,) = model.contacts, model.rigid_bodies
    assert [type(s).__name__ for s in contacts.shapes] == ["Plane"]
    assert contacts.margin == 3.0 and contacts.shapes[0].position[1] == -15.0
    assert cube.mass == 0.01
    np.testing.assert_allclose(cube.inertia, 0.01 * 400 / 6 * np.eye(3), rtol=1e-6)
    import meshio

    stl = meshio.read(MESHES / "Trunk_trunk.stl").points
    assert len(contacts.points) == len(np.unique(stl, axis=0))
    solver = scene.solver(tangent="lagged")
    state = model.rest_state()
    for _ in range(100):
        state = solver.step(state)
    x, y, _ = state.rigid_positions[0]
    assert x < -21.0  # pushed from -20 towards -x
    assert abs(y - (-15.0 + 10.0)) < 0.5  # resting on the floor


def test_unsupported_components_are_listed_in_one_error(tmp_path) -> None:
    scene = tmp_path / "scene.scn"
    scene.write_text(
        """<Node name="root"><Node name="Body">
        <MeshVTKLoader name="loader" filename="x.vtk"/>
        <TetrahedronFEMForceField/>
        <BeamFEMForceField/>
        <Node name="cavity"><SurfacePressureForceField/></Node>
        </Node></Node>"""
    )
    with pytest.raises(SceneError) as err:
        load_scene(scene)
    message = str(err.value)
    assert "BeamFEMForceField (at root/Body)" in message
    assert "SurfacePressureForceField (at root/Body/cavity)" in message


def test_a_cavity_scene_inflates_like_the_pressure_load(tmp_path) -> None:
    """A SurfacePressureConstraint on a surface mesh of its own (STL, mapped into the body)
    in pressure mode: the closed surface's pressure force, p dV/dx, is the SurfacePressure
    load's on the same faces, so the static equilibria agree."""
    import meshio

    mesh = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    surface = mesh.boundary_triangles()
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    meshio.write(tmp_path / "cavity.stl", meshio.Mesh(mesh.points, [("triangle", surface)]))
    scene = tmp_path / "cavity.scn"
    scene.write_text(
        """<Node name="root" dt="0.01" gravity="0 0 0">
        <Node name="Body">
          <StaticSolver/>
          <MeshVTKLoader name="loader" filename="body.vtu"/>
          <MeshTopology name="topo" src="@loader"/>
          <MechanicalObject name="dofs"/>
          <UniformMass totalMass="0.001"/>
          <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="polar"/>
          <BoxROI name="box" box="-1 -1 -1 0.1 11 11"/>
          <FixedConstraint indices="@box.indices"/>
          <Node name="cavity">
            <MeshSTLLoader name="surface" filename="cavity.stl"/>
            <MeshTopology name="walls" src="@surface"/>
            <MechanicalObject name="points" src="@surface"/>
            <SurfacePressureConstraint triangles="@walls.triangles" value="20"
                valueType="pressure"/>
            <BarycentricMapping/>
          </Node>
        </Node></Node>"""
    )
    loaded = load_scene(scene)
    assert loaded.solver_kind == "static" and len(loaded.model.actuators) == 1
    by_scene = loaded.simulate(1).positions
    body = TetBody(
        mesh,
        Corotational(1000.0, 0.3),
        density=1e-6,
        fixed_nodes=np.flatnonzero(mesh.points[:, 0] < 0.1),
        loads=[SurfacePressure(surface, 20.0)],
    )
    by_load = StaticSolver(Model(body)).step(Model(body).rest_state()).positions
    motion = np.abs(by_load - mesh.points).max()
    assert motion > 0.1
    assert np.abs(by_scene - by_load).max() < 1e-8 * motion


@needs_reference
def test_a_cable_not_carried_by_the_body_is_refused(tmp_path) -> None:
    text = (REFERENCE / "diamond_plain.scn").read_text()
    text = text.replace(
        "<DefaultAnimationLoop/>",
        '<DefaultAnimationLoop/><Node name="loose"><MechanicalObject position="0 0 0 1 1 1"/>'
        '<CableConstraint name="c"/></Node>',
    )
    scene = tmp_path / "scene.scn"
    scene.write_text(text)
    with pytest.raises(SceneError, match=r"CableConstraint \(at root/loose\)"):
        load_scene(scene, mesh_dirs=[MESHES])


def test_a_scene_without_a_body_says_so(tmp_path) -> None:
    scene = tmp_path / "scene.scn"
    scene.write_text('<Node name="root"><Node name="Body"><UniformMass/></Node></Node>')
    with pytest.raises(SceneError, match="no deformable body"):
        load_scene(scene)


@needs_reference
def test_pliant_run_takes_a_scene_file(tmp_path) -> None:
    from typer.testing import CliRunner

    from pliant.cli import app

    result = CliRunner().invoke(
        app,
        [
            "run",
            str(REFERENCE / "diamond_plain.scn"),
            "--mesh-dir",
            str(MESHES),
            "--duration",
            "0.02",
            "--frames",
            "1",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "diamond_plain" / "diamond_plain.pvd").is_file()


# ---------------------------------------------------------------------------------------------
# Points outside the mesh (SOFA's BarycentricMapping)


def test_outside_points_are_kept_where_they_are_and_follow_affine_motions(rng) -> None:
    """An outside point keeps its place at rest, gets barycentric coordinates (some negative,
    summing to 1) in the element whose centre is nearest, and, since the element's
    interpolation is affine, follows any affine motion of the mesh exactly."""
    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    points = np.array([[15.0, 5.0, 10.6], [31.0, 2.0, 3.0], [12.0, 5.0, 5.0]])
    kept = EmbeddedPoints(mesh, points, outside="keep", tolerance=2.0)
    projected = EmbeddedPoints(mesh, points, tolerance=2.0)
    assert np.abs(kept.positions(mesh.points) - points).max() < 1e-12
    assert np.abs(kept.weights.sum(axis=1) - 1.0).max() < 1e-12
    assert kept.weights[:2].min(axis=1).max() < 0.0
    centres = mesh.points[mesh.tets].mean(axis=1)
    for j in range(2):
        nearest = np.argmin(np.linalg.norm(centres - points[j], axis=1))
        assert set(kept.nodes[j]) == set(mesh.tets[nearest])
    # Projection moves the outside points onto the mesh; the inside point is the same.
    moved = np.linalg.norm(projected.positions(mesh.points) - points, axis=1)
    assert moved[0] > 0.5 and moved[1] > 0.9 and moved[2] < 1e-12
    a = np.eye(3) + 0.2 * rng.uniform(-1.0, 1.0, (3, 3))
    c = rng.uniform(-5.0, 5.0, 3)
    assert np.abs(kept.positions(mesh.points @ a.T + c) - (points @ a.T + c)).max() < 1e-12


# ---------------------------------------------------------------------------------------------
# SoftRobots' rate limit


@pytest.mark.parametrize(
    ("reference", "expected"),
    # SoftRobots measures the change from the displacement it stored while solving the
    # previous step, before that step's correction: delta_n <= delta_{n-2} + 1, so a ramp met
    # exactly climbs 1 mm every other step.
    [("last", [1.0, 2.0, 3.0, 4.0, 4.0]), ("lagged", [1.0, 1.0, 2.0, 2.0, 3.0])],
)
def test_the_cable_ramp_follows_the_change_reference(reference, expected) -> None:
    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    body = TetBody(
        mesh,
        Corotational(1000.0, 0.45),
        density=1e-6,
        fixed_nodes=np.flatnonzero(mesh.points[:, 0] < 1e-9),
    )
    path = np.array([[0.0, 5.0, 8.0], [30.0, 5.0, 8.0], [60.0, 5.0, 8.0]])
    cable = CableActuator(
        EmbeddedPoints(mesh, path),
        body.rest_positions,
        value=4.0,
        max_displacement_change=1.0,
        change_reference=reference,
    )
    model = Model(body, actuators=[cable])
    for solver in (StaticSolver(model), ImplicitEuler(model, 0.01, tangent="fresh")):
        state, reached = model.rest_state(), []
        for _ in range(5):
            state = solver.step(state)
            reached.append(float(state.displacement[0]))
        # Static: met exactly; dynamic: met to first order (the length is linearised in
        # the step), a small fraction of the 1 mm steps.
        tol = 1e-6 if isinstance(solver, StaticSolver) else 0.05
        assert np.abs(np.array(reached) - expected).max() < tol, (type(solver), reached)


def test_large_frames_keep_the_file_order_of_reoriented_elements(tmp_path, rng) -> None:
    """A mesh file with some elements negatively oriented (nodes 0 and 1 swapped): the loader
    reorients them for Pliant but keeps SOFA's frame, the file's first three nodes, so the
    forces are those of the NumPy reference run on the file's elements as they are."""
    import meshio

    from pliant.fem import reference

    mesh = box_beam(20.0, 10.0, 10.0, 2, 1, 1)
    tets = mesh.tets.copy()
    tets[::3] = tets[::3][:, [1, 0, 2, 3]]
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", tets)]))
    scene = tmp_path / "body.scn"
    scene.write_text(
        """<Node name="root" gravity="0 0 0"><Node name="Body">
        <EulerImplicitSolver/><MeshVTKLoader name="loader" filename="body.vtu"/>
        <UniformMass totalMass="0.001"/><TetrahedronFEMForceField youngModulus="1000"
        poissonRatio="0.3"/></Node></Node>"""
    )
    body = load_scene(scene).model.body
    moved = mesh.points + 0.8 * rng.standard_normal(mesh.points.shape)
    material = body.material
    forces, _ = reference.internal_forces(
        moved, tets, mesh.points, material.mu, material.lam, "corotational", rotation="large"
    )
    assert np.abs(body.linearise(moved).forces - forces).max() < 1e-10 * np.abs(forces).max()


# ---------------------------------------------------------------------------------------------
# The hyperelastic force field


HYPERELASTIC_SCENE = """<Node name="root" dt="0.01" gravity="0 0 0">
<Node name="Body">
  <StaticSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="0.001"/>
  <TetrahedronHyperelasticityFEMForceField {material}/>
  <BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/>
  <FixedConstraint indices="@clamp.indices"/>
  <BoxROI name="tip" box="39.9 -1 -1 41 11 11"/>
  <ConstantForceField indices="@tip.indices" force="0 0 -1500"/>
</Node></Node>"""


@pytest.mark.parametrize("law", ["NeoHookean", "StVenantKirchhoff"])
def test_a_hyperelastic_scene_bends_like_the_same_pliant_model(tmp_path, law) -> None:
    """SOFA's NeoHookean (ParameterSet = mu lambda, Bonet and Wood's law) and
    StVenantKirchhoff (ParameterSet = mu lambda) on a cantilever under a tip load: the loaded
    scene's static deflection is Pliant's model's with the same law and Lame parameters
    (mu = 3448.2759, lambda = 31034.483: E = 1e4, nu = 0.45, the values of SOFA's own example
    scene), to the Newton tolerance."""
    import meshio

    from pliant.fem import material as laws
    from pliant.fem.loads import NodalForces

    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    scene = tmp_path / "hyper.scn"
    scene.write_text(
        HYPERELASTIC_SCENE.format(
            material=f'materialName="{law}" ParameterSet="3448.2759 31034.483"'
        )
    )
    loaded = load_scene(scene)
    material = loaded.model.body.material
    assert type(material) is getattr(laws, law)
    assert abs(material.mu - 3448.2759) < 1e-8 and abs(material.lam - 31034.483) < 1e-7
    by_scene = loaded.simulate(1).positions
    x = mesh.points
    tip = np.flatnonzero(x[:, 0] > 39.9)
    body = TetBody(
        mesh,
        getattr(laws, law)(1e4, 0.45),
        total_mass=0.001,
        mass="uniform",
        fixed_nodes=np.flatnonzero(x[:, 0] < 0.1),
        loads=[NodalForces(tip, [0.0, 0.0, -1500.0])],
    )
    by_model = StaticSolver(Model(body)).step(Model(body).rest_state()).positions
    deflection = -(by_model - x)[tip, 2].mean()
    assert deflection > 1.0
    assert np.abs(by_scene - by_model).max() < 1e-6 * deflection


@pytest.mark.parametrize(
    ("material", "message"),
    [
        ('materialName="Ogden" ParameterSet="1 2 3"', "'Ogden' has no Pliant law"),
        ('ParameterSet="1 2"', "SOFA's default is ArrudaBoyce"),
        ('materialName="NeoHookean" ParameterSet="1"', "takes 2 values \\(mu lambda\\)"),
    ],
)
def test_unsupported_hyperelastic_materials_are_named(tmp_path, material, message) -> None:
    import meshio

    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    scene = tmp_path / "hyper.scn"
    scene.write_text(HYPERELASTIC_SCENE.format(material=material))
    with pytest.raises(SceneError, match=message):
        load_scene(scene)


# ---------------------------------------------------------------------------------------------
# Nodes on a plane or a line (ProjectToPlaneConstraint, ProjectToLineConstraint)


PROJECTED_SCENE = """<Node name="root" dt="0.01" gravity="0 0 0">
<Node name="Body">
  <StaticSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="0.001"/>
  <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="polar"/>
  <BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/>
  <FixedConstraint indices="@clamp.indices"/>
  <{kind} indices="{indices}" {axis} origin="{origin}"/>
  <ConstantForceField indices="{indices}" force="5 10 -30"/>
</Node></Node>"""


@pytest.mark.parametrize(
    ("kind", "axis", "origin", "projection"),
    [
        # The plane y + z = 10 holds the edges (x, 0, 10) and (x, 10, 0) of the last two
        # cross-sections; the line along (1, 1, -1) through the tip corner (30, 10, 10).
        ("ProjectToPlaneConstraint", (0.0, 1.0, 1.0), (0.0, 0.0, 10.0), "plane"),
        ("ProjectToLineProjectiveConstraint", (1.0, 1.0, -1.0), (30.0, 10.0, 10.0), "line"),
    ],
)
def test_scenes_hold_nodes_on_planes_and_lines(tmp_path, kind, axis, origin, projection) -> None:
    """The loader maps SOFA's projections onto a plane (origin, normal) and a line (origin,
    direction): the held nodes stay on them under a load that pulls them off, and the scene
    ends where the model built with OnPlane / OnLine does."""
    import meshio

    from pliant.fem.loads import NodalForces
    from pliant.fem.supports import OnLine, OnPlane

    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    x = mesh.points
    if projection == "plane":
        held_nodes = np.flatnonzero((np.abs((x - origin) @ axis) < 1e-9) & (x[:, 0] > 15.0))
    else:
        held_nodes = np.flatnonzero(np.linalg.norm(x - origin, axis=1) < 1e-9)
    key = "normal" if projection == "plane" else "direction"
    scene = tmp_path / "projected.scn"
    scene.write_text(
        PROJECTED_SCENE.format(
            kind=kind,
            indices=" ".join(map(str, held_nodes)),
            axis=f'{key}="{" ".join(map(str, axis))}"',
            origin=" ".join(map(str, origin)),
        )
    )
    loaded = load_scene(scene)
    (held,) = loaded.model.body.projections
    assert held.kind == projection and list(held.nodes) == sorted(held_nodes)
    by_scene = loaded.simulate(1).positions
    made = (OnPlane if projection == "plane" else OnLine)(held_nodes, axis)
    body = TetBody(
        mesh,
        Corotational(1000.0, 0.3),
        total_mass=0.001,
        mass="uniform",
        fixed_nodes=np.flatnonzero(x[:, 0] < 0.1),
        projections=[made],
        loads=[NodalForces(held_nodes, [5.0, 10.0, -30.0])],
    )
    by_model = StaticSolver(Model(body)).step(Model(body).rest_state()).positions
    u = (by_scene - x)[held_nodes]
    assert np.abs(u).max() > 0.01
    assert np.abs(np.einsum("kmi,ki->km", made.held_directions(), u)).max() < 1e-12
    assert np.abs(by_scene - by_model).max() < 1e-10


def test_a_node_off_its_plane_is_named(tmp_path) -> None:
    import meshio

    mesh = box_beam(30.0, 10.0, 10.0, 3, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    scene = tmp_path / "projected.scn"
    scene.write_text(
        PROJECTED_SCENE.format(
            kind="ProjectToPlaneConstraint", indices="15", axis='normal="1 0 0"', origin="29 0 0"
        )
    )
    with pytest.raises(SceneError, match="lies 1 off the plane"):
        load_scene(scene)


# ---------------------------------------------------------------------------------------------
# pliant inverse on a scene


INVERSE_SCENE = """<Node name="root" dt="0.01" gravity="0 0 0">
  <RequiredPlugin pluginName="SoftRobots SoftRobots.Inverse"/>
  <FreeMotionAnimationLoop/>
  <QPInverseProblemSolver/>
  <Node name="goal">
    <MechanicalObject name="goalMO" position="{goal}"/>
  </Node>
  <Node name="beam">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>
    <MeshVTKLoader name="loader" filename="beam.vtu"/>
    <MeshTopology src="@loader"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="0.01"/>
    <TetrahedronFEMForceField youngModulus="500" poissonRatio="0.3"/>
    <BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/>
    <FixedConstraint indices="@clamp.indices"/>
    <Node name="cableA">
      <MechanicalObject position="0 2 2  30 2 2  60 2 2"/>
      <CableActuator pullPoint="-5 2 2" minForce="0" maxPositiveDisp="5"/>
      <BarycentricMapping/>
    </Node>
    <Node name="cableB">
      <MechanicalObject position="0 8 2  30 8 2  60 8 2"/>
      <CableActuator pullPoint="-5 8 2" minForce="0" maxPositiveDisp="5"/>
      <BarycentricMapping/>
    </Node>
    <Node name="cableC">
      <MechanicalObject position="0 8 8  30 8 8  60 8 8"/>
      <CableActuator pullPoint="-5 8 8" minForce="0" maxPositiveDisp="5"/>
      <BarycentricMapping/>
    </Node>
    <Node name="cableD">
      <MechanicalObject position="0 2 8  30 2 8  60 2 8"/>
      <CableActuator pullPoint="-5 2 8" minForce="0" maxPositiveDisp="5"/>
      <BarycentricMapping/>
    </Node>
    <Node name="effector">
      <MechanicalObject position="60 5 5"/>
      <PositionEffector indices="0" effectorGoal="@../../goal/goalMO.position"/>
      <BarycentricMapping/>
    </Node>
  </Node>
</Node>"""


def test_pliant_inverse_reaches_a_scene_goal(tmp_path) -> None:
    """A SoftRobots inverse scene (QPInverseProblemSolver, four CableActuators that only pull,
    a PositionEffector whose effectorGoal links to a goal node elsewhere in the tree) run by
    `pliant inverse`: the goal is one the cables reach (the tip where pulling cables B and C by
    1 and 1.5 mm puts it), approached in three goals on the line from the tip; each is reached
    within 0.05 mm (measured: 0.001, 0.001, 0.010 mm)."""
    import json

    import meshio
    from typer.testing import CliRunner

    from pliant.cli import app

    mesh = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(tmp_path / "beam.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    scene = tmp_path / "cables.scn"
    scene.write_text(INVERSE_SCENE.format(goal="58.95 8.07 6.95"))
    loaded = load_scene(scene)
    np.testing.assert_allclose(loaded.model.effectors[0].goals, [[58.95, 8.07, 6.95]])
    out = tmp_path / "out"
    args = ["inverse", str(scene), "--goals", "3", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = json.loads((out / "cables" / "cables_goal.json").read_text())
    assert len(report["errors"]) == 3 and not any(report["out_of_reach"])
    assert report["max_error"] < 0.05


def test_pliant_inverse_needs_a_scene_effector_with_a_goal(tmp_path) -> None:
    import meshio
    from typer.testing import CliRunner

    from pliant.cli import app

    mesh = box_beam(60.0, 10.0, 10.0, 6, 2, 2)
    meshio.write(tmp_path / "beam.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    scene = tmp_path / "cables.scn"
    scene.write_text(INVERSE_SCENE.format(goal="60 5 5"))  # the effector's rest position
    result = CliRunner().invoke(app, ["inverse", str(scene), "--out", str(tmp_path)])
    assert result.exit_code != 0
    assert "has no goal away from its rest position" in result.output
