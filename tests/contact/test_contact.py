"""Verification of the contact building blocks: collision shapes and detection, the
Signorini-Coulomb Gauss-Seidel solver, and rigid bodies stepped with frictional contact."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.direct import solve_direct
from pliant.constraints.friction import ContactConstraint, ContactForces, solve_contact
from pliant.errors import ContactConvergenceWarning, ContactError, ModelError
from pliant.fem.material import Corotational
from pliant.fem.rigid import (
    AttachedPoints,
    KinematicBody,
    RigidBody,
    contact_twist_jacobian,
    rail,
    servo,
    twist_jacobian,
)
from pliant.geometry import collision_kernels as kernels
from pliant.geometry.collision import (
    Box,
    Capsule,
    ContactSet,
    Plane,
    Sphere,
    TriangleMesh,
    TriangleSurface,
    collide,
    detect,
    shape_velocities,
    tangent_frame,
)
from pliant.geometry.inertia import box_inertia, capsule_inertia, sphere_inertia
from pliant.geometry.rotation import axis_angle, exp_map, log_map
from pliant.mesh import box_beam
from pliant.solvers.rigid import RigidSolver, RigidWorld

G = 9.81


# ---------------------------------------------------------------------------- helpers


def actuator(**settings) -> CableActuator:
    """An actuator row (a cable along a unit segment; only its mode and bounds matter here)."""
    segment = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    return CableActuator(EmbeddedPoints.at_nodes([0, 1]), segment, **settings)


def random_spd(rng: np.random.Generator, n: int, floor: float = 0.05) -> np.ndarray:
    b = rng.normal(size=(n, n))
    return b @ b.T / n + floor * np.eye(n)


def box_mesh(half_extents) -> tuple[np.ndarray, np.ndarray]:
    """The 12 outward triangles of the box [-h, h]."""
    h = np.asarray(half_extents, dtype=float)
    vertices = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -h, x = +h
            [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -h, y = +h
            [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # z = -h, z = +h
        ]
    )  # fmt: skip
    return vertices, faces


def assert_contact_laws(solution, mu: np.ndarray, tol: float) -> None:
    """Signorini and Coulomb at the solution, to `tol` in displacement units."""
    lam = solution.contact_forces
    delta = solution.displacement[solution.slices["contact"]].reshape(-1, 3)
    assert lam[:, 0].min() >= 0.0
    assert delta[:, 0].min() >= -tol
    assert np.all(np.abs(lam[:, 0] * delta[:, 0]) <= tol * np.maximum(lam[:, 0], 1.0))
    tangential = np.linalg.norm(lam[:, 1:], axis=1)
    assert np.all(tangential <= mu * lam[:, 0] * (1 + 1e-12) + 1e-300)  # the cone
    stick = tangential < mu * lam[:, 0] * (1 - 1e-9)
    assert np.abs(delta[stick, 1:]).max(initial=0.0) <= tol
    slip = ~stick & (lam[:, 0] > 0)
    slide = delta[slip, 1:]
    moving = np.linalg.norm(slide, axis=1) > 10 * tol
    # Maximal dissipation: the slip is opposite to the friction force.
    cosine = np.einsum("ij,ij->i", lam[slip, 1:][moving], slide[moving]) / (
        tangential[slip][moving] * np.linalg.norm(slide[moving], axis=1)
    )
    assert np.all(cosine <= -1 + 1e-9)


# ---------------------------------------------------------------------------- friction solver


@pytest.mark.parametrize("free_normal", [-0.3, 0.2])
def test_frictionless_contact_is_the_closed_form(rng, free_normal):
    # One frictionless contact: lambda_n = max(0, -delta_free_n / W_nn), lambda_t = 0.
    w = random_spd(rng, 3)
    free = np.array([free_normal, 0.7, -0.4])
    solution = solve_contact(CondensedProblem.of_rows(w, free), 0.0, tolerance=1e-14)
    expected = max(0.0, -free_normal / w[0, 0])
    np.testing.assert_allclose(solution.contact_forces[0], [expected, 0.0, 0.0], atol=1e-14)
    assert solution.report.converged and solution.report.iterations <= 2


def test_stick_and_slip_of_one_contact():
    # W = diag(w_n, w_t, w_t), delta_free = (-d, s, 0): lambda_n = d / w_n; the contact sticks
    # (lambda_t = -s / w_t, delta_t = 0) iff |s| / w_t <= mu lambda_n, otherwise it slips with
    # lambda_t = -mu lambda_n sign(s) and delta_t = s - w_t mu lambda_n sign(s).
    w_n, w_t, d, mu = 2.0, 0.5, 0.4, 0.5
    w = np.diag([w_n, w_t, w_t])
    lam_n = d / w_n
    for s in (0.02, -0.04, 0.3, -1.0):
        solution = solve_contact(
            CondensedProblem.of_rows(w, np.array([-d, s, 0.0])), mu, tolerance=1e-14
        )
        lam = solution.contact_forces[0]
        delta = solution.displacement
        if abs(s) / w_t <= mu * lam_n:
            np.testing.assert_allclose(lam, [lam_n, -s / w_t, 0.0], atol=1e-14)
            np.testing.assert_allclose(delta, 0.0, atol=1e-14)
        else:
            slip = -mu * lam_n * np.sign(s)
            np.testing.assert_allclose(lam, [lam_n, slip, 0.0], atol=1e-14)
            np.testing.assert_allclose(delta[1], s + w_t * slip, atol=1e-14)


def test_anisotropic_slip_opposes_the_force(rng):
    # With W_tt anisotropic a radial clamp of the unconstrained lambda_t would slip obliquely;
    # the disk problem keeps delta_t = -nu lambda_t (maximal dissipation).
    w = np.array([[1.0, 0.2, -0.1], [0.2, 3.0, 1.2], [-0.1, 1.2, 0.8]])
    solution = solve_contact(
        CondensedProblem.of_rows(w, np.array([-0.5, 2.0, -1.0])), 0.3, tolerance=1e-14
    )
    assert_contact_laws(solution, np.array([0.3]), 1e-12)
    lam = solution.contact_forces[0]
    np.testing.assert_allclose(np.linalg.norm(lam[1:]), 0.3 * lam[0], rtol=1e-12)


def test_coupled_contacts_obey_signorini_and_coulomb(rng):
    k = 25
    w = random_spd(rng, 3 * k)
    mu = rng.uniform(0.0, 1.0, k)
    for _ in range(3):
        free = rng.normal(size=3 * k)
        solution = solve_contact(
            CondensedProblem.of_rows(w, free), mu, tolerance=1e-12, max_iterations=5000
        )
        assert solution.report.converged
        assert_contact_laws(solution, mu, 1e-10)


def test_actuators_without_active_contact_match_the_direct_solve(rng):
    # Contacts wide open (delta_free_n >> 0) exert nothing; the actuators then follow exactly
    # the direct solve: a displacement command, a force command held at its course bound.
    w = random_spd(rng, 2 + 6)
    free = np.concatenate([[0.1, -0.2], [5.0, 0.1, 0.2, 7.0, -0.3, 0.0]])
    actuators = [
        actuator(name="cable", mode="displacement", value=0.5, max_force=10.0),
        actuator(name="cavity", mode="force", value=3.0, max_displacement=0.4),
    ]
    problem = CondensedProblem.of_rows(w, free, actuators=2)
    solution = solve_contact(problem, 0.4, actuators=actuators, tolerance=1e-14)
    expected = solve_direct(problem, actuators, np.zeros(2), tolerance=1e-14)
    np.testing.assert_allclose(solution.actuation, expected, atol=1e-12)
    np.testing.assert_allclose(solution.contact_forces, 0.0, atol=1e-15)


def test_actuator_pushing_into_a_contact(rng):
    # A displacement-mode actuator drives a point into an obstacle: the command is met, the
    # contact is compressed just enough (and no more) to hold the point at the surface.
    w = random_spd(rng, 4)
    free = np.array([0.0, 0.05, 0.0, 0.0])
    servo_row = actuator(name="servo", mode="displacement", value=1.0, min_force=-np.inf)
    solution = solve_contact(
        CondensedProblem.of_rows(w, free, actuators=1), 0.5, actuators=[servo_row], tolerance=1e-14
    )
    np.testing.assert_allclose(solution.displacement[0], 1.0, atol=1e-12)
    assert_contact_laws(solution, np.array([0.5]), 1e-12)


def test_warm_start_reduces_the_iterations(rng):
    k = 30
    w = random_spd(rng, 3 * k)
    mu = np.full(k, 0.6)
    free = rng.normal(size=3 * k)
    cold = solve_contact(
        CondensedProblem.of_rows(w, free), mu, tolerance=1e-10, max_iterations=5000
    )
    nearby = free + 1e-6 * rng.normal(size=3 * k)  # the next step of a smooth motion
    again_cold = solve_contact(
        CondensedProblem.of_rows(w, nearby), mu, tolerance=1e-10, max_iterations=5000
    )
    warm = solve_contact(
        CondensedProblem.of_rows(w, nearby),
        mu,
        initial=cold.forces,
        tolerance=1e-10,
        max_iterations=5000,
    )
    assert warm.report.iterations < again_cold.report.iterations / 2
    np.testing.assert_allclose(warm.forces, again_cold.forces, atol=1e-6)


def test_non_convergence_warns_with_the_residual(rng):
    w = random_spd(rng, 30)
    with pytest.warns(ContactConvergenceWarning, match="residual"):
        solution = solve_contact(
            CondensedProblem.of_rows(w, rng.normal(size=30)), 0.5, tolerance=1e-14, max_iterations=2
        )
    assert not solution.report.converged
    assert solution.report.iterations == 2 and solution.report.residual > 1e-14


def test_invalid_contact_problems_raise(rng):
    w, free = random_spd(rng, 6), rng.normal(size=6)
    with pytest.raises(ContactError, match="mu = -0.1"):
        solve_contact(CondensedProblem.of_rows(w, free), [0.5, -0.1])
    with pytest.raises(ContactError, match="finite"):
        solve_contact(CondensedProblem.of_rows(w, free), [0.5, np.nan])
    bad = free.copy()
    bad[2] = np.inf
    with pytest.raises(ContactError, match="finite"):
        solve_contact(CondensedProblem.of_rows(w, bad), 0.5)
    with pytest.raises(ContactError, match="symmetric"):
        solve_contact(CondensedProblem.of_rows(w + np.triu(np.ones((6, 6)), 1), free), 0.5)
    with pytest.raises(ContactError, match="triples"):
        solve_contact(CondensedProblem.of_rows(w[:5, :5], free[:5]), 0.5)


def test_warm_start_is_matched_by_contact_identity():
    def contacts(keys, normals):
        k = len(keys)
        keys = np.asarray(keys)
        z = np.zeros((k, 3))
        return ContactSet(keys[:, 0], keys[:, 1], keys[:, 2], np.zeros(k), normals, z, z)

    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    before = contacts([[3, 0, 6], [5, 1, 10]], normals)
    forces = ContactForces.from_multipliers(before, np.array([[2.0, 0.1, 0.2], [1.0, 0.0, 0.3]]))
    # The second contact is gone, a new one appears, the first one's normal turned.
    turned = exp_map(np.array([0.2, 0.0, 0.0])) @ normals[0]
    after = contacts([[9, 0, 18], [3, 0, 6]], np.array([[0.0, 1.0, 0.0], turned]))
    start = ContactForces.warm_start(forces, after).reshape(-1, 3)
    np.testing.assert_allclose(start[0], 0.0)
    world_force = forces.forces[0]
    np.testing.assert_allclose(after.frames[1].T @ start[1], world_force, atol=1e-14)


# ---------------------------------------------------------------------------- shapes


def test_primitive_signed_distances_match_closed_forms(rng):
    rotation = axis_angle([1.0, -2.0, 0.5], 0.8)
    centre = np.array([0.3, -0.2, 0.1])
    points = centre + rng.uniform(-2.0, 2.0, (2000, 3))
    local = (points - centre) @ rotation  # R^T (p - c), row-wise

    def along_axis(v):
        return v @ rotation.T

    h = np.array([0.5, 0.3, 0.8])
    q = np.abs(local) - h
    box_phi = np.where(
        np.all(q <= 0, axis=1), q.max(axis=1), np.linalg.norm(np.maximum(q, 0), axis=1)
    )
    segment = np.zeros_like(local)
    segment[:, 2] = np.clip(local[:, 2], -0.6, 0.6)
    expected = {
        "sphere": (Sphere(0.7, centre), np.linalg.norm(points - centre, axis=1) - 0.7),
        "plane": (Plane(along_axis([0, 0, 1.0]), centre), local[:, 2]),
        "box": (Box(h, centre, rotation), box_phi),
        "capsule": (
            Capsule(0.4, 0.6, centre, rotation),
            np.linalg.norm(local - segment, axis=1) - 0.4,
        ),
    }
    for name, (shape, phi) in expected.items():
        answer = shape.signed_distance(points)
        np.testing.assert_allclose(answer.gap, phi, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(np.linalg.norm(answer.normal, axis=1), 1.0, atol=1e-12)
        # p = c + phi n, and c lies on the surface.
        np.testing.assert_allclose(
            answer.closest + answer.gap[:, None] * answer.normal, points, atol=1e-12, err_msg=name
        )
        np.testing.assert_allclose(shape.signed_distance(answer.closest).gap, 0.0, atol=1e-12)


def test_mesh_of_a_box_agrees_with_the_box(rng):
    h = np.array([0.4, 0.25, 0.6])
    rotation = axis_angle([0.3, 1.0, -0.2], 1.1)
    position = np.array([1.0, -0.5, 0.2])
    box = Box(h, position, rotation)
    mesh = TriangleMesh(*box_mesh(h), position, rotation)
    points = position + rng.uniform(-1.5, 1.5, (5000, 3))
    a, b = box.signed_distance(points), mesh.signed_distance(points)
    np.testing.assert_allclose(b.gap, a.gap, atol=1e-12)
    np.testing.assert_allclose(b.closest, a.closest, atol=1e-12)
    np.testing.assert_allclose(b.normal, a.normal, atol=1e-9)
    np.testing.assert_allclose(mesh.volume, 8 * np.prod(h), rtol=1e-12)


def test_mesh_distance_agrees_with_trimesh_on_a_torus(rng):
    # An independent code (closest points by trimesh, sign by its ray tests; trimesh counts
    # inside as positive) on a non-convex mesh.
    trimesh = pytest.importorskip("trimesh")
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    mesh = TriangleMesh(torus.vertices, torus.faces)
    points = rng.uniform(-1.5, 1.5, (1500, 3))
    reference = -trimesh.proximity.signed_distance(torus, points)
    np.testing.assert_allclose(mesh.signed_distance(points).gap, reference, atol=1e-7)


def test_invalid_shapes_raise():
    vertices, faces = box_mesh([1.0, 1.0, 1.0])
    with pytest.raises(ContactError, match="inwards"):
        TriangleMesh(vertices, faces[:, ::-1])
    with pytest.raises(ContactError, match="not closed"):
        TriangleMesh(vertices, faces[:-1])
    with pytest.raises(ContactError, match="radius"):
        Sphere(0.0)
    with pytest.raises(ContactError, match="half extents"):
        Box([1.0, -1.0, 1.0])
    with pytest.raises(ContactError, match="half length"):
        Capsule(1.0, np.nan)
    with pytest.raises(ContactError, match="rotation"):
        Box([1.0, 1.0, 1.0], rotation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ContactError, match="position"):
        Sphere(1.0, [0.0, np.inf, 0.0])
    with pytest.raises(ContactError, match="mu"):
        ContactConstraint(ContactSet.empty(), EmbeddedPoints.at_nodes(np.arange(3)), friction=-1)


def test_rigid_pairs_give_closed_form_gaps():
    # Sphere-sphere: |c_a - c_b| - r_a - r_b along the line of centres.
    pair = collide(Sphere(0.5, [0.0, 0.0, 1.2]), Sphere(0.6, [0.0, 0.0, 0.0]), margin=0.5)
    np.testing.assert_allclose([pair.gap[0], *pair.normal[0]], [0.1, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(pair.point_a[0] - pair.point_b[0], 0.1 * pair.normal[0])
    # Box above sphere (b first): the sphere's centre against the box, normal out of the box.
    pair = collide(Box([1.0, 1.0, 0.5], [0.0, 0.0, 1.0]), Sphere(0.4, [0.2, 0.0, 0.0]), 0.5)
    np.testing.assert_allclose([pair.gap[0], *pair.normal[0]], [0.1, 0.0, 0.0, 1.0], atol=1e-15)
    # A box tilted on one edge over a plane: its two lowest corners, at their height.
    tilt = axis_angle([1.0, 0.0, 0.0], 0.3)
    box = Box([0.5, 0.2, 0.1], [0.0, 0.0, 0.3], tilt)
    corners = box.samples()[0]
    pair = collide(box, Plane(), margin=0.3 - 0.2 * np.sin(0.3) + 0.01)
    lowest = np.sort(corners[:, 2])[:4]
    np.testing.assert_allclose(np.sort(pair.gap), lowest[:2] if lowest[2] > lowest[1] else lowest)
    # A box on a mesh of a box: the same contacts as on the box itself.
    ground = Box([2.0, 2.0, 0.5], [0.0, 0.0, -0.5])
    mesh = TriangleMesh(*box_mesh([2.0, 2.0, 0.5]), [0.0, 0.0, -0.5])
    on_box, on_mesh = collide(box, ground, 0.5), collide(box, mesh, 0.5)
    np.testing.assert_array_equal(on_mesh.feature, on_box.feature)
    np.testing.assert_allclose(on_mesh.gap, on_box.gap, atol=1e-14)
    np.testing.assert_allclose(on_mesh.normal, on_box.normal, atol=1e-14)


# ---------------------------------------------------------------------------- broad phase


def test_broad_phase_finds_exactly_the_brute_force_contacts(rng):
    points = rng.uniform(0.0, 100.0, (10_000, 3))
    shapes = [Plane([0.1, 0.0, 1.0], [0.0, 0.0, 4.0])]
    for i in range(24):
        centre = rng.uniform(0.0, 100.0, 3)
        rotation = axis_angle(rng.normal(size=3), rng.uniform(0.0, 3.0))
        size = rng.uniform(1.0, 6.0, 3)
        if i % 4 == 0:
            shapes.append(Box(size, centre, rotation))
        elif i % 4 == 1:
            shapes.append(Sphere(size[0], centre))
        elif i % 4 == 2:
            shapes.append(Capsule(size[0], size[1], centre, rotation))
        else:
            shapes.append(TriangleMesh(*box_mesh(size), centre, rotation))
    margin = 1.5
    rows = []
    for j, shape in enumerate(shapes):
        answer = shape.signed_distance(points)
        hit = np.flatnonzero(answer.gap < margin)
        rows += [(int(i), j, answer.gap[i]) for i in hit]
    reference = sorted(rows, key=lambda r: (r[1], r[0]))
    for broad_phase in ("mask", "tree"):
        detect(points, shapes, margin, broad_phase=broad_phase)  # compile / warm caches
        start = time.perf_counter()
        contacts = detect(points, shapes, margin, broad_phase=broad_phase)
        elapsed = time.perf_counter() - start
        print(f"detect 10k points x {len(shapes)} shapes ({broad_phase}): {1e3 * elapsed:.1f} ms")
        found = np.column_stack([contacts.index_a, contacts.index_b]).tolist()
        assert found == [list(r[:2]) for r in reference]
        np.testing.assert_array_equal(contacts.gap, [r[2] for r in reference])


def test_compiled_detection_matches_the_plain_signed_distances(rng):
    """detect's compiled pass over primitives (collision_kernels.primitive_contacts) against the
    shapes' NumPy signed distances, for balls of radius r: the same contacts, gaps, normals
    and contact points; points on a box's faces, edges and centre and on a capsule's axis
    included (the ties of the closest feature). The frames against tangent_frame."""
    rotation = axis_angle([1.0, -2.0, 0.5], 0.8)
    centre = np.array([0.3, -0.2, 0.1])
    h = np.array([0.5, 0.3, 0.8])
    ties = np.array([[0.5, 0.0, 0.0], [0.5, 0.3, 0.1], [0.0, 0.0, 0.0], [0.0, 0.0, 0.2]])
    points = np.vstack([centre + rng.uniform(-2.0, 2.0, (2000, 3)), centre + ties @ rotation.T])
    shapes = [
        Plane(rotation[:, 2], centre),
        Sphere(0.7, centre),
        Box(h, centre, rotation),
        Capsule(0.4, 0.6, centre, rotation),
    ]
    margin, radius = 0.3, 0.2
    found = detect(points, shapes, margin, radius=radius)
    for j, shape in enumerate(shapes):
        answer = shape.signed_distance(points)
        hit = np.flatnonzero(answer.gap - radius < margin)
        mine = found.index_b == j
        np.testing.assert_array_equal(found.index_a[mine], hit)
        np.testing.assert_array_equal(found.gap[mine], answer.gap[hit] - radius)
        np.testing.assert_array_equal(found.normal[mine], answer.normal[hit])
        np.testing.assert_array_equal(found.point_b[mine], answer.closest[hit])
        np.testing.assert_array_equal(
            found.point_a[mine], points[hit] - radius * answer.normal[hit]
        )
    normals = np.vstack([found.normal, np.eye(3), [[0.6, 0.6, 0.0], [0.0, -0.8, 0.6]]])
    t1, t2 = tangent_frame(normals)
    frames = kernels.tangent_frames(normals)
    np.testing.assert_array_equal(frames, np.stack([normals, t1, t2], axis=1))


def test_bounds_are_the_extreme_corners_of_the_posed_local_box(rng):
    """Shape.bounds (extremes taken term by term) against the eight corners of the local box
    posed in the world, and bounding_radius against the farthest corner: equal."""
    for _ in range(20):
        rotation = axis_angle(rng.normal(size=3), rng.uniform(0.0, 3.0))
        centre = rng.normal(size=3)
        size = rng.uniform(0.5, 2.0, 3)
        for shape in (
            Box(size, centre, rotation),
            Capsule(size[0], size[1], centre, rotation),
            TriangleMesh(*box_mesh(size), centre, rotation),
        ):
            lo, hi = shape._local_box()
            corners = np.array(
                [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
            )
            world = corners @ rotation.T + centre
            np.testing.assert_allclose(shape.bounds()[0], world.min(axis=0), rtol=0, atol=1e-15)
            np.testing.assert_allclose(shape.bounds()[1], world.max(axis=0), rtol=0, atol=1e-15)
            farthest = np.linalg.norm(corners, axis=1).max()
            assert shape.bounding_radius() == pytest.approx(farthest, rel=1e-15)


# ---------------------------------------------------------------------------- contact rows


def test_contact_constraint_rows_and_jacobian(rng):
    # Points embedded in a tetrahedron, against a moving box: delta = (phi - n.u, -t.u) at
    # detection, and H is the derivative of delta (finite differences: delta is affine in x).
    mesh = box_beam(2.0, 2.0, 1.0, 2, 2, 1)
    nodes = mesh.points + np.array([-1.0, -1.0, 0.6])
    points = EmbeddedPoints(mesh, rng.uniform([0, 0, 0], [2, 2, 0.3], (20, 3)))
    obstacle = Box([2.0, 2.0, 0.5], [0.0, 0.0, 0.0], axis_angle([1.0, 0.0, 0.0], 0.1))
    obstacle.set_twist([0.1, 0.0, -0.2], [0.0, 0.3, 0.0])
    contacts = detect(points.positions(nodes), [obstacle], margin=10.0)
    dt = 0.01
    motion = dt * shape_velocities(contacts, [obstacle])
    rows = ContactConstraint(contacts, points, friction=0.4, obstacle_displacement=motion)
    delta = rows.distance(nodes).reshape(-1, 3)
    np.testing.assert_allclose(delta[:, 0], contacts.gap - np.sum(contacts.normal * motion, 1))
    np.testing.assert_allclose(delta[:, 1], -np.sum(contacts.tangent1 * motion, 1), atol=1e-15)
    jac = rows.jacobian(nodes)
    dense = np.zeros((rows.n_rows, *nodes.shape))
    for r in range(rows.n_rows):
        np.add.at(dense[r], jac.nodes[r], jac.values[r])
    step = rng.normal(size=nodes.shape)
    np.testing.assert_allclose(
        rows.distance(nodes + step) - rows.distance(nodes),
        np.einsum("rij,ij->r", dense, step),
        atol=1e-12,
    )
    assert rows.role == "contact" and rows.n_rows == 3 * len(contacts)


def test_contact_rows_in_a_deformable_statics_solve_match_a_qp(clamped_beam):
    # The integration path end to end: detect the surface nodes of a cantilever sagging under
    # gravity onto a sphere, turn them into contact rows, condense them with the stiffness
    # (W = H K^-1 H^T, delta_free = delta + H K^-1 f, linear statics) and solve. Frictionless
    # linear-elastic contact is the QP min 1/2 u^T K u - f^T u s.t. phi + n.u >= 0 at every
    # contact, solved here independently by ProxQP.
    proxsuite = pytest.importorskip("proxsuite")
    model = clamped_beam(Corotational(100.0, 0.3), gravity=(0.0, 0.0, -9810.0))
    body = model.body
    x = body.rest_positions
    obstacle = Sphere(15.0, [50.0, 10.0, -17.0])  # its top 2 mm under the beam, near the tip
    surface = np.unique(body.mesh.boundary_triangles())
    contacts = detect(x[surface], [obstacle], margin=5.0)
    rows = ContactConstraint(contacts, EmbeddedPoints.at_nodes(surface), friction=0.0)
    space = model.constraint_space(x, [rows])
    assert space.slices["contact"] == slice(0, rows.n_rows)
    stiffness = body.stiffness_matrix(body.linearise(x)).toarray()
    load = body.gather(body.gravity_forces())
    compliance_ht = np.linalg.solve(stiffness, space.jacobian_t)
    free = space.distance + space.jacobian_t.T @ np.linalg.solve(stiffness, load)
    problem = CondensedProblem(space.jacobian_t.T @ compliance_ht, free, space.slices)
    solution = solve_contact(problem, rows.friction, tolerance=1e-12, max_iterations=20000)
    displacement = np.linalg.solve(stiffness, load) + compliance_ht @ solution.forces
    normal_rows = space.jacobian_t[:, 0::3].T
    qp = proxsuite.proxqp.dense.solve(
        stiffness, -load, None, None, normal_rows, -contacts.gap, None, eps_abs=1e-12
    )
    scale = np.abs(qp.x).max()
    assert solution.contact_forces[:, 0].max() > 0.0  # the beam does rest on the sphere
    np.testing.assert_allclose(displacement, qp.x, atol=1e-7 * scale)
    print(f"beam on sphere: {len(contacts)} contacts, {solution.report.iterations} sweeps")


@pytest.mark.parametrize("mu", [5.0, 0.0])
def test_pressed_contacts_on_an_elastic_body_are_solved_exactly(clamped_beam, mu):
    # The bottom face of a cantilever pressed 0.3 mm into the floor. With ample friction every
    # contact sticks, so delta = 0 on all rows and lambda = -W^-1 delta_free exactly; without
    # friction lambda_t = 0 and the normal rows alone give lambda_n = -W_nn^-1 delta_free_n.
    # W is the elastic compliance, far from diagonal (plain Gauss-Seidel needs 947 sweeps with
    # friction); once the sweeps have found the states, the active-set solve lands on the answer.
    model = clamped_beam(Corotational(100.0, 0.3), gravity=(0.0, 0.0, -9810.0))
    body = model.body
    x = body.rest_positions
    bottom = np.flatnonzero((x[:, 2] == 0.0) & (x[:, 0] > 0.0))
    points = EmbeddedPoints.at_nodes(bottom)
    contacts = detect(x[bottom], [Plane(point=[0.0, 0.0, 0.3])], margin=1.0)
    rows = ContactConstraint(contacts, points, friction=mu)
    space = model.constraint_space(x, [rows])
    stiffness = body.stiffness_matrix(body.linearise(x)).toarray()
    compliance_ht = np.linalg.solve(stiffness, space.jacobian_t)
    load = body.gather(body.gravity_forces())
    free = space.distance + compliance_ht.T @ load
    w = space.jacobian_t.T @ compliance_ht
    solution = solve_contact(
        CondensedProblem(w, free, space.slices), rows.friction, tolerance=1e-12
    )
    exact = np.zeros_like(free)
    if mu > 0.0:
        exact = np.linalg.solve(w, -free)
    else:
        exact[0::3] = np.linalg.solve(w[0::3, 0::3], -free[0::3])
    assert exact[0::3].min() > 0.0  # all pressed (and, with friction, inside their cones)
    np.testing.assert_allclose(solution.forces, exact, rtol=1e-9, atol=1e-9 * np.abs(exact).max())
    assert solution.report.iterations < 100
    print(f"{len(contacts)} pressed contacts, mu = {mu}: {solution.report.iterations} sweeps")


# ---------------------------------------------------------------------------- rigid bodies


def incline(theta: float, mu: float, half_extents=(0.1, 0.05, 0.02)):
    """A box resting on a plane tilted by theta about y (downhill is the plane's +x)."""
    rotation = axis_angle([0.0, 1.0, 0.0], theta)
    h = np.asarray(half_extents)
    box = RigidBody(
        Box(h), 2.0, position=rotation @ [0.0, 0.0, h[2]], rotation=rotation, friction=mu
    )
    ground = KinematicBody(Plane(rotation[:, 2]), friction=mu)
    return RigidWorld([box], [ground], gravity=(0.0, 0.0, -G)), rotation


def run(world: RigidWorld, solver: RigidSolver, steps: int, check=None):
    state = world.initial_state()
    iterations = []
    for _ in range(steps):
        new = solver.step(state)
        if check is not None:
            check(state, new)
        iterations.append(solver.last_report.iterations)
        state = new
    return state, iterations


def test_block_on_a_gentle_incline_sticks():
    # tan(theta) = 0.31 < mu = 0.5: static friction holds the block.
    world, rotation = incline(0.3, 0.5)
    solver = RigidSolver(world, dt=1e-3, tolerance=1e-12)
    state, iterations = run(world, solver, 300)
    # Creep bounded by the solver tolerance per step.
    drift = np.linalg.norm(state.positions[0] - world.bodies[0].position)
    assert drift < 300 * 1e-12 * 10
    assert np.abs(state.velocities[0]).max() < 1e-9
    print(f"sticking block: Gauss-Seidel sweeps per step max {max(iterations)}")


def test_block_on_a_steep_incline_slides_at_the_coulomb_rate():
    # tan(theta) = 0.55 > mu = 0.3: a = g (sin theta - mu cos theta) down the slope. With
    # symplectic Euler v_N = a N h exactly and s_N = a h^2 N (N + 1) / 2 = a t^2 / 2 + a h t / 2.
    theta, mu, dt, steps = 0.5, 0.3, 1e-3, 300
    world, rotation = incline(theta, mu)
    solver = RigidSolver(world, dt=dt, tolerance=1e-12)
    state, iterations = run(world, solver, steps)
    a, t = G * (np.sin(theta) - mu * np.cos(theta)), steps * dt
    local = rotation.T @ (state.positions[0] - world.bodies[0].position)
    velocity = rotation.T @ state.velocities[0]
    np.testing.assert_allclose(velocity[0], a * t, rtol=1e-9)
    assert abs(local[0] - 0.5 * a * t * t) <= a * dt * t
    np.testing.assert_allclose(local[1:], 0.0, atol=1e-9)  # no lift-off, no lateral drift
    np.testing.assert_allclose(state.angular_velocities[0], 0.0, atol=1e-9)
    print(f"sliding block: Gauss-Seidel sweeps per step max {max(iterations)}")


@pytest.mark.parametrize("spin", [0.0, 2.0])
def test_dropped_sphere_comes_to_rest_without_gaining_energy(spin):
    # Inelastic impact. Without spin the sphere stops; spinning at w0 about a horizontal axis,
    # friction turns the spin into rolling and conserves the angular momentum about the contact
    # point: (2/5) m r^2 w0 = (7/5) m r^2 w, so it rolls on at v = 2/7 w0 r.
    radius = 0.05
    sphere = RigidBody(
        Sphere(radius), 0.3, position=(0.0, 0.0, 0.3), angular_velocity=(0.0, spin, 0.0)
    )
    world = RigidWorld([sphere], [Plane()])
    solver = RigidSolver(world, dt=1e-3, tolerance=1e-12)
    scale = world.energy(world.initial_state())

    def energy_never_grows(before, after):
        assert world.energy(after) <= world.energy(before) + 1e-12 * abs(scale)

    state, iterations = run(world, solver, 400, energy_never_grows)
    np.testing.assert_allclose(state.velocities[0], [2 / 7 * spin * radius, 0, 0], atol=1e-9)
    np.testing.assert_allclose(state.angular_velocities[0], [0, 2 / 7 * spin, 0], atol=1e-9)
    assert state.positions[0, 2] - radius >= -1e-12  # penetration below the solver tolerance
    print(f"dropped sphere: Gauss-Seidel sweeps per step max {max(iterations)}")


def test_sphere_rolls_down_an_incline_at_five_sevenths_g_sin_theta():
    # Rolling without slipping (mu >= 2/7 tan theta): a = 5/7 g sin theta, w = v / r.
    theta, radius, dt, steps = 0.4, 0.05, 1e-3, 300
    rotation = axis_angle([0.0, 1.0, 0.0], theta)
    ball = RigidBody(Sphere(radius), 0.2, position=rotation @ [0, 0, radius], friction=0.6)
    world = RigidWorld([ball], [KinematicBody(Plane(rotation[:, 2]), friction=0.6)])
    state, _ = run(world, RigidSolver(world, dt=dt, tolerance=1e-13), steps)
    velocity = rotation.T @ state.velocities[0]
    np.testing.assert_allclose(velocity[0], 5 / 7 * G * np.sin(theta) * steps * dt, rtol=1e-8)
    spin = rotation.T @ state.angular_velocities[0]
    np.testing.assert_allclose(spin[1], velocity[0] / radius, rtol=1e-8)


def maze(tilt: np.ndarray):
    """A 0.4 x 0.4 tray with border walls and one inner wall, tilted by `tilt`, and a ball."""
    wall = 0.01
    parts = [
        Box([0.2, 0.2, wall], [0.0, 0.0, -wall]),
        Box([wall, 0.2 + 2 * wall, 0.03], [0.2 + wall, 0.0, 0.03]),
        Box([wall, 0.2 + 2 * wall, 0.03], [-0.2 - wall, 0.0, 0.03]),
        Box([0.2, wall, 0.03], [0.0, 0.2 + wall, 0.03]),
        Box([0.2, wall, 0.03], [0.0, -0.2 - wall, 0.03]),
        Box([wall, 0.15, 0.03], [0.0, -0.05, 0.03]),  # inner wall from y = -0.2 to 0.1
    ]
    obstacles = []
    for part in parts:
        part.set_pose(tilt @ part.position, tilt)
        obstacles.append(KinematicBody(part, friction=0.3))
    ball = RigidBody(Sphere(0.02), 0.05, position=tilt @ [0.15, 0.15, 0.02], friction=0.3)
    return RigidWorld([ball], obstacles), parts


def test_ball_in_a_tilted_maze_runs_downhill_without_gaining_energy():
    # Tilted so that gravity pulls the ball towards -x and -y: it rolls diagonally into the
    # inner wall (at x = 0.01), along it, and into the corner with the lower border.
    tilt = axis_angle([1.0, -1.0, 0.0], 0.25)
    world, parts = maze(tilt)
    solver = RigidSolver(world, dt=2e-3, tolerance=1e-10)
    scale = abs(world.energy(world.initial_state()))
    penetration = []

    def check(before, after):
        assert world.energy(after) <= world.energy(before) + 1e-10 * scale
        ball = after.positions[0]
        penetration.append(min(p.signed_distance(ball[None]).gap[0] for p in parts) - 0.02)

    state, iterations = run(world, solver, 600, check)
    local = tilt.T @ state.positions[0]
    assert world.energy(state) < world.energy(world.initial_state()) - 1e-3
    assert 0.03 - 1e-6 < local[0] < 0.05 and local[1] < -0.17
    assert min(penetration) > -1e-6
    print(f"maze: Gauss-Seidel sweeps per step max {max(iterations)}, mean {np.mean(iterations)}")


def test_stacked_boxes_rest_on_each_other():
    # Body-body contacts: a box resting on a box resting on the ground stays still, and the
    # lower contacts carry both weights: sum of normal forces = (m1 + m2) g.
    lower = RigidBody(Box([0.2, 0.2, 0.05]), 2.0, position=(0.0, 0.0, 0.05))
    upper = RigidBody(Box([0.1, 0.1, 0.05]), 1.0, position=(0.03, -0.02, 0.15))
    world = RigidWorld([lower, upper], [Plane()])
    solver = RigidSolver(world, dt=1e-3, tolerance=1e-12)
    state, iterations = run(world, solver, 100)
    np.testing.assert_allclose(state.positions, world.initial_state().positions, atol=1e-12)
    contacts = solver.last_contacts
    forces = state.contacts.forces
    on_ground = contacts.index_b == 2
    # To the solver's tolerance: 1e-12 in displacement is 1e-12 m / h^2 ~ 1e-6 in force.
    np.testing.assert_allclose(forces[on_ground, 2].sum(), 3.0 * G, atol=1e-5)
    # The force on side a (the lower box) from b (the upper one) is its weight, downwards.
    np.testing.assert_allclose(forces[~on_ground, 2].sum(), -1.0 * G, atol=1e-5)
    print(f"stacked boxes: Gauss-Seidel sweeps per step max {max(iterations)}")


def test_box_on_a_moving_cart_is_carried_along():
    # A cart starting at 0.5 m/s under a resting box: friction accelerates the box at mu g
    # until it moves with the cart (v = 0.5 after t = 0.5 / (mu g) = 0.102 s).
    cart = KinematicBody(
        Box([1.0, 1.0, 0.05]), rail([0.0, 0.0, -0.05], [1.0, 0.0, 0.0], lambda t: 0.5 * t)
    )
    box = RigidBody(Box([0.05, 0.05, 0.05]), 1.0, position=(0.0, 0.0, 0.05), friction=0.5)
    world = RigidWorld([box], [cart])
    solver = RigidSolver(world, dt=1e-3, tolerance=1e-12)
    state, _ = run(world, solver, 50)
    np.testing.assert_allclose(state.velocities[0, 0], 0.5 * G * 0.05, rtol=1e-6)
    state, _ = run(world, solver, 200)
    np.testing.assert_allclose(state.velocities[0], [0.5, 0.0, 0.0], atol=1e-9)


def test_state_restores_exactly():
    tilt = axis_angle([1.0, -1.0, 0.0], 0.25)
    world, _ = maze(tilt)
    solver = RigidSolver(world, dt=2e-3)
    state = world.initial_state()
    for _ in range(60):
        state = solver.step(state)
    saved = state.copy()
    first = state
    for _ in range(40):
        first = solver.step(first)
    second = saved
    for _ in range(40):
        second = solver.step(second)
    assert first.allclose(second) and second.time == first.time


def test_kinematic_twist_and_attached_point_jacobian(rng):
    # A servo turning at 2 rad/s about z through the origin: w = 2 e_z, v of the frame origin
    # x0 = (1, 0, 0) is 2 e_z x x0, up to the chord error O(h).
    horn = KinematicBody(
        Box([0.1, 0.1, 0.1]), servo([0, 0, 0], [0, 0, 1], lambda t: 2.0 * t, [1.0, 0, 0])
    )
    v, w = horn.twist(0.0, 1e-6)
    np.testing.assert_allclose(w, [0.0, 0.0, 2.0], rtol=1e-9)
    np.testing.assert_allclose(v, [0.0, 2.0, 0.0], atol=1e-5)
    # Points fixed in a body: d p / d(v, w) = [I, -[R r]x], checked by finite differences of
    # p = x + exp(e [w]x) R r.
    local = rng.normal(size=(5, 3))
    points = AttachedPoints(local)
    rotation = axis_angle(rng.normal(size=3), 0.9)
    twist = rng.normal(size=6)
    eps = 1e-7
    moved = points.positions(eps * twist[:3], exp_map(eps * twist[3:]) @ rotation)
    numeric = (moved - points.positions(np.zeros(3), rotation)) / eps
    np.testing.assert_allclose(points.jacobian(rotation) @ twist, numeric, atol=1e-6)
    np.testing.assert_allclose(log_map(exp_map([0.0, 3.1, 0.0])), [0.0, 3.1, 0.0], atol=1e-12)


def test_contact_twist_jacobian_is_the_frames_times_the_point_jacobians(rng):
    """Rows (n, t1, t2) J(p) of contacts carried by bodies 0..2, and zero rows for contacts
    on an obstacle (body index -1 or 3): against twist_jacobian, frame by frame."""
    k, n = 9, 3
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    frames = np.stack([normals, *tangent_frame(normals)], axis=1)
    points, centres = rng.normal(size=(k, 3)), rng.normal(size=(n, 3))
    bodies = np.array([0, 2, -1, 1, 3, 0, 2, 1, -1])
    rows = contact_twist_jacobian(frames, points, bodies, centres, n).reshape(k, 3, n, 6)
    for c in range(k):
        expected = np.zeros((3, n, 6))
        if 0 <= bodies[c] < n:
            arm = points[c] - centres[bodies[c]]
            expected[:, bodies[c]] = frames[c] @ twist_jacobian(arm)[0]
        np.testing.assert_allclose(rows[c], expected, atol=1e-14)


def test_invalid_rigid_bodies_raise():
    with pytest.raises(ModelError, match="mass"):
        RigidBody(Sphere(0.1), 0.0)
    with pytest.raises(ModelError, match="positive definite"):
        RigidBody(Box([0.1, 0.1, 0.1]), 1.0, inertia=np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(ModelError, match="symmetric"):
        RigidBody(Sphere(0.1), 1.0, inertia=np.eye(3) + np.triu(np.ones((3, 3)), 1))
    with pytest.raises(ModelError, match="bounded"):
        RigidBody(Plane(), 1.0, inertia=np.eye(3))
    with pytest.raises(ContactError, match="mu"):
        RigidBody(Sphere(0.1), 1.0, friction=-0.2)
    with pytest.raises(ModelError, match="six booleans"):
        RigidBody(Sphere(0.1), 1.0, held=[True, False, False])
    with pytest.raises(ModelError, match="every motion held"):
        RigidBody(Sphere(0.1), 1.0, held=[True] * 6)
    np.testing.assert_allclose(
        box_inertia(12.0, [0.5, 1.0, 1.5]), np.diag([13.0, 10.0, 5.0]), rtol=1e-12
    )
    # A capsule of vanishing length is a sphere; a long thin one is a rod, m (2L)^2 / 12.
    np.testing.assert_allclose(capsule_inertia(3.0, 0.5, 1e-12), sphere_inertia(3.0, 0.5))
    np.testing.assert_allclose(capsule_inertia(3.0, 1e-4, 1.0)[0, 0], 3.0 * 4 / 12, rtol=1e-3)


def test_an_open_triangle_surface_keeps_points_on_their_side() -> None:
    """TriangleSurface (an open wall): the unsigned distance to its nearest face, the normal
    toward the point, on either side."""
    square = TriangleSurface(
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2], [0, 2, 3]]
    )
    query = square.signed_distance(np.array([[0.3, 0.4, 0.2], [0.3, 0.4, -0.1], [1.5, 0.5, 0.0]]))
    np.testing.assert_allclose(query.gap, [0.2, 0.1, 0.5])
    np.testing.assert_allclose(query.normal, [[0, 0, 1], [0, 0, -1], [1, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(query.closest[0], [0.3, 0.4, 0.0])
