"""Discrete Cosserat rods (pliant.fem.rod): verified against beam theory's closed forms, the
elastica solved independently, finite differences, and the invariances of the continuum."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.optimize
from conftest import ROD_E as E  # noqa: E402  (shared with tests/constraints)
from conftest import ROD_L as L  # noqa: E402
from conftest import ROD_RADIUS as RADIUS  # noqa: E402
from conftest import dead_load, straight_rod  # noqa: E402

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.effector import PositionEffector
from pliant.constraints.joint import RotationActuator
from pliant.errors import ConstraintError, DivergenceError, MaterialError, ModelError
from pliant.fem.material import Material
from pliant.fem.rigid import KinematicBody, motor, rail, servo
from pliant.fem.rod import ClampedEnd, RodBody, RodSection, parallel_frames
from pliant.geometry.collision import Box
from pliant.geometry.rotation import exp_map, log_map
from pliant.model import Model, State
from pliant.robots.common import smooth_ramp
from pliant.solvers import ImplicitEuler, StaticSolver


def helix(n: int = 24) -> RodBody:
    s = np.linspace(0.0, 3.0 * np.pi, n + 1)
    points = np.column_stack([20.0 * np.cos(s), 20.0 * np.sin(s), 8.0 * s])
    return RodBody(
        points, RodSection.rectangle(3.0, 2.0), Material(E, 0.4), density=1e-6, clamped=[0]
    )


def deformed(rod: RodBody, seed: int = 0) -> np.ndarray:
    """A state away from rest: the nodes moved and every orientation turned."""
    rng = np.random.default_rng(seed)
    q = rod.rest_positions.copy()
    n = rod.n_centreline
    q[:n] += rng.normal(scale=1.0, size=(n, 3))
    q[rod.fixed_nodes] = rod.rest_positions[rod.fixed_nodes]
    spins = rng.normal(scale=0.3, size=(n, 3))
    spins[np.isin(np.arange(n) + n, rod.fixed_nodes)] = 0.0
    return rod.advance(q, np.vstack([np.zeros((n, 3)), spins]))


# --- invariance and consistency --------------------------------------------------------------


def test_rigid_motions_give_no_force_on_a_curved_rod() -> None:
    """A helix of rectangular section (rest curvature and twist) translated and turned by a
    large rotation keeps zero strain: no force, no moment, no energy."""
    rod = helix()
    n = rod.n_centreline
    turn = exp_map(np.array([0.7, -1.9, 1.2]))  # 2.4 rad
    q = rod.rest_positions.copy()
    q[:n] = q[:n] @ turn.T + [30.0, -5.0, 12.0]
    q[n:] = np.array([log_map(turn @ f) for f in rod.frames(rod.rest_positions)])
    lin = rod.linearise(q)
    scale = E * rod.section.area  # a force of unit strain
    assert np.abs(lin.forces).max() < 1e-10 * scale
    assert abs(lin.energy) < 1e-16 * scale * L


def test_forces_are_the_gradient_of_the_energy() -> None:
    """dE along a random variation (positions and spins) = -f . variation (central
    differences, step 1e-6: error ~1e-9 relative)."""
    rod = helix()
    q = deformed(rod)
    lin = rod.linearise(q)
    rng = np.random.default_rng(1)
    for _ in range(3):
        d = rod.scatter(rng.normal(size=rod.n_free))
        eps = 1e-6
        slope = (
            rod.linearise(rod.advance(q, eps * d)).energy
            - rod.linearise(rod.advance(q, -eps * d)).energy
        ) / (2 * eps)
        assert slope == pytest.approx(-float(np.sum(lin.forces * d)), rel=1e-7)


def test_consistent_tangent_is_the_force_jacobian_and_the_default_is_exact_at_rest() -> None:
    """The consistent tangent equals the symmetric part of -df/dq by central differences over
    positions and spins (the antisymmetric part is half the nodal torques, which vanish at
    equilibrium); at rest (zero stress) it equals the default Gauss-Newton tangent."""
    rod = helix(10)
    q = deformed(rod, seed=2)
    n = rod.n_free
    jac = np.empty((n, n))
    eps = 1e-4  # forces of ~1e4: round-off eps_mach f / eps ~ 1e-8 of them, truncation alike
    for k in range(n):
        d = rod.scatter(np.eye(n)[k] * eps)
        jac[:, k] = -(
            rod.gather(rod.linearise(rod.advance(q, d)).forces)
            - rod.gather(rod.linearise(rod.advance(q, -d)).forces)
        ) / (2 * eps)
    exact = rod.stiffness_matrix(rod.linearise(q), exact=True).toarray()
    sym = 0.5 * (jac + jac.T)
    assert np.abs(exact - sym).max() < 1e-6 * np.abs(sym).max()
    rest = rod.linearise(rod.rest_positions)
    k_exact = rod.stiffness_matrix(rest, exact=True).toarray()
    k_default = rod.stiffness_matrix(rest).toarray()
    assert np.abs(k_exact - k_default).max() < 1e-8 * np.abs(k_default).max()


def test_stiffness_times_velocity_matches_the_assembled_tangent() -> None:
    rod = helix(8)
    q = deformed(rod, seed=3)
    v = rod.scatter(np.random.default_rng(4).normal(size=rod.n_free))
    lin = rod.linearise(q, v)
    expected = rod.stiffness_matrix(lin) @ rod.gather(v)
    np.testing.assert_allclose(rod.gather(lin.stiffness_velocity), expected, rtol=1e-12, atol=1e-9)


# --- statics against closed forms ------------------------------------------------------------


def test_tip_load_converges_to_timoshenko_at_second_order() -> None:
    """Small tip load P on a cantilever: w = P L^3 / (3 E I) + P L / (k G A) (Timoshenko,
    nu = 0: G = E / 2, k = 0.9). One-point elements under-predict the bending part by
    1 / (4 N^2) of it (measured: 6.25 %, 1.56 %, 0.39 %, 0.098 % for N = 2 .. 16), so the
    error falls by 4 per halving of the element length."""
    errors = []
    for n in (2, 4, 8, 16):
        rod = straight_rod(n, nu=0.0)
        inertia = rod.section.inertia[0]
        p = 1e-3 * 3 * E * inertia / L**2  # w = 1e-3 L: geometric nonlinearity ~1e-6
        model = Model(rod, actuators=[dead_load(rod, n, [0.0, 0.0, -1.0])])
        state = StaticSolver(model).step(model.rest_state(), [p])
        expected = p * L**3 / (3 * E * inertia) + p * L / (0.9 * E / 2 * rod.section.area)
        errors.append(abs(-state.positions[n, 2] - expected) / expected)
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 3.8), errors
    assert errors[-1] < 1.5e-3


def test_tip_moment_bends_the_rod_into_an_arc() -> None:
    """A torque M about -y at the tip of a cantilever along x bends it at constant curvature
    M / (E I) with no stretch (no force): each element turns by Phi = M l / (E I), so its chord
    l follows the turn exactly and the tip sits at l sin(N Phi / 2) / sin(Phi / 2) along the
    angle N Phi / 2 (a closed form of the discrete rod, met to solver precision), which
    converges at second order to the arc (R sin t, R (1 - cos t)), R = L / t. Turn t = 0.9 pi,
    loaded in nine static steps."""
    turn = 0.9 * np.pi
    gaps = []
    for n in (10, 20):
        rod = straight_rod(n)
        inertia = rod.section.inertia[0]
        model = Model(rod, actuators=[RotationActuator(rod, n, [0.0, -1.0, 0.0], mode="force")])
        solver = StaticSolver(model)
        state = model.rest_state()
        for k in range(1, 10):
            state = solver.step(state, [turn * E * inertia / L * k / 9])
        phi, l = turn / n, L / n
        chord = l * np.sin(n * phi / 2) / np.sin(phi / 2)
        discrete = chord * np.array([np.cos(n * phi / 2), 0.0, np.sin(n * phi / 2)])
        np.testing.assert_allclose(state.positions[n], discrete, atol=1e-7)
        assert state.displacement[0] == pytest.approx(turn, rel=1e-9)
        arc = L / turn * np.array([np.sin(turn), 0.0, 1.0 - np.cos(turn)])
        gaps.append(float(np.linalg.norm(state.positions[n] - arc)))
    assert gaps[0] / gaps[1] == pytest.approx(4.0, rel=0.02)


def _elastica_tip(alpha: float) -> tuple[float, float]:
    """Tip (x / L, drop / L) of an inextensible cantilever under a vertical tip load with
    alpha = P L^2 / (E I): theta'' = -alpha cos(theta) in s / L, theta(0) = 0, theta'(1) = 0,
    solved by shooting on theta'(0) (scipy: solve_ivp + brentq)."""

    def shoot(curvature0: float):
        def rhs(_, y):
            return [y[1], -alpha * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])]

        return scipy.integrate.solve_ivp(
            rhs, (0.0, 1.0), [0.0, curvature0, 0.0, 0.0], rtol=1e-12, atol=1e-12
        ).y[:, -1]

    curvature0 = scipy.optimize.brentq(lambda c: shoot(c)[1], 1e-6, alpha, xtol=1e-14)
    end = shoot(curvature0)
    return float(end[2]), float(end[3])


def test_large_tip_load_matches_the_elastica() -> None:
    """P L^2 / (E I) = 3: the tip drops to 0.60 L. The rod (slender, r = L / 100: stretch and
    shear below 1e-4) meets the elastica to within its O(1/N^2) discretisation error."""
    alpha = 3.0
    x_ref, drop_ref = _elastica_tip(alpha)
    n = 40
    rod = straight_rod(n)
    p = alpha * E * rod.section.inertia[0] / L**2
    model = Model(rod, actuators=[dead_load(rod, n, [0.0, 0.0, -1.0])])
    solver = StaticSolver(model)
    state = model.rest_state()
    for k in range(1, 7):
        state = solver.step(state, [p * k / 6])
    tip = state.positions[n] / L
    assert drop_ref > 0.5
    assert tip[0] == pytest.approx(x_ref, abs=2e-3)
    assert -tip[2] == pytest.approx(drop_ref, abs=2e-3)


def test_first_bending_frequency_converges_to_euler_bernoulli() -> None:
    """omega_1 = 1.8751^2 sqrt(E I / (rho A L^4)) for a clamped-free beam: the generalised
    eigenproblem K u = omega^2 M u of the rod at rest (lumped mass) converges to it (r / L =
    0.01: shear and rotary inertia shift it by ~1e-4)."""
    errors = []
    for n in (5, 10, 20, 40):
        rod = straight_rod(n)
        k = rod.stiffness_matrix(rod.linearise(rod.rest_positions)).toarray()
        m = np.diag(rod.mass_matvec(np.ones(rod.n_free)))
        omega = np.sqrt(scipy.linalg.eigh(k, m, eigvals_only=True, subset_by_index=[0, 0])[0])
        area, inertia = rod.section.area, rod.section.inertia[0]
        expected = 1.875104069**2 * np.sqrt(E * inertia / (rod.density * area * L**4))
        errors.append(abs(omega - expected) / expected)
    assert all(a > b for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[-1] < 2e-3


# --- dynamics ------------------------------------------------------------------------------------


def test_damped_dynamics_settle_on_the_static_equilibrium() -> None:
    rod = straight_rod(12, gravity=(0.0, 0.0, -9810.0), density=1e-7, rayleigh_mass=20.0)
    model = Model(rod)
    static = StaticSolver(model).step(model.rest_state())
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(600):
        state = solver.step(state)
    sag = static.positions[12, 2]
    assert sag < -1.0
    assert abs(state.positions[12, 2] - sag) < 1e-6 * abs(sag)
    np.testing.assert_allclose(state.positions[13:], static.positions[13:], atol=1e-8)


def test_a_rest_curvature_set_between_steps_acts_on_the_next_step() -> None:
    """The solver linearises the next step at the end of each (its look-ahead); a rest
    curvature or stretch set in between (a proxy's actuation) must not be met by that stale
    linearisation: each step equals the step of a fresh solver, which has none."""
    rod = straight_rod(8, rayleigh_mass=5.0)
    model = Model(rod)
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    for k in range(1, 6):
        rod.set_rest_curvature([0.0, 2e-3 * k, 0.0])
        rod.set_rest_stretch(1.0 - 0.01 * k)
        fresh = ImplicitEuler(model, 0.01).step(state.copy())
        state = solver.step(state)
        np.testing.assert_allclose(state.positions, fresh.positions, rtol=0, atol=1e-12)
    assert np.linalg.norm(state.positions[8, 1:]) > 1.0  # it bent
    revision = rod.revision
    rod.set_rest_curvature(rod.kappa0.copy())  # the same values: nothing to say
    assert rod.revision == revision


def test_free_vibration_never_gains_energy() -> None:
    """Released from a bent static state without damping: kinetic + elastic energy (the
    rotary part included) never grows under implicit Euler, and it decays."""
    rod = straight_rod(10)
    model = Model(rod, actuators=[dead_load(rod, 10, [0.0, 1.0, 1.0])])
    bent = StaticSolver(model).step(model.rest_state(), [2e-3])
    free = Model(rod)
    solver = ImplicitEuler(free, 0.01)
    # the bent shape, as a state of the model without the load (a state of the loaded model
    # is refused by the other one: pliant.model.Model.check_state)
    state = State(bent.positions.copy(), bent.velocities.copy())
    energies = []
    for _ in range(300):
        state = solver.step(state)
        kinetic = 0.5 * float(np.sum(rod.node_masses[:, None] * state.velocities**2))
        energies.append(kinetic + rod.linearise(state.positions).energy)
    energies = np.array(energies)
    assert np.all(np.diff(energies) <= 1e-12 * energies[0])
    assert energies[-1] < 0.7 * energies[0]  # implicit Euler's damping, ~ omega^2 h per s


def test_rod_on_an_accelerating_cart_lags_by_its_static_deflection() -> None:
    """Clamped on a cart accelerating at a along x (a ClampedEnd), the rod standing along z
    carries -m a in the cart's frame: once stiffness damping has killed the transient (it
    does not act on rigid motion), its tip lags the base by the static deflection of the
    rod under a gravity -a x, computed separately."""
    a = 500.0
    points = np.column_stack([np.zeros(11), np.zeros(11), np.linspace(0.0, 50.0, 11)])

    def rod(**kwargs):
        return RodBody(
            points,
            RodSection.circle(2.0),
            Material(300.0, 0.3),
            density=1e-6,
            clamped=[0],
            rayleigh_stiffness=0.02,
            **kwargs,
        )

    moving = rod()
    cart = KinematicBody(
        _carrier_shape(), rail([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], lambda t: 0.5 * a * t * t)
    )
    model = Model(moving, drivers=[ClampedEnd(moving, 0, cart, name="cart")])
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    lags = []
    for _ in range(250):
        state = solver.step(state)
        if state.step in (200, 250):
            lags.append(state.positions[10, 0] - 0.5 * a * state.time**2)
    still = rod(gravity=(-a, 0.0, 0.0))
    static = StaticSolver(Model(still)).step(Model(still).rest_state())
    deflection = static.positions[10, 0]
    assert deflection < -0.5
    for lag in lags:
        assert abs(lag - deflection) < 1e-4 * abs(deflection), (lag, deflection)


def _carrier_shape():
    """A shape for a kinematic carrier (any collision shape serves)."""
    return Box([2.0, 2.0, 1.0], position=[0.0, 0.0, 0.0])


def test_a_motor_turning_the_clamp_turns_the_rod_rigidly() -> None:
    """A servo turns the clamp by 90 degrees about z in a smooth 2 s ramp: once the damped
    vibrations have died out, the rod (no gravity) has followed as a rigid body, its tip at
    the turned rest position and its frames turned."""
    rod = straight_rod(8, rayleigh_stiffness=0.2)
    shaft = KinematicBody(_carrier_shape())
    quarter = np.pi / 2
    shaft.trajectory = servo(
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        lambda t: quarter * smooth_ramp(t, 0.0, 2.0),
        [0.0, 0.0, 0.0],
    )
    model = Model(rod, drivers=[ClampedEnd(rod, 0, shaft, name="motor")])
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(600):
        state = solver.step(state)
    turn = exp_map(np.array([0.0, 0.0, quarter]))
    np.testing.assert_allclose(state.positions[8], turn @ [L, 0.0, 0.0], atol=1e-3)
    frames = rod.frames(state.positions)
    rest = rod.frames(rod.rest_positions)
    np.testing.assert_allclose(frames, turn @ rest, atol=1e-4)


def test_inverse_control_of_a_tendon_driven_rod() -> None:
    """Constraints on rods work as on tetrahedra: four tendons from anchors around the clamped
    base to the tip of a vertical rod; inverse control (the QP of Eq. 2.15) brings the tip to
    a reachable goal in closed loop, tensions within their bounds."""
    from pliant.constraints.control import InverseControl

    points = np.column_stack([np.zeros(11), np.zeros(11), np.linspace(0.0, L, 11)])
    rod = RodBody(
        points,
        RodSection.circle(2.0),
        Material(20.0 * E, 0.3),  # stiff enough not to buckle under the tendons (62 mN)
        density=1e-6,
        clamped=[0],
        rayleigh_mass=10.0,
    )
    anchors = [[20.0, 0.0, 0.0], [-20.0, 0.0, 0.0], [0.0, 20.0, 0.0], [0.0, -20.0, 0.0]]
    tendons = [
        CableActuator(
            EmbeddedPoints.at_nodes([10]),
            rod.rest_positions,
            pull_point=anchor,
            name=f"tendon_{i}",
            mode="force",
            max_force=500.0,
        )
        for i, anchor in enumerate(anchors)
    ]
    tip = PositionEffector(EmbeddedPoints.at_nodes([10]), rod.rest_positions, name="tip")
    model = Model(rod, actuators=tendons, effectors=[tip])
    free = StaticSolver(model).step(model.rest_state(), [40.0, 0.0, 10.0, 0.0])
    goal = tip.position(free.positions)  # reachable: where these tensions put the tip
    assert np.linalg.norm(goal - [0.0, 0.0, L]) > 10.0
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(200):
        state = solver.step(state, InverseControl(goals=[goal]))
    assert np.linalg.norm(tip.position(state.positions) - goal) < 0.05
    assert np.all(state.actuation >= -1e-9) and np.all(state.actuation <= 500.0 + 1e-9)


# --- bad input -------------------------------------------------------------------------------


def test_bad_rods_raise() -> None:
    material = Material(E, 0.3)
    circle = RodSection.circle(1.0)
    with pytest.raises(ModelError):
        RodBody(np.zeros((1, 3)), circle, material, density=1.0)
    with pytest.raises(ModelError):
        RodBody(np.array([[0.0, 0, 0], [0, 0, 0]]), circle, material, density=1.0)
    with pytest.raises(ModelError):
        RodBody(np.array([[0.0, 0, 0], [np.nan, 0, 1]]), circle, material, density=1.0)
    with pytest.raises(ModelError):
        RodSection.circle(-1.0)
    with pytest.raises(ModelError):
        RodSection.rectangle(1.0, np.inf)
    points = np.array([[0.0, 0, 0], [0, 0, 1], [0, 0, 2]])
    with pytest.raises(MaterialError):
        RodBody(points, circle, material)  # neither density nor total mass
    with pytest.raises(MaterialError):
        RodBody(points, circle, material, density=-1.0)
    with pytest.raises(MaterialError):
        Material(E, 0.5)
    with pytest.raises(ModelError):
        RodBody(points, circle, material, density=1.0, clamped=[3])
    with pytest.raises(ModelError):
        RodBody(points, circle, material, density=1.0, frames=np.ones((3, 3, 3)))
    with pytest.raises(ModelError):
        parallel_frames(points, normal=[0.0, 0.0, 1.0])  # along the tangent
    rod = RodBody(points, circle, material, density=1.0, clamped=[0])
    with pytest.raises(ConstraintError):
        RotationActuator(rod, 5, [0.0, 0.0, 1.0])
    with pytest.raises(ConstraintError):
        RotationActuator(rod, 1, [0.0, 0.0, 0.0])
    with pytest.raises(ModelError):
        rod.interpolation([3.0])
    with pytest.raises(ModelError):
        ClampedEnd(rod, 7, KinematicBody(_carrier_shape()))
    with pytest.raises(ModelError, match="fixed nodes"):  # a clamp carries held nodes only
        Model(rod, drivers=[ClampedEnd(rod, 2, KinematicBody(_carrier_shape()))])
    with pytest.raises(ModelError):
        motor([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], np.nan, [0.0, 0.0, 0.0])


def test_a_rod_folded_onto_itself_is_reported_not_silently_inverted() -> None:
    """An element pushed through its neighbour (gamma_3 <= 0) is an inversion: the step
    raises DivergenceError instead of going on with a nonsensical state."""
    rod = straight_rod(4)
    model = Model(rod)
    state = model.rest_state()
    state.positions[4] = state.positions[3] - [10.0, 0.0, 0.0]  # last element reversed
    with pytest.raises(DivergenceError):
        ImplicitEuler(model, 0.01).step(state)


def test_cartstem_with_a_rod_stem_reaches_the_goal_behind_the_obstacle() -> None:
    """CartStemContact with a Cosserat stem (SofaGym's): the scripted slide bends the rod over
    the left obstacle and swings its tip over the right one to x = 25 mm (SofaGym's success
    threshold: 1.5 mm); the rod's surface (its nodes' balls of radius width / 2) stays out of
    the obstacles, and its motion stays in the cart's plane."""
    from pliant.robots.cartstem import cartstem_rod

    model = cartstem_rod()
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    deepest = 0.0
    for _ in range(300):
        state = solver.step(state)
        points = model.contacts.points.positions(state.positions)
        for box in model.contacts.shapes:
            gap = box.signed_distance(points).gap - model.contacts.thickness
            deepest = min(deepest, float(gap.min()))
    tip = model.effectors[0].position(state.positions)[0]
    assert abs(tip[0] - 25.0) < 1.5
    assert len(state.contact_forces.keys) > 0  # bearing on the obstacle
    assert deepest > -0.05
    assert np.abs(model.body.centreline(state.positions)[:, 1]).max() < 1e-9


def test_a_rod_resting_on_the_floor_carries_its_weight_on_its_surface() -> None:
    """A free rod of radius 2 dropped from 0.5 mm onto a plane with friction: its nodes,
    contact balls of the rod's radius, come to rest at height 2 (within the contact solver's
    tolerance) and the floor's normal forces add up to the weight."""
    from pliant.constraints.contact import Contacts
    from pliant.geometry.collision import Plane

    points = np.column_stack([np.linspace(0.0, L, 11), np.zeros(11), np.full(11, 2.5)])
    rod = RodBody(
        points,
        RodSection.circle(2.0),
        Material(E, 0.3),
        density=1e-6,
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=5.0,
    )
    contacts = Contacts(
        [Plane()],
        friction=0.5,
        margin=1.0,
        thickness=2.0,
    )
    model = Model(rod, contacts=contacts)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(200):
        state = solver.step(state)
    np.testing.assert_allclose(rod.centreline(state.positions)[:, 2], 2.0, atol=1e-4)
    weight = rod.total_mass * 9810.0
    assert state.contact_forces.forces[:, 2].sum() == pytest.approx(weight, rel=1e-5)


def test_a_dc_motor_spins_a_rod_leg_at_its_speed() -> None:
    """A leg clamped on a DC motor's shaft (`motor`: constant speed omega about z from t = 0):
    once the start-up vibrations have died out (stiffness damping, which leaves rigid motion
    alone), the leg turns with the shaft, its tip at the shaft's angle and at speed omega L.
    Implicit Euler moves the nodes along chords: the velocity is the chord's, omega h / 2
    behind the tangent, and the spinning leg stretches by O(omega h) (measured 0.42 % at
    h = 0.01, 0.21 % at 0.005): first order, as the scheme."""
    omega, stretch = 2.0, []
    for dt in (0.01, 0.005):
        rod = straight_rod(10, rayleigh_stiffness=0.2)
        shaft = KinematicBody(_carrier_shape())
        shaft.trajectory = motor([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], omega, [0.0, 0.0, 0.0])
        model = Model(rod, drivers=[ClampedEnd(rod, 0, shaft, name="motor")])
        solver = ImplicitEuler(model, dt)
        state = model.rest_state()
        for _ in range(round(3.0 / dt)):
            state = solver.step(state)
        angle = omega * state.time
        tip, velocity = state.positions[10], state.velocities[10]
        assert np.angle(np.exp(1j * (np.arctan2(tip[1], tip[0]) - angle))) == pytest.approx(
            0.0, abs=1e-4
        )
        heading = np.arctan2(velocity[1], velocity[0]) - (angle + np.pi / 2)
        assert np.angle(np.exp(1j * heading)) == pytest.approx(-omega * dt / 2, rel=0.02)
        speed = np.linalg.norm(velocity) / (omega * L)
        stretch.append(np.linalg.norm(tip) / L - 1.0)
        assert speed - 1.0 == pytest.approx(stretch[-1], abs=1e-4)
    assert 0.0 < stretch[1] < 0.6 * stretch[0] < 0.003


# --- lattices ------------------------------------------------------------------------------


def l_frame(n: int, a: float = 60.0, b: float = 40.0, **kwargs) -> RodBody:
    """Two beams welded at a right angle: n elements from the clamped origin to the corner
    (a, 0, 0), then n elements to the tip (a, b, 0); a lattice whose corner node is shared."""
    first = np.column_stack([np.linspace(0.0, a, n + 1), np.zeros(n + 1), np.zeros(n + 1)])
    second = np.column_stack([np.full(n, a), np.linspace(0.0, b, n + 1)[1:], np.zeros(n)])
    points = np.vstack([first, second])
    elements = np.column_stack([np.arange(2 * n), np.arange(1, 2 * n + 1)])
    kwargs.setdefault("density", 1e-6)
    return RodBody(
        points,
        RodSection.circle(RADIUS),
        Material(E, 0.3),
        elements=elements,
        clamped=[0],
        **kwargs,
    )


def test_a_welded_l_frame_under_an_out_of_plane_tip_load_matches_frame_theory() -> None:
    """An L of two beams welded at the corner, loaded at the tip along z: the second beam
    bends, the first bends and twists (torque P b), which turns the second: w = P a^3 / (3 E I)
    + P b^3 / (3 E I) + P a b^2 / (G J) + P (a + b) / (k G A). The lattice's corner keeps its
    right angle, so the tip meets the formula to the one-point elements' O(1/N^2) bending
    error (measured -0.67 %, -0.17 %, -0.042 % at 4, 8, 16 elements a beam); the twist, which
    only a weld carries, is 57 % of the deflection."""
    n, a, b = 16, 60.0, 40.0
    rod = l_frame(n, a, b)
    tip = 2 * n
    inertia, torsion, area = rod.section.inertia[0], rod.section.torsion, rod.section.area
    shear = E / (2 * 1.3)
    p = 1e-4 * 3 * E * inertia / (a + b) ** 2  # small: geometric nonlinearity negligible
    model = Model(rod, actuators=[dead_load(rod, tip, [0.0, 0.0, 1.0])])
    state = StaticSolver(model).step(model.rest_state(), [p])
    expected = (
        p * (a**3 + b**3) / (3 * E * inertia)
        + p * a * b**2 / (shear * torsion)
        + p * (a + b) / (0.9 * shear * area)
    )
    assert state.positions[tip, 2] == pytest.approx(expected, rel=1e-3)
    # The weld: the corner's two elements still meet at a right angle (to the load's order).
    x = state.positions[: rod.n_centreline]
    before, after = x[n] - x[n - 1], x[n + 1] - x[n]
    cosine = before @ after / np.linalg.norm(before) / np.linalg.norm(after)
    assert abs(cosine) < 1e-3


def test_a_lattice_is_at_rest_in_its_rest_state_and_under_rigid_motions() -> None:
    """A tripod of three legs meeting at a hub: no force at rest, nor after a rigid motion of
    the whole (every node moved and turned alike), at any rotation."""
    hub = np.array([0.0, 0.0, 30.0])
    feet = np.array([[30.0, 0.0, 0.0], [-15.0, 26.0, 0.0], [-15.0, -26.0, 0.0]])
    legs = [np.linspace(f, hub, 5)[:-1] for f in feet]  # 4 nodes a leg, the hub last
    points = np.vstack([*legs, hub])
    hub_index = len(points) - 1
    elements = []
    for k in range(3):
        nodes = list(range(4 * k, 4 * k + 4)) + [hub_index]
        elements += list(zip(nodes[:-1], nodes[1:], strict=True))
    rod = RodBody(
        points,
        RodSection.rectangle(3.0, 2.0),
        Material(E, 0.4),
        density=1e-6,
        elements=np.array(elements),
    )
    rest = rod.linearise(rod.rest_positions)
    assert np.abs(rest.forces).max() < 1e-9
    turn = exp_map(np.array([0.4, -1.1, 2.0]))
    n = rod.n_centreline
    moved = rod.rest_positions.copy()
    moved[:n] = points @ turn.T + [5.0, -3.0, 2.0]
    spins = np.tile(log_map(turn), (n, 1))
    moved[n:] = rod.advance(rod.rest_positions, np.vstack([np.zeros((n, 3)), spins]))[n:]
    forces = rod.linearise(moved).forces
    assert np.abs(forces).max() < 1e-8 * E * rod.section.area
    skin_points, triangles = rod.skin(moved)
    assert triangles.max() < len(skin_points)
    assert len(triangles) == len(rod.elements) * 2 * len(rod.section.outline)


def test_bad_lattices_raise() -> None:
    points = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]])
    section, material = RodSection.circle(1.0), Material(E, 0.3)
    for elements, message in (
        ([[0, 1], [1, 1]], "joins a node to itself"),
        ([[0, 1], [1, 0]], "same two nodes twice"),
        ([[0, 1]], "belong to no element"),
        ([[0, 3], [1, 2]], "must join nodes"),
        ([[0.0, 1.0], [1.0, 2.0]], "node indices"),
    ):
        with pytest.raises(ModelError, match=message):
            RodBody(points, section, material, density=1e-6, elements=np.array(elements))
    lattice = RodBody(points, section, material, density=1e-6, elements=np.array([[0, 1], [1, 2]]))
    with pytest.raises(ModelError, match="polyline"):
        lattice.interpolation([1.0])


def test_a_tripod_lattice_settles_on_its_static_equilibrium_under_gravity() -> None:
    """Three legs clamped at their feet carry a hub under gravity: damped dynamics settle
    where the static solver balances the lattice's weight."""
    hub = np.array([0.0, 0.0, 30.0])
    feet = np.array([[30.0, 0.0, 0.0], [-15.0, 26.0, 0.0], [-15.0, -26.0, 0.0]])
    points = np.vstack([*[np.linspace(f, hub, 5)[:-1] for f in feet], hub])
    elements = []
    for k in range(3):
        nodes = [*range(4 * k, 4 * k + 4), 12]
        elements += list(zip(nodes[:-1], nodes[1:], strict=True))
    rod = RodBody(
        points,
        RodSection.circle(1.5),
        Material(300.0, 0.4),
        density=2e-6,
        elements=np.array(elements),
        clamped=[0, 4, 8],
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=20.0,
    )
    model = Model(rod)
    static = StaticSolver(model).step(model.rest_state())
    sag = 30.0 - static.positions[12, 2]
    assert sag > 1e-3
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    for _ in range(300):
        state = solver.step(state)
    assert np.abs(state.positions[:13] - static.positions[:13]).max() < 1e-3 * sag


def test_rod_sections_loads_point_masses_and_held_dofs_are_checked() -> None:
    """The rod's SOFA-reading options refuse what they cannot mean, naming it."""
    points = np.column_stack([np.linspace(0.0, 10.0, 4), np.zeros(4), np.zeros(4)])
    args = (points, RodSection.circle(0.5), Material(1e5, 0.3))
    with pytest.raises(ModelError, match="one section number per element"):
        RodBody(*args, density=1e-6, sections=[0, 0])
    with pytest.raises(ModelError, match="point mass"):
        RodBody(*args, density=1e-6, point_masses=[(7, 1.0, 0.0)])
    with pytest.raises(ModelError, match="held DoFs"):
        RodBody(*args, density=1e-6, held_dofs=[24])
    rod = RodBody(
        *args, density=1e-6, sections=[0, 0, 1], point_masses=[(3, 2.0, 0.5)], held_dofs=[0]
    )
    assert rod.node_masses[3] > 2.0 and rod.node_masses[7] > 0.5
    assert rod.free_dofs[0] == 1 and len(rod.loads) == 1  # the tie of elements 0 and 1
