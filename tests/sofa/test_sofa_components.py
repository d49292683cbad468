"""SOFA components with SOFA's semantics, checked against closed forms and against the same
model built with Pliant's API: the St Venant-Kirchhoff law of
TetrahedronHyperelasticityFEMForceField, and SoftRobots' PositionConstraint."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.point import PointActuator
from pliant.errors import ConstraintError
from pliant.fem.body import TetBody, fixed_components
from pliant.fem.loads import NodalForces, SurfaceTraction
from pliant.fem.material import StVenantKirchhoff
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.sofa import SceneError, load_scene
from pliant.solvers import StaticSolver

# ---------------------------------------------------------------------------------------------
# St Venant-Kirchhoff


def test_st_venant_kirchhoff_stretches_a_bar_as_its_closed_form() -> None:
    """A dead traction t on the end of a bar free to contract: the state is homogeneous and
    S = lam tr(E) I + 2 mu E is uniaxial, S11 = Y E11 with Young's modulus Y (linear in the
    Green strain), so P11 = s (s^2 - 1) Y / 2 = t for the stretch s, and the lateral stretch
    is sqrt(1 - 2 nu E11). A 30 % stretch, far from the linear range."""
    young, nu, stretch = 1000.0, 0.3, 1.3
    traction = stretch * (stretch**2 - 1.0) * young / 2.0
    mesh = box_beam(20.0, 5.0, 5.0, 4, 2, 2)
    x = mesh.points
    tri = mesh.boundary_triangles()
    end = tri[np.all(np.abs(x[tri][:, :, 0] - 20.0) < 1e-9, axis=1)]
    supports = np.concatenate(
        [
            fixed_components(np.flatnonzero(x[:, 0] < 1e-9), (True, False, False)),
            fixed_components(np.flatnonzero(x[:, 1] < 1e-9), (False, True, False)),
            fixed_components(np.flatnonzero(x[:, 2] < 1e-9), (False, False, True)),
        ]
    )
    body = TetBody(
        mesh,
        StVenantKirchhoff(young, nu),
        density=1e-6,
        fixed_dofs=supports,
        loads=[SurfaceTraction(end, x, [traction, 0.0, 0.0])],
    )
    model = Model(body)
    state = StaticSolver(model).step(model.rest_state())
    grad = np.einsum("eai,eaj->eij", state.positions[mesh.tets], body.grads)
    green = 0.5 * (stretch**2 - 1.0)
    lateral = np.sqrt(1.0 - 2.0 * nu * green)
    assert np.abs(grad - np.diag([stretch, lateral, lateral])).max() < 1e-8


def test_st_venant_kirchhoff_forces_energy_and_tangent_are_consistent(rng) -> None:
    """On a randomly deformed block: the forces are minus the gradient of the energy, and the
    tangent K u is minus their derivative along u (central differences)."""
    mesh = box_beam(10.0, 5.0, 5.0, 2, 1, 1)
    body = TetBody(mesh, StVenantKirchhoff(1000.0, 0.3), density=1e-6)
    x = mesh.points + 0.6 * rng.standard_normal(mesh.points.shape)
    lin = body.linearise(x)
    u = rng.standard_normal(x.shape)
    h = 1e-6
    plus, minus = body.linearise(x + h * u), body.linearise(x - h * u)
    assert abs((plus.energy - minus.energy) / (2 * h) + np.sum(lin.forces * u)) < 1e-6 * abs(
        np.sum(lin.forces * u)
    )
    numeric = -(plus.forces - minus.forces) / (2 * h)
    for exact in (False, True):
        tangent = body.stiffness_matvec(lin, u.reshape(-1)[body.free_dofs], exact=exact)
        expected = numeric.reshape(-1)[body.free_dofs]
        assert np.abs(tangent - expected).max() < 1e-6 * np.abs(expected).max()


# ---------------------------------------------------------------------------------------------
# PositionConstraint

POSITION_SCENE = """<Node name="root" dt="0.01" gravity="0 -9810 0">
<Node name="Body">
  <StaticSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="0.01"/>
  <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="polar"/>
  <BoxROI name="clamp" box="0.1 11 11 -1 -1 -1"/>
  <FixedConstraint indices="@clamp.indices"/>
  <BoxROI name="tip" box="39.9 -1 -1 41 11 11"/>
  <PositionConstraint indices="@tip.indices" useDirections="0 1 0" {command}/>
</Node></Node>"""


@pytest.fixture
def beam(tmp_path):
    mesh = box_beam(40.0, 10.0, 10.0, 4, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    return mesh, tmp_path


def _position_scene(folder, command: str):
    (folder / "pc.scn").write_text(POSITION_SCENE.format(command=command))
    return load_scene(folder / "pc.scn")


def test_a_position_constraint_moves_its_points_by_the_value(beam) -> None:
    """Displacement mode: each tip node rises by exactly `value` along y (one row per node),
    other components free; the same rows built with Pliant's API give the same state."""
    mesh, folder = beam
    scene = _position_scene(folder, 'value="2.5" valueType="displacement"')
    tip = np.flatnonzero(mesh.points[:, 0] > 39.9)
    assert len(scene.model.actuators) == tip.size
    state = scene.simulate(1)
    assert np.abs((state.positions - mesh.points)[tip, 1] - 2.5).max() < 1e-9
    assert np.abs(state.displacement - 2.5).max() < 1e-9
    rows = [
        PointActuator(EmbeddedPoints.at_nodes([n]), mesh.points, [0, 1, 0], value=2.5, name=f"p{n}")
        for n in tip
    ]
    model = Model(scene.model.body, actuators=rows)
    by_api = StaticSolver(model).step(model.rest_state())
    assert np.abs(by_api.positions - state.positions).max() < 1e-12


def test_a_position_constraint_in_force_mode_is_a_nodal_force(beam) -> None:
    """Force mode: each row pushes its node by `value` along y, as a ConstantForceField does."""
    mesh, folder = beam
    scene = _position_scene(folder, 'value="-40" valueType="force"')
    state = scene.simulate(1)
    tip = np.flatnonzero(mesh.points[:, 0] > 39.9)
    body = scene.model.body
    loaded = TetBody(
        mesh,
        body.material,
        mass="uniform",
        total_mass=0.01,
        fixed_nodes=np.flatnonzero(mesh.points[:, 0] < 0.1),
        gravity=(0.0, -9810.0, 0.0),
        loads=[NodalForces(tip, [0.0, -40.0, 0.0])],
    )
    model = Model(loaded)
    by_force = StaticSolver(model).step(model.rest_state())
    assert (mesh.points - by_force.positions)[tip, 1].min() > 1.0
    assert np.abs(by_force.positions - state.positions).max() < 1e-8
    assert np.allclose(state.actuation, -40.0)


def test_a_position_constraint_controller_reads_its_force(beam) -> None:
    """The force the scene's data hold after a step (as controllers read them) is the first
    row's lambda."""
    mesh, folder = beam
    scene = _position_scene(folder, 'value="1.0"')
    state = scene.simulate(1)
    scene.end_step(state)
    obj = scene.root.getChild("Body").getObject("PositionConstraint")
    assert obj.force.value == pytest.approx(state.actuation[0])
    assert obj.displacement.value == pytest.approx(1.0)


def test_a_point_actuator_refuses_a_null_direction() -> None:
    mesh = box_beam(10.0, 5.0, 5.0, 1, 1, 1)
    with pytest.raises(ConstraintError, match="direction"):
        PointActuator(EmbeddedPoints.at_nodes([0]), mesh.points, [0, 0, 0])


def test_position_constraint_directions_are_checked(beam) -> None:
    _, folder = beam
    with pytest.raises(SceneError, match="three axes"):
        _position_scene(folder, 'value="1" directions="1 0 0 0 1 0"')
