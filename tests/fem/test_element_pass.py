"""The vectorised polar corotational pass (pliant.fem.soa_kernels) against the element-by-element
kernel: same forces, K_s v, rotations, determinants and energy to round-off."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import distorted_box
from scipy.spatial.transform import Rotation

from pliant.bench.element_pass import vector_flops
from pliant.fem import kernels, soa_kernels
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.mesh import box_beam


def _both(body: TetBody, x: np.ndarray, v: np.ndarray) -> list[tuple]:
    """(forces, K_s v, frames, dets, energy) of both passes at x (K_s v only when v has rows)."""
    out = []
    for vectorised in (False, True):
        body.vectorised_element_pass = vectorised
        lin = body.linearise(x, v if v.shape[0] else None)
        out.append((lin.forces, lin.stiffness_velocity, lin.frames, lin.dets, lin.energy))
    return out


def _assert_same(body: TetBody, old: tuple, new: tuple) -> None:
    forces, kv, frames, dets, energy = old
    active = dets > 0.0
    # Forces of a unit strain, the scale of round-off where the body is near rest.
    scale = max(np.abs(forces).max(), body.mu.max() * body.volumes.max() ** (2.0 / 3.0))
    assert np.abs(new[0] - forces).max() <= 1e-10 * scale
    if kv is not None:
        assert np.abs(new[1] - kv).max() <= 1e-10 * np.abs(kv).max()
    # Rotations on the elements that have one (an inverted element's frame is not written).
    assert np.abs(new[2][active] - frames[active]).max() <= 1e-10
    np.testing.assert_array_equal(new[3], dets)
    assert abs(new[4] - energy) <= 1e-10 * max(abs(energy), scale)


@pytest.mark.parametrize("amplitude", [0.0, 0.02, 0.3, 2.0])
def test_vectorised_pass_matches_the_element_pass(rng, amplitude) -> None:
    """Random deformations of a distorted box, turned as a whole: from elements that converge
    in three Newton steps to stretched and inverted ones that the pass computes again one at
    a time; forces and K_s v with and without a velocity."""
    mesh = distorted_box(rng, cells=3)
    body = TetBody(mesh, Corotational(1000.0, 0.45), density=1e-6)
    turn = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    x = (mesh.points + rng.normal(scale=amplitude, size=mesh.points.shape)) @ turn.T
    for v in (np.empty((0, 3)), rng.normal(size=x.shape)):
        old, new = _both(body, x, v)
        _assert_same(body, old, new)
    if amplitude == 2.0:
        assert (old[3] <= 0.0).any(), "no inverted element: the fallback is not exercised"


def test_vectorised_pass_on_a_bent_beam_with_per_element_materials(rng) -> None:
    """A smooth bend of a beam whose Lame parameters vary per element (as SOFA scenes set
    them): every block of elements, including a last partial one, against the element pass."""
    mesh = box_beam(60.0, 10.0, 10.0, 7, 2, 2)  # 168 elements: ten blocks and a partial one
    body = TetBody(mesh, Corotational(500.0, 0.4), density=1e-6)
    body.mu *= rng.uniform(0.5, 2.0, body.mu.shape)
    body.lam *= rng.uniform(0.5, 2.0, body.lam.shape)
    p = mesh.points
    angle = p[:, 0] / 60.0
    x = np.stack([50.0 * np.sin(angle) + p[:, 2] * np.sin(angle), p[:, 1], p[:, 2]], axis=1)
    x[:, 2] = 50.0 * (1.0 - np.cos(angle)) + p[:, 2] * np.cos(angle)
    old, new = _both(body, x, rng.normal(size=x.shape))
    _assert_same(body, old, new)
    assert np.abs(old[0]).max() > 1.0  # a real deformation, not the rest shape


@pytest.mark.parametrize("stretch", [1.01, 1.3])
def test_block_newton_steps_reach_the_polar_factor(rng, stretch) -> None:
    """Small strains converge in the fixed steps, 30 % stretches in the block's further steps:
    no element is left to the element-by-element code, and each rotation is the polar factor
    of its deformation gradient."""
    mesh = box_beam(20.0, 10.0, 10.0, 2, 1, 1)
    turn = Rotation.from_rotvec([0.2, 0.5, -0.4]).as_matrix()
    x = mesh.points * [stretch, 1.0, 1.0] + rng.normal(scale=0.01, size=mesh.points.shape)
    x = x @ turn.T
    vols, grads = kernels.rest_gradients(mesh.points, mesh.tets)
    nodes, g = soa_kernels.soa_layout(mesh.tets, grads)
    m = mesh.n_tets
    frames, dets, energies, last = np.empty((m, 3, 3)), np.empty(m), np.empty(m), np.empty(m)
    forces = np.empty((m, 4, 3))
    mu, lam = np.ones(m), np.ones(m)
    args = (x, np.empty((0, 3)), nodes, g, vols, mu, lam, forces, np.empty((0, 4, 3)), frames)
    soa_kernels._blocks(0, m, *args, dets, energies, last)
    assert (last < kernels._POLAR_TOL).all()
    f = np.einsum("eai,eaj->eij", x[mesh.tets], grads)
    for e in range(m):
        np.testing.assert_allclose(frames[e], kernels.polar_rotation(f[e]), atol=1e-12)


def test_vector_flops_reads_the_vector_loops_of_an_ir_listing() -> None:
    """`pliant bench --element-pass` counts flops per element in the vector loops' IR: each
    vector operation's lanes over the elements an iteration takes, loops told apart by their
    divisions and by whether they read `v`; scalar blocks are not counted."""
    ir = "\n".join(
        [
            "entry:",
            "  %a = fmul double %x, %y",
            "vector.body:",
            "  %1 = fdiv <4 x double> %p, %q",
            "  %2 = fmul <4 x double> %1, %1",
            "  %index.next = add nuw i64 %index, 4",
            "vector.body7:",
            "  %3 = load <4 x double>, ptr %arg.v.4",
            "  %4 = fadd <4 x double> %3, %3",
            "  %5 = fsub <4 x double> %4, %3",
            "  %6 = fmul fast <4 x double> %5, %4",
            "  %index.next9 = add nuw i64 %index8, 4",
        ]
    )
    assert vector_flops(ir) == {"one_more_polar_step": 2.0, "kv": 3.0}
