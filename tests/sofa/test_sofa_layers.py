"""A second FEM on part of the body's elements (SoftRobots' stiffer layer: a child node with its
own topology, from a BoxROI's ``tetrahedraInROI``, and no MechanicalObject), checked against
closed forms: the laws are linear in mu and lambda, so the layer adds its Lame parameters to
its elements."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.sofa import SceneError, load_scene

LAYER_SCENE = """<Node name="root" dt="0.01" gravity="0 -9810 0">
<Node name="Finger">
  <EulerImplicitSolver/>
  <SparseLDLSolver/>
  <MeshVTKLoader name="loader" filename="body.vtu"/>
  <MeshTopology src="@loader" name="container"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="0.01"/>
  <TetrahedronFEMForceField youngModulus="500" poissonRatio="0.3" method="large"/>
  <BoxROI name="clamp" box="-1 -1 -1 0.1 11 11"/>
  <FixedConstraint indices="@clamp.indices"/>
  <BoxROI name="layer" box="{box}" {strict}/>
  <Node name="SubTopology">
    <MeshTopology position="@loader.position" tetrahedra="@layer.tetrahedraInROI"/>
    <TetrahedronFEMForceField youngModulus="1500" poissonRatio="{nu}" {method}/>
  </Node>
</Node></Node>"""


@pytest.fixture(scope="module")
def layer_beam(tmp_path_factory):
    folder = tmp_path_factory.mktemp("layer")
    mesh = box_beam(40.0, 10.0, 10.0, 4, 2, 2)
    meshio.write(folder / "body.vtu", meshio.Mesh(mesh.points, [("tetra", mesh.tets)]))
    return folder, mesh


def _load(folder, name, *, box="-1 -1 -1 41 11 11", nu=0.3, strict="", method='method="large"'):
    text = LAYER_SCENE.format(box=box, nu=nu, strict=strict, method=method)
    (folder / f"{name}.scn").write_text(text)
    return load_scene(folder / f"{name}.scn")


def test_a_layer_over_every_element_is_the_summed_modulus(layer_beam) -> None:
    """E = 500 everywhere and a layer of E = 1500 (same nu) on every element: the beam of
    E = 2000, to round-off."""
    folder, mesh = layer_beam
    layered = _load(folder, "all")
    single = _load(folder, "single", box="100 100 100 101 101 101")  # a layer on nothing
    assert np.allclose(layered.model.body.mu, Corotational(2000.0, 0.3).mu)
    assert np.allclose(layered.model.body.lam, Corotational(2000.0, 0.3).lam)
    single.model.body.mu[:] = Corotational(2000.0, 0.3).mu
    single.model.body.lam[:] = Corotational(2000.0, 0.3).lam
    single.model.body.changed()
    a, b = layered.simulate(3), single.simulate(3)
    assert np.abs(a.positions - b.positions).max() < 1e-10
    assert np.abs(a.positions - mesh.points).max() > 1e-3  # it sags


def test_a_layer_adds_its_lame_parameters_to_its_elements(layer_beam) -> None:
    """A layer on the upper half (y > 5) with another Poisson ratio: its elements (the
    centre in the box; with strict, all four nodes) get mu and lambda of both laws added,
    the others the body's."""
    folder, mesh = layer_beam
    box = "-1 5 -1 41 11 11"
    centres = mesh.points[mesh.tets].mean(axis=1)
    for strict, chosen in (
        ('strict="0"', centres[:, 1] > 5.0),
        ("", (mesh.points[mesh.tets][:, :, 1] >= 5.0).all(axis=1)),
    ):
        body = _load(folder, "half", box=box, nu=0.45, strict=strict).model.body
        base, layer = Corotational(500.0, 0.3), Corotational(1500.0, 0.45)
        assert chosen.any() and not chosen.all()
        assert np.allclose(body.mu[chosen], base.mu + layer.mu)
        assert np.allclose(body.lam[chosen], base.lam + layer.lam)
        assert np.allclose(body.mu[~chosen], base.mu)


def test_a_layer_of_another_method_is_named(layer_beam) -> None:
    folder, _ = layer_beam
    with pytest.raises(SceneError, match="a layer's method and material are the body's"):
        _load(folder, "polar", method='method="polar"')
