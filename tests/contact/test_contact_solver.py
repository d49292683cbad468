"""Verification of the contact solver (semismooth Newton judged by Gauss-Seidel): it meets the
tolerance where plain Gauss-Seidel needs thousands of sweeps, its solutions obey Signorini's
and Coulomb's laws (checked from the laws, not from the solver), and it finds Gauss-Seidel's
solution where that one is unique."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints import contact_kernels as kernels
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.friction import ContactBlocks, solve_contact
from pliant.fem.rigid import contact_twist_jacobian
from pliant.geometry.collision import tangent_frame
from pliant.geometry.inertia import box_inertia

# ---------------------------------------------------------------------------- helpers


def cables() -> list[CableActuator]:
    """A displacement-mode row within force bounds and a force-mode row within its course."""
    segment = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    points = EmbeddedPoints.at_nodes([0, 1])
    return [
        CableActuator(points, segment, name="pulled", mode="displacement", value=0.3, max_force=4),
        CableActuator(
            points, segment, name="pushed", mode="force", value=2.0, max_displacement=0.1
        ),
    ]


def gauss_seidel(
    w: np.ndarray, free: np.ndarray, mu: np.ndarray, actuators=(), tolerance=1e-13, sweeps=10**6
) -> tuple[np.ndarray, int, float]:
    """Plain projected block Gauss-Seidel from zero forces: (lambda, sweeps, residual)."""
    n = len(actuators)
    blocks = ContactBlocks.of(actuators, np.zeros(n), slice(0, n), n, mu)
    lam = np.zeros(free.size)
    done, residual = kernels.gauss_seidel(w, free, lam, blocks.arrays(), tolerance, sweeps)
    return lam, int(done), float(residual)


def assert_signorini_coulomb(solution, mu: np.ndarray, tol: float) -> None:
    """The laws at the solution, each contact on its own, to `tol` in displacement units:

    0 <= delta_n _|_ lambda_n >= 0;  |lambda_t| <= mu lambda_n;  inside the disk delta_t = 0;
    on its rim delta_t = -nu lambda_t, nu >= 0 (the slip against the friction force).
    """
    lam = solution.contact_forces
    delta = solution.displacement[solution.slices["contact"]].reshape(-1, 3)
    scale = max(1.0, np.abs(lam).max())
    assert lam[:, 0].min() >= -1e-12 * scale, "Signorini: a contact pulls"
    assert delta[:, 0].min() >= -tol, "Signorini: a contact sinks"
    pressed = lam[:, 0] > 1e-12 * scale
    assert np.abs(delta[pressed, 0]).max(initial=0.0) <= tol, "a pressed contact is open"
    tangential = np.linalg.norm(lam[:, 1:], axis=1)
    radius = mu * lam[:, 0]
    assert np.all(tangential <= radius * (1 + 1e-10) + 1e-12 * scale), "outside the disk"
    stick = tangential < radius * (1 - 1e-6)
    assert np.abs(delta[stick, 1:]).max(initial=0.0) <= tol, "a sticking contact slips"
    rim = ~stick & pressed & (tangential > 0.0)
    direction = lam[rim, 1:] / tangential[rim, None]
    along = np.einsum("ij,ij->i", delta[rim, 1:], direction)
    across = delta[rim, 1:] - along[:, None] * direction
    assert along.max(initial=0.0) <= tol, "a contact slips along its friction force"
    assert np.abs(across).max(initial=0.0) <= tol, "a slip not opposite to its friction force"


def squeezed_box(*, on_floor: bool) -> tuple[np.ndarray, np.ndarray]:
    """W and delta_free of an indeterminate grasp: a rigid 20 mm box of 10 g held by friction
    between two soft blocks that each press 4 points on a face (0.2 mm into it over the step),
    under gravity; on_floor: also resting on its 4 lower corners (W singular there, rank 30 of
    36). Units mm, kg, mN; h = 0.01 s. Each block's points have the compliance of a smooth
    positive-definite kernel, 1e-4 mm/mN on the diagonal; the box's h^2 J M^-1 J^T dwarfs it,
    so the two faces' normal rows are nearly opposite: the stiff-coupling case of the gripper.
    """
    h, mass, a, g = 0.01, 0.01, 10.0, 9810.0
    points = [
        [side * a, y, z] for side in (1, -1) for y in (-a / 2, a / 2) for z in (-a / 2, a / 2)
    ]
    normals = [[side, 0, 0] for side in (1, -1) for _ in range(4)]  # from the box to the block
    if on_floor:
        points += [[x, y, -a] for x in (-a, a) for y in (-a, a)]
        normals += [[0, 0, -1]] * 4
    points, normals = np.array(points, dtype=float), np.array(normals, dtype=float)
    k = len(points)
    frames = np.stack([normals, *tangent_frame(normals)], axis=1)
    jacobian = contact_twist_jacobian(
        frames, points, np.zeros(k, dtype=np.int64), np.zeros((1, 3)), 1
    )
    inverse_mass = np.zeros((6, 6))
    inverse_mass[:3, :3] = np.eye(3) / mass
    inverse_mass[3:, 3:] = np.linalg.inv(box_inertia(mass, [a, a, a]))
    w = h * h * jacobian @ inverse_mass @ jacobian.T
    for block in (slice(0, 4), slice(4, 8)):
        p, f = points[block], frames[block]
        kernel = 1e-4 * np.exp(-np.linalg.norm(p[:, None] - p[None], axis=2) / a)
        rows = np.arange(3 * block.start, 3 * block.stop)
        w[np.ix_(rows, rows)] += np.einsum("ij,iab,jcb->iajc", kernel, f, f).reshape(12, 12)
    # The box falls freely by g h^2 over the step: side a (the blocks, the floor) sees it rise.
    free = -h * jacobian @ np.array([0.0, 0.0, -g * h, 0.0, 0.0, 0.0])
    free[0:24:3] -= 0.2
    return w, free


# ---------------------------------------------------------------------------- tests


@pytest.mark.parametrize("on_floor", [False, True])
def test_indeterminate_grasp_meets_the_tolerance_in_few_iterations(on_floor):
    w, free = squeezed_box(on_floor=on_floor)
    mu = np.full(free.size // 3, 0.8)
    tolerance = 1e-6
    _, sweeps, residual = gauss_seidel(w, free, mu, tolerance=tolerance, sweeps=1000)
    assert residual > tolerance, f"plain Gauss-Seidel met the tolerance in {sweeps} sweeps"
    solution = solve_contact(CondensedProblem.of_rows(w, free), mu, tolerance=tolerance)
    report = solution.report
    assert report.converged and report.iterations <= 20, report
    assert_signorini_coulomb(solution, mu, 10 * tolerance)
    assert np.all(solution.contact_forces[:8, 0] > 0.0)  # both faces squeezed


@pytest.mark.parametrize("rank_deficit", [0, 9])
def test_random_problems_obey_the_laws(rng, rank_deficit):
    """Coupled contacts with friction and two actuators on random W, of full rank or singular
    (W = B B^T with B of 9 columns fewer than rows)."""
    k = 20
    r = 2 + 3 * k
    for _ in range(5):
        b = rng.normal(size=(r, r - rank_deficit))
        w = b @ b.T / r
        free = np.concatenate([rng.normal(size=2), rng.normal(size=3 * k)])
        mu = rng.uniform(0.0, 1.0, k)
        solution = solve_contact(
            CondensedProblem.of_rows(w, free, actuators=2), mu, actuators=cables(), tolerance=1e-10
        )
        assert solution.report.converged, solution.report
        assert_signorini_coulomb(solution, mu, 1e-9)


def test_equals_gauss_seidel_where_its_solution_is_unique(rng):
    """W positive definite: one solution, which plain Gauss-Seidel reaches to 1e-13."""
    k = 15
    r = 2 + 3 * k
    b = rng.normal(size=(r, r))
    w = b @ b.T / r + 0.05 * np.eye(r)
    mu = rng.uniform(0.0, 1.0, k)
    for _ in range(3):
        free = np.concatenate([rng.normal(size=2), rng.normal(size=3 * k)])
        expected, sweeps, residual = gauss_seidel(w, free, mu, cables())
        assert residual <= 1e-13
        solution = solve_contact(
            CondensedProblem.of_rows(w, free, actuators=2), mu, actuators=cables(), tolerance=1e-12
        )
        np.testing.assert_allclose(
            solution.forces, expected, rtol=0, atol=1e-9 * np.abs(expected).max()
        )
        assert solution.report.iterations < sweeps


def test_newton_derivative_matches_finite_differences(rng):
    """J of alart_curnier against central differences of F, at points where no contact or
    actuator is on a kink (open, stick and slip contacts; an actuator holding a displacement,
    one on its force)."""
    k = 12
    r = 2 + 3 * k
    b = rng.normal(size=(r, r))
    w = b @ b.T / r + 0.05 * np.eye(r)
    free = rng.normal(size=r)
    lam = rng.normal(size=r)
    lam[2::3] = np.abs(lam[2::3])
    mu = rng.uniform(0.1, 1.0, k)
    actuators = cables()
    blocks = ContactBlocks.of(actuators, np.zeros(2), slice(0, 2), 2, mu).arrays()
    jacobian, proximal, none = np.empty((r, r)), np.empty((r, r)), np.empty((0, 0))
    f, _ = kernels.alart_curnier(w, w @ lam + free, lam, blocks, jacobian, proximal)
    step = 1e-6
    numeric = np.empty((r, r))
    for j in range(r):
        e = np.zeros(r)
        e[j] = step
        plus, _ = kernels.alart_curnier(w, w @ (lam + e) + free, lam + e, blocks, none, none)
        minus, _ = kernels.alart_curnier(w, w @ (lam - e) + free, lam - e, blocks, none, none)
        numeric[:, j] = (plus - minus) / (2 * step)
    np.testing.assert_allclose(jacobian, numeric, atol=1e-6 * np.abs(jacobian).max())


def test_many_candidate_contacts_are_solved_by_the_sweeps_alone(rng):
    """More rows than ``NEWTON_MAX_ROWS`` (a dense Newton step would cost O(r^3)): 600
    candidate contacts, five pressed into the obstacle, the others open, as the screening of a
    large step hands them over. The sweeps alone meet the laws, with no Newton step."""
    k = 600
    r = 3 * k
    assert r > kernels.NEWTON_MAX_ROWS
    b = rng.normal(size=(r, 30))
    w = 0.2 * b @ b.T / 30 + np.eye(r)
    free = np.zeros(r)
    free[0::3] = rng.uniform(0.1, 1.0, k)
    pressed = rng.choice(k, 5, replace=False)
    free[3 * pressed] = -0.5
    free[1::3], free[2::3] = rng.normal(0.0, 0.1, (2, k))
    mu = np.full(k, 0.5)
    solution = solve_contact(CondensedProblem.of_rows(w, free), mu, tolerance=1e-10)
    assert solution.report.converged and solution.report.newton_steps == 0, solution.report
    assert_signorini_coulomb(solution, mu, 1e-9)
    assert np.count_nonzero(solution.contact_forces[:, 0]) >= 5
