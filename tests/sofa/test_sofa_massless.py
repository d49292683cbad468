"""A SOFA body with no mass component (SofaGym's BubbleMotion board): a massless Pliant body,
which gravity does not pull; under an EulerImplicitSolver each step moves it by
h / (h + rayleighStiffness) K_s^-1 f, as SOFA's solve with M = 0 does."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.mesh import box_beam
from pliant.sofa import SceneError, load_scene

SCENE = """<Node name="root" dt="0.01" gravity="0 0 -9810">
<Node name="Body">
  {solver}
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader"/>
  <MechanicalObject name="dofs"/>
  <TetrahedronFEMForceField youngModulus="200" poissonRatio="0.3" method="large"/>
  {clamp}
  <BoxROI name="tip" box="59.9 -1 -1 61 11 11"/>
  <ConstantForceField indices="@tip.indices" force="0 0 -20"/>
</Node></Node>"""
CLAMP = '<BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/><FixedConstraint indices="@clamp.indices"/>'


def _scene(tmp_path, solver: str, clamp: str = CLAMP):
    import meshio

    mesh = box_beam(60.0, 10.0, 10.0, 6, 1, 1)
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    path = tmp_path / "massless.scn"
    path.write_text(SCENE.format(solver=solver, clamp=clamp))
    return load_scene(path)


def test_a_body_without_mass_takes_damped_newton_steps(tmp_path):
    loaded = _scene(tmp_path, '<EulerImplicitSolver rayleighStiffness="0.02"/>')
    body = loaded.model.body
    assert body.massless and not np.any(body.gravity_forces())
    rest = loaded.model.rest_state()
    moved = body.gather(loaded.simulate(1).positions - rest.positions)
    lin = body.linearise(rest.positions)
    dx = (
        loaded.dt
        / (loaded.dt + 0.02)
        * np.linalg.solve(body.stiffness_matrix(lin).toarray(), body.gather(lin.forces))
    )
    assert np.abs(dx).max() > 1.0
    np.testing.assert_allclose(moved, dx, rtol=1e-8, atol=1e-10 * np.abs(dx).max())


def test_a_static_body_without_mass_bears_no_weight(tmp_path):
    loaded = _scene(tmp_path, "<StaticSolver/>")
    assert loaded.model.body.massless
    z = loaded.simulate(1).positions[:, 2] - loaded.model.body.rest_positions[:, 2]
    # The tip load alone: gravity (-9810) on a mass would bend it far more.
    assert -20.0 < z.min() < -1.0


def test_a_free_body_without_mass_is_refused(tmp_path):
    # Its implicit step (the stiffness alone) is singular: the loader names the body.
    with pytest.raises(SceneError, match="root/Body: the body has no mass .* nothing holds it"):
        _scene(tmp_path, "<EulerImplicitSolver/>", clamp="")
