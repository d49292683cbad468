"""Verification of the tetrahedral elasticity: closed-form cantilevers under mesh refinement,
patch tests, rigid-motion invariance, finite-difference checks of forces and tangents."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MATERIALS, clamped_body
from scipy.spatial.transform import Rotation

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.fem import reference
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.solvers import StaticSolver

E, NU = 1000.0, 0.3

# ---------------------------------------------------------------------------------------------
# Cantilevers clamped at x = 0: 100 x 20 x 20 (the meshes of SOFA's cantilever benchmarks) and a
# slender 100 x 10 x 10.
#
# Euler-Bernoulli: tip load P -> w = P L^3 / (3 E I); distributed load q -> w = q L^4 / (8 E I),
# I = b h^3 / 12. Timoshenko adds shear (k = 5/6, G = E / (2 (1 + nu))), 2.4 % of the
# deflection at L / h = 5 and 0.6 % at L / h = 10:
#   w_P = P L^3 / (3 E I) + P L / (k G A),    w_q = q L^4 / (8 E I) + q L^2 / (2 k G A).
# nu = 0, so that the clamp does not restrain a Poisson contraction the beam theories ignore.
# Loads give w = 1e-3 L: geometric nonlinearity is O((w / L)^2) = 1e-6, below what is measured.
#
# Linear tetrahedra lock in bending: the error is set by the elements through the height
# (2, 4, 8), not by L / h. Measured errors w.r.t. Timoshenko, both geometries and both loads:
# 44.6 %, 17.4 %, 5.1 % (slender: 45.0 %, 17.6 %, 5.1 %); the error falls at close to the
# asymptotic O(h^2) rate only on the finer pair (ratio 3.4, order 1.77).
CANTILEVER_E, SHEAR_FACTOR = 1000.0, 5.0 / 6.0
TIP_DEFLECTION_EB = 0.1  # mm, the Euler-Bernoulli deflection the loads are sized for
CANTILEVERS = {
    "stocky": ((100.0, 20.0, 20.0), [(10, 2, 2), (20, 4, 4), (40, 8, 8)]),
    "slender": ((100.0, 10.0, 10.0), [(20, 2, 2), (40, 4, 4), (80, 8, 8)]),
}


def _cantilever_deflection(size, cells, load: str) -> tuple[float, float]:
    """Mean vertical deflection of the tip face (FE) and Timoshenko's value."""
    L, b, h = size
    area, inertia = b * h, b * h**3 / 12.0
    shear = CANTILEVER_E / 2.0 * SHEAR_FACTOR * area  # k G A with nu = 0
    mesh = box_beam(L, b, h, *cells)
    x = mesh.points
    tip = np.flatnonzero(x[:, 0] >= L - 1e-9)
    material = Corotational(CANTILEVER_E, 0.0)
    if load == "gravity":
        rho = 1e-6
        q = TIP_DEFLECTION_EB * 8.0 * CANTILEVER_E * inertia / L**4
        body = clamped_body(mesh, material, density=rho, gravity=(0.0, 0.0, -q / (rho * area)))
        model = Model(body)
        expected = q * L**4 / (8.0 * CANTILEVER_E * inertia) + q * L**2 / (2.0 * shear)
        commands = None
    else:
        p = TIP_DEFLECTION_EB * 3.0 * CANTILEVER_E * inertia / L**3
        # Tributary areas of the tip-face nodes (trapezoidal rule on the ny x nz grid).
        j = np.rint(x[tip, 1] / (b / cells[1]))
        k = np.rint(x[tip, 2] / (h / cells[2]))
        weights = np.where((j == 0) | (j == cells[1]), 0.5, 1.0)
        weights *= np.where((k == 0) | (k == cells[2]), 0.5, 1.0)
        weights /= weights.sum()
        # A cable pulled from 1e6 mm below a node is a constant vertical force (direction
        # error w / 1e6).
        cables = [
            CableActuator(
                EmbeddedPoints.at_nodes([node]),
                x,
                pull_point=x[node] - [0.0, 0.0, 1e6],
                name=f"load_{node}",
                mode="force",
            )
            for node in tip
        ]
        model = Model(clamped_body(mesh, material), actuators=cables)
        commands = p * weights
        expected = p * L**3 / (3.0 * CANTILEVER_E * inertia) + p * L / shear
    state = StaticSolver(model).step(model.rest_state(), commands)
    deflection = -float(np.mean(state.positions[tip, 2] - x[tip, 2]))
    return deflection, expected


@pytest.mark.parametrize(
    ("beam", "load"), [("stocky", "tip"), ("stocky", "gravity"), ("slender", "tip")]
)
def test_cantilever_converges_to_timoshenko(beam: str, load: str) -> None:
    size, meshes = CANTILEVERS[beam]
    results = [_cantilever_deflection(size, cells, load) for cells in meshes]
    expected = results[0][1]
    w = np.array([r[0] for r in results])
    errors = (expected - w) / expected
    # Displacement-based elements are too stiff: every mesh under-predicts the deflection.
    assert np.all(errors > 0.0), errors
    assert np.all(np.diff(errors) < 0.0), f"error must fall with refinement: {errors}"
    assert errors[-1] < 0.06, errors
    # Observed order on the finer pair, log2(e2 / e3) (asymptotically 2 for linear elements).
    assert np.log2(errors[1] / errors[2]) > 1.5, errors
    # Richardson extrapolation with the O(h^2) rate removes most of the discretisation error
    # (measured 1.0 % left).
    extrapolated = w[2] + (w[2] - w[1]) / 3.0
    assert abs(extrapolated / expected - 1.0) < 0.02, (extrapolated, expected)


# ---------------------------------------------------------------------------------------------
# Rigid motions and patch tests


def _rotation(degrees: float, axis) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return Rotation.from_rotvec(np.deg2rad(degrees) * axis / np.linalg.norm(axis)).as_matrix()


@pytest.mark.parametrize("material", sorted(MATERIALS))
def test_rigid_motions_produce_no_force(material: str, distorted_mesh) -> None:
    body = TetBody(distorted_mesh, MATERIALS[material](E, NU), density=1e-6)
    x = distorted_mesh.points
    # Force of a unit strain on a cell face: E h^2 (h = 10 mm cells).
    scale = E * 10.0**2
    for moved in (x + [12.0, -7.0, 30.0], x @ _rotation(60.0, [1.0, 2.0, -0.5]).T + [5, 0, -3]):
        lin = body.linearise(moved)
        assert np.abs(lin.forces).max() < 1e-9 * scale
        assert abs(lin.energy) < 1e-9 * E * body.volumes.sum()
        assert lin.n_inverted == 0


@pytest.mark.parametrize(
    ("material", "gradient"),
    [("corotational", 0.02), ("corotational", 0.3), ("neo-hookean", 0.3)],
)
def test_affine_patch_is_reproduced_exactly(material, gradient, rng, distorted_mesh) -> None:
    """Boundary nodes at x + G x + c: a uniform F = I + G is an equilibrium of any
    homogeneous material (interior nodal forces sum V P g_a over their elements, which vanishes
    for constant P), so the static solve must put every interior node on the affine map."""
    mesh = distorted_mesh
    x = mesh.points
    boundary = np.unique(mesh.boundary_triangles())
    interior = np.setdiff1d(np.arange(mesh.n_nodes), boundary)
    assert interior.size > 0
    body = TetBody(mesh, MATERIALS[material](E, NU), density=1e-6, fixed_nodes=boundary)
    model = Model(body)
    g = gradient * rng.uniform(-1.0, 1.0, (3, 3))
    affine = x + x @ g.T + rng.uniform(-5.0, 5.0, 3)
    state = model.rest_state()
    # The static solver holds fixed nodes where the state puts them; interior nodes start
    # off the affine map so that Newton has work to do.
    state.positions[:] = affine
    state.positions[interior] += rng.uniform(-1.0, 1.0, (interior.size, 3))
    solved = StaticSolver(model).step(state)
    size = float(np.linalg.norm(np.ptp(x, axis=0)))
    assert np.abs(solved.positions - affine).max() < 1e-8 * size


def test_kernels_match_the_numpy_reference(rng, distorted_mesh) -> None:
    x = distorted_mesh.points
    moved = x @ _rotation(35.0, [0.3, -1.0, 0.2]).T + 0.1 * rng.standard_normal(x.shape) * 10
    for name, cls in MATERIALS.items():
        mat = cls(E, NU)
        lin = TetBody(distorted_mesh, mat, density=1e-6).linearise(moved)
        forces, energy = reference.internal_forces(
            moved, distorted_mesh.tets, x, mat.mu, mat.lam, name
        )
        assert np.abs(lin.forces - forces).max() < 1e-10 * np.abs(forces).max(), name
        assert abs(lin.energy - energy) < 1e-12 * abs(energy), name


# ---------------------------------------------------------------------------------------------
# Finite differences of energy and forces


def _deformed(rng: np.random.Generator, mesh, amplitude: float = 0.5) -> np.ndarray:
    """A large rotation plus a random distortion of ~5 % strain (cells of 10 mm)."""
    x = mesh.points
    return x @ _rotation(50.0, [0.3, -0.5, 0.8]).T + amplitude * rng.standard_normal(x.shape)


@pytest.fixture
def small_beam():
    return box_beam(30.0, 10.0, 10.0, 3, 1, 1)


@pytest.mark.parametrize("material", sorted(MATERIALS))
def test_forces_are_the_energy_gradient(material, rng, small_beam) -> None:
    """f = -dE/dx: central differences (E(x + e d) - E(x - e d)) / 2e = -f . d + O(e^2)."""
    body = TetBody(small_beam, MATERIALS[material](E, NU), density=1e-6)
    x = _deformed(rng, small_beam)
    lin = body.linearise(x)
    assert lin.n_inverted == 0
    eps = 1e-5
    for _ in range(5):
        d = rng.standard_normal(x.shape)
        fd = (body.linearise(x + eps * d).energy - body.linearise(x - eps * d).energy) / (2 * eps)
        assert fd == pytest.approx(-np.sum(lin.forces * d), rel=1e-7)


@pytest.mark.parametrize(
    ("material", "exact"), [("corotational", True), ("neo-hookean", False), ("neo-hookean", True)]
)
def test_tangent_stiffness_matches_force_differences(material, exact, rng, small_beam) -> None:
    """K_s u = -(f(x + e u) - f(x - e u)) / 2e + O(e^2), on the free DoFs, at a stretched and
    rotated configuration (the corotational default R K0 R^T is not the exact tangent there)."""
    mesh = small_beam
    body = clamped_body(mesh, MATERIALS[material](E, NU))
    x = _deformed(rng, mesh)
    lin = body.linearise(x)
    eps = 1e-4
    for _ in range(3):
        u = body.gather(rng.standard_normal(x.shape))
        du = body.scatter(u)
        fd = -body.gather(body.linearise(x + eps * du).forces - body.linearise(x - eps * du).forces)
        fd /= 2 * eps
        ku = body.stiffness_matvec(lin, u, exact=exact)
        error = np.linalg.norm(ku - fd) / np.linalg.norm(fd)
        assert error < 1e-6, f"relative error of K u: {error:.3g}"


@pytest.mark.parametrize(
    ("material", "exact"), [("corotational", False), ("corotational", True), ("neo-hookean", False)]
)
def test_assembled_stiffness_equals_matvec_and_is_symmetric(material, exact, rng, small_beam):
    body = clamped_body(small_beam, MATERIALS[material](E, NU))
    lin = body.linearise(_deformed(rng, small_beam))
    k = body.stiffness_matrix(lin, exact=exact).toarray()
    u = rng.standard_normal((body.n_free, 3))
    ku = body.stiffness_matvec(lin, u, exact=exact)
    assert np.abs(k @ u - ku).max() < 1e-12 * np.abs(k @ u).max()
    # The exact tangent of an energy and SOFA's R K0 R^T are both symmetric.
    assert np.abs(k - k.T).max() < 1e-12 * np.abs(k).max()


def test_corotational_default_tangent_is_exact_at_rotated_rest(small_beam) -> None:
    """At F = R (no strain) the stress vanishes, so the variation of R drops out of
    dP = dR sigma + R dsigma and SOFA's R K0 R^T is the exact tangent."""
    body = clamped_body(small_beam, Corotational(E, NU))
    x = small_beam.points @ _rotation(60.0, [1.0, 2.0, -0.5]).T + [3.0, -1.0, 2.0]
    lin = body.linearise(x)
    default = body.stiffness_matrix(lin).toarray()
    exact = body.stiffness_matrix(lin, exact=True).toarray()
    error = np.abs(default - exact).max() / np.abs(default).max()
    assert error < 1e-10, f"max |K_default - K_exact| / max |K| = {error:.3g}"


def test_corotational_default_tangent_matches_differences_at_rotated_rest(rng, small_beam):
    body = clamped_body(small_beam, Corotational(E, NU))
    x = small_beam.points @ _rotation(60.0, [1.0, 2.0, -0.5]).T + [3.0, -1.0, 2.0]
    lin = body.linearise(x)
    eps = 1e-4
    u = body.gather(rng.standard_normal(x.shape))
    du = body.scatter(u)
    fd = -body.gather(body.linearise(x + eps * du).forces - body.linearise(x - eps * du).forces)
    fd /= 2 * eps
    error = np.linalg.norm(body.stiffness_matvec(lin, u) - fd) / np.linalg.norm(fd)
    assert error < 1e-6, f"relative error of K u: {error:.3g}"


# ---------------------------------------------------------------------------------------------
# Mass


@pytest.mark.parametrize("mass", ["lumped", "uniform", "consistent"])
def test_mass_of_a_rigid_translation_is_the_total_mass(mass, distorted_mesh) -> None:
    """u^T M u for a unit translation u is the body's mass rho V, for every mass model, and
    the weight M g adds up to rho V g (linear shape functions sum to 1)."""
    body = TetBody(
        distorted_mesh, Corotational(E, NU), density=2e-6, mass=mass, gravity=(0, 0, -9.0)
    )
    total = 2e-6 * 30.0**3
    assert body.total_mass == pytest.approx(total, rel=1e-12)
    for axis in range(3):
        u = np.zeros((body.n_nodes, 3))
        u[:, axis] = 1.0
        u = body.gather(u)
        assert u @ body.mass_matvec(u) == pytest.approx(total, rel=1e-12)
    assert body.gravity_forces().sum(axis=0) == pytest.approx([0.0, 0.0, -9.0 * total], rel=1e-12)
    matrix = body.pattern.matrix(body.mass_data)
    v = np.random.default_rng(1).standard_normal(body.n_free)
    assert matrix @ v == pytest.approx(body.mass_matvec(v), rel=1e-12)


def test_nodal_sums_agree_on_one_and_several_threads():
    """The element-order scatter (one thread) and the node-parallel gather sum the same terms."""
    from pliant.fem import kernels

    body = TetBody(box_beam(30.0, 10.0, 10.0, 6, 2, 2), Corotational(E, NU), density=1e-6)
    values = np.random.default_rng(0).normal(size=(body.tets.shape[0], 4, 6))
    by_node = np.empty((body.rest_positions.shape[0], 6))
    by_element = np.empty_like(by_node)
    kernels._gather_by_node(values, body._incidence_ptr, body._incidence, by_node)
    kernels._scatter_by_element(values, body.tets, by_element)
    expected = np.zeros_like(by_node)
    np.add.at(expected, body.tets, values)
    np.testing.assert_allclose(by_node, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(by_element, expected, rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# SOFA's "large" rotation: R = Q(x) Q(X)^T from the edge frames (first edge, then the plane of
# the first two), P = R (2 mu eps + lam tr(eps) I) with eps = sym(R^T F) - I.


def _large(young: float = E, nu: float = NU) -> Corotational:
    return Corotational(young, nu, rotation="large")


def test_large_rotation_rigid_motions_produce_no_force(distorted_mesh) -> None:
    body = TetBody(distorted_mesh, _large(), density=1e-6)
    x = distorted_mesh.points
    scale = E * 10.0**2
    for moved in (x + [12.0, -7.0, 30.0], x @ _rotation(130.0, [1.0, 2.0, -0.5]).T + [5, 0, -3]):
        lin = body.linearise(moved)
        assert np.abs(lin.forces).max() < 1e-9 * scale
        assert abs(lin.energy) < 1e-9 * E * body.volumes.sum()


def test_large_rotation_kernels_match_the_numpy_reference(rng, distorted_mesh) -> None:
    x = distorted_mesh.points
    moved = x @ _rotation(35.0, [0.3, -1.0, 0.2]).T + rng.standard_normal(x.shape)
    mat = _large()
    lin = TetBody(distorted_mesh, mat, density=1e-6).linearise(moved)
    forces, energy = reference.internal_forces(
        moved, distorted_mesh.tets, x, mat.mu, mat.lam, "corotational", rotation="large"
    )
    assert np.abs(lin.forces - forces).max() < 1e-10 * np.abs(forces).max()
    assert abs(lin.energy - energy) < 1e-12 * abs(energy)
    polar = TetBody(distorted_mesh, Corotational(E, NU), density=1e-6).linearise(moved)
    assert np.abs(lin.forces - polar.forces).max() > 1e-3 * np.abs(forces).max()


def test_large_rotation_passes_the_patch_test_to_first_order(rng, distorted_mesh) -> None:
    """Boundary nodes on a rotated affine map x = R0 (X + G X) + c. Each element's edge frame
    differs from the polar rotation by O(|G|), so a uniform F is an equilibrium up to O(|G|^2)
    (exactly in the linear limit, the linear patch test): the interior nodes' distance to the
    affine map, relative to the strain's displacement, falls in proportion to |G|."""
    mesh = distorted_mesh
    x = mesh.points
    boundary = np.unique(mesh.boundary_triangles())
    interior = np.setdiff1d(np.arange(mesh.n_nodes), boundary)
    model = Model(TetBody(mesh, _large(), density=1e-6, fixed_nodes=boundary))
    r0 = _rotation(70.0, [0.2, 1.0, -0.4])
    direction = rng.uniform(-1.0, 1.0, (3, 3))
    relative = []
    for size in (1e-2, 1e-3):
        g = size * direction
        affine = (x + x @ g.T) @ r0.T + [3.0, -2.0, 1.0]
        state = model.rest_state()
        state.positions[:] = affine
        solved = StaticSolver(model).step(state)
        strain_motion = np.abs(x @ g.T).max()
        relative.append(np.abs(solved.positions - affine)[interior].max() / strain_motion)
    # Measured: 4.2e-4 and 4.2e-5 (a tenth of the strain, a tenth of the relative error).
    assert relative[0] < 2e-3
    assert relative[1] < 0.15 * relative[0], relative


def test_large_rotation_forces_are_the_energy_gradient_where_the_frame_is_polar(rng) -> None:
    """With the first edge along x and the first face in the xy plane, F = R0 diag(a, b, c)
    keeps the edge frame equal to the polar rotation (R^T F symmetric), where the variation of
    R drops out of d psi: f = -dE/dx there, although R depends on x."""
    rest = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [1.0, 3.0, 0.0], [1.5, 1.0, 5.0]])
    mesh = TetMesh(rest, np.array([[0, 1, 2, 3]]))
    body = TetBody(mesh, _large(), density=1e-6)
    r0 = _rotation(40.0, [1.0, -2.0, 0.5])
    x = (rest * [1.1, 0.93, 1.05]) @ r0.T + [1.0, 2.0, 3.0]
    lin = body.linearise(x)
    assert np.abs(lin.forces).max() > 1.0
    eps = 1e-6
    for _ in range(5):
        d = rng.standard_normal(x.shape)
        fd = (body.linearise(x + eps * d).energy - body.linearise(x - eps * d).energy) / (2 * eps)
        assert fd == pytest.approx(-np.sum(lin.forces * d), rel=1e-7)


def _sofa_element_stiffness(rest: np.ndarray, x: np.ndarray, young: float, nu: float):
    """One element's stiffness as SOFA's 'large' method assembles it, written independently of
    the kernels: the element in its rest edge frame, the strain-displacement matrix B (6 x 12,
    Voigt, engineering shear), the isotropic C, K_local = V B^T C B, then rotated to the current
    edge frame: K = Q K_local Q^T blockwise."""
    q0, q = reference.edge_frame(rest), reference.edge_frame(x)
    local = (rest - rest[0]) @ q0
    dm = (local[1:] - local[0]).T
    grads = np.vstack([-np.linalg.inv(dm).sum(axis=0), np.linalg.inv(dm)])
    b = np.zeros((6, 12))
    for a, (gx, gy, gz) in enumerate(grads):
        b[:, 3 * a : 3 * a + 3] = [
            [gx, 0, 0],
            [0, gy, 0],
            [0, 0, gz],
            [gy, gx, 0],
            [0, gz, gy],
            [gz, 0, gx],
        ]
    c = np.full((3, 3), nu) + np.eye(3) * (1 - 2 * nu)
    c = np.block([[c, np.zeros((3, 3))], [np.zeros((3, 3)), np.eye(3) * (1 - 2 * nu) / 2]])
    c *= young / ((1 + nu) * (1 - 2 * nu))
    vol = abs(np.linalg.det(dm)) / 6.0
    rot = np.kron(np.eye(4), q)
    return rot @ (vol * b.T @ c @ b) @ rot.T


def test_large_rotation_tangent_is_sofas_rotated_linear_stiffness(rng) -> None:
    """The step's tangent (and the static Newton's, for this law) is SOFA's R K0 R^T, not the
    Jacobian of the forces: it matches SOFA's element stiffness at a strained, rotated state."""
    rest = np.array([[0.0, 0.0, 0.0], [4.0, 0.5, 0.0], [1.0, 3.0, 0.2], [1.5, 1.0, 5.0]])
    mesh = TetMesh(rest, np.array([[0, 1, 2, 3]]))
    body = TetBody(mesh, _large(), density=1e-6)
    x = rest @ _rotation(75.0, [1.0, 0.3, -0.5]).T + 0.2 * rng.standard_normal(rest.shape)
    lin = body.linearise(x)
    expected = _sofa_element_stiffness(rest, x, E, NU)
    for exact in (False, True):
        k = body.stiffness_matrix(lin, exact=exact).toarray()
        assert np.abs(k - expected).max() < 1e-12 * np.abs(expected).max()


def test_large_rotation_tangent_matches_force_differences_at_rotated_rest(rng, small_beam):
    """At F = R (no strain) R K0 R^T is the exact Jacobian of the forces."""
    body = clamped_body(small_beam, _large())
    x = small_beam.points @ _rotation(60.0, [1.0, 2.0, -0.5]).T + [3.0, -1.0, 2.0]
    lin = body.linearise(x)
    eps = 1e-4
    u = body.gather(rng.standard_normal(x.shape))
    du = body.scatter(u)
    fd = -body.gather(body.linearise(x + eps * du).forces - body.linearise(x - eps * du).forces)
    fd /= 2 * eps
    error = np.linalg.norm(body.stiffness_matvec(lin, u) - fd) / np.linalg.norm(fd)
    assert error < 1e-6, f"relative error of K u: {error:.3g}"


def test_an_unknown_rotation_is_a_material_error() -> None:
    from pliant.errors import MaterialError

    with pytest.raises(MaterialError, match="'polar' or 'large'"):
        Corotational(E, NU, rotation="small")


def test_inversion_needs_the_large_frame_and_a_known_policy() -> None:
    from pliant.errors import MaterialError

    with pytest.raises(MaterialError, match="reflection"):
        Corotational(E, NU, inversion="tolerate")
    with pytest.raises(MaterialError, match="'refuse' or 'tolerate'"):
        Corotational(E, NU, rotation="large", inversion="ignore")


# ---------------------------------------------------------------------------------------------
# Inverted elements under the large frame. SOFA's method="large" has no inversion check: the edge
# frame is a rotation whatever the element's orientation, and an inverted element keeps the
# force of psi = mu |sym(R^T F) - I|^2 + lam/2 tr(R^T F - I)^2, which pushes it back.


def _inverted_state(small_beam) -> np.ndarray:
    """The beam's positions (30 x 10 x 10 mm, cells of 10 mm) with its tip corner node pushed
    15 mm inwards, through the elements around it."""
    x = small_beam.points.copy()
    tip = np.flatnonzero(x[:, 0] >= x[:, 0].max() - 1e-9)
    corner = tip[np.argmax(x[tip, 1] + x[tip, 2])]
    x[corner, 0] -= 15.0
    return x


def test_an_inverted_element_keeps_sofas_large_frame_force_when_tolerated(small_beam) -> None:
    from pliant.errors import DivergenceError
    from pliant.solvers.base import check_linearisation

    x = _inverted_state(small_beam)
    tolerant = Corotational(E, NU, rotation="large", inversion="tolerate")
    lin = clamped_body(small_beam, tolerant).linearise(x)
    assert lin.n_inverted > 0 and lin.dets.min() < 0.0
    forces, energy = reference.internal_forces(
        x, small_beam.tets, small_beam.points, tolerant.mu, tolerant.lam, "corotational", "large"
    )
    assert np.abs(lin.forces - forces).max() < 1e-10 * np.abs(forces).max()
    assert lin.energy == pytest.approx(energy, rel=1e-12)
    check_linearisation(lin, 1, 0.01)  # tolerated: no error
    # The same state under the refusing law: the inverted elements give no force and the
    # step reports them.
    refused = clamped_body(small_beam, _large()).linearise(x)
    assert refused.n_inverted == lin.n_inverted
    assert np.abs(refused.forces - forces).max() > 1e-3 * np.abs(forces).max()
    with pytest.raises(DivergenceError, match="inverted") as info:
        check_linearisation(refused, 1, 0.01)
    assert info.value.cause == "inverted"
    # Away from inversion the two laws are one.
    x_ok = small_beam.points + 0.01 * (x - small_beam.points)
    a = clamped_body(small_beam, tolerant).linearise(x_ok)
    b = clamped_body(small_beam, _large()).linearise(x_ok)
    np.testing.assert_array_equal(a.forces, b.forces)


def test_a_tolerated_inverted_element_is_pulled_back_to_the_rest_shape(small_beam) -> None:
    """Released from the inverted state, the damped beam returns to its rest shape with every
    element the right way out; the refusing law stops at the first step."""
    from pliant.errors import DivergenceError
    from pliant.model import State
    from pliant.solvers import ImplicitEuler

    x = _inverted_state(small_beam)
    tolerant = Corotational(E, NU, rotation="large", inversion="tolerate")
    body = clamped_body(small_beam, tolerant, rayleigh_mass=5.0, rayleigh_stiffness=0.01)
    model = Model(body)
    solver = ImplicitEuler(model, 0.01)
    rest = model.rest_state()
    state = State(x, np.zeros_like(x))
    assert body.linearise(state.positions).n_inverted > 0
    for _ in range(200):
        state = solver.step(state)
    assert body.linearise(state.positions).n_inverted == 0
    assert np.abs(state.positions - rest.positions).max() < 0.03  # mm

    refusing = Model(clamped_body(small_beam, _large(), rayleigh_mass=5.0))
    with pytest.raises(DivergenceError, match="inverted"):
        ImplicitEuler(refusing, 0.01).step(State(x, np.zeros_like(x)))
