"""Beam-skeleton proxies (pliant.proxy): rest curvature as actuation against the arc's closed
form and the rod's verified statics, the two robots' skeletons, skinning's invariances, and
calibration recovering a proxy's own parameters."""

from __future__ import annotations

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.errors import ModelError
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection
from pliant.geometry.rotation import exp_map, log_map
from pliant.mesh.multigait import CHAMBERS
from pliant.model import Model
from pliant.proxy import Bending, CurvatureActuation, Skinning, multigait_proxy, trunk_proxy
from pliant.proxy.calibrate import (
    calibrate,
    command_sequence,
    rollout,
    split,
    travel,
    travel_error,
)
from pliant.solvers import ImplicitEuler, StaticSolver

L, E, RADIUS = 100.0, 1000.0, 1.0  # mm, kPa, mm


def cantilever(n: int) -> RodBody:
    """n elements along +x, clamped at the origin; d1 = y, d2 = z."""
    points = np.column_stack([np.linspace(0.0, L, n + 1), np.zeros(n + 1), np.zeros(n + 1)])
    return RodBody(
        points,
        RodSection.circle(RADIUS),
        Material(E, 0.0),
        density=1e-6,
        clamped=[0],
        normal=(0.0, 1.0, 0.0),
    )


def tip_load(rod: RodBody, direction) -> CableActuator:
    """A dead load on the tip in force mode (a cable pulled from 1e6 mm away)."""
    x, tip = rod.rest_positions, rod.n_centreline - 1
    return CableActuator(
        EmbeddedPoints.at_nodes([tip]),
        x,
        pull_point=x[tip] + 1e6 * np.asarray(direction, dtype=float),
        mode="force",
        name="load",
    )


def bent_cantilever(n: int, turn: float, stretch: float = 0.0):
    """A cantilever of n elements under a rest curvature turn / L about d1 (and a rest stretch
    1 + stretch) ramped in nine static steps: the rod, its bending, the static solver, the
    bent state and the discrete rod's closed-form tip without stretch: each element turns by
    Phi = turn / n with its chord l, so the tip sits at l sin(N Phi / 2) / sin(Phi / 2) along
    the angle N Phi / 2."""
    rod = cantilever(n)
    bending = CurvatureActuation(
        rod, [Bending("all", tuple(range(n)), (1, 0, 0), turn / L, max_stretch=stretch)]
    )
    model = Model(rod)
    solver, state = StaticSolver(model), model.rest_state()
    for k in range(1, 10):
        bending.apply([k / 9])
        state = solver.step(state)
    phi, l = turn / n, L / n
    chord = l * np.sin(n * phi / 2) / np.sin(phi / 2)
    discrete = chord * np.array([np.cos(n * phi / 2), 0.0, -np.sin(n * phi / 2)])
    return rod, bending, solver, state, discrete


def released(bending: CurvatureActuation, solver, state):
    """The state after ramping `bending` back to 0 in nine static steps."""
    for k in range(8, -1, -1):
        bending.apply([k / 9])
        state = solver.step(state)
    return state


def test_a_prescribed_rest_curvature_bends_an_unloaded_rod_into_the_arc() -> None:
    """Rest curvature kappa about d1 = y on every element, no load: the tip sits at the
    discrete rod's closed form (:func:`bent_cantilever`, met to solver precision), which
    converges at second order to the arc of radius 1 / kappa: (R sin t, -R (1 - cos t)),
    t = kappa L (turning x towards -z about +y). Turn 0.9 pi, ramped in nine static steps."""
    turn = 0.9 * np.pi
    kappa = turn / L
    gaps = []
    for n in (10, 20):
        rod, bending, solver, state, discrete = bent_cantilever(n, turn)
        np.testing.assert_allclose(state.positions[n], discrete, atol=1e-7)
        radius = 1.0 / kappa
        arc = radius * np.array([np.sin(turn), 0.0, -(1.0 - np.cos(turn))])
        gaps.append(float(np.linalg.norm(state.positions[n] - arc)))
    assert gaps[0] / gaps[1] == pytest.approx(4.0, rel=0.02)
    state = released(bending, solver, state)  # back to the natural curvature: straight
    np.testing.assert_allclose(state.positions[: n + 1], rod.rest_positions[: n + 1], atol=1e-7)


def test_a_bending_that_stretches_takes_the_arc_scaled_by_its_stretch() -> None:
    """Rest curvature kappa and rest stretch 1 + s together (Bending.max_stretch), no load:
    each element keeps its turn Phi = kappa l and lengthens by 1 + s, so the tip is the
    discrete arc's (previous test) times 1 + s, to solver precision; the elements' stretch
    gamma_3 is 1 + s; released, the rod is straight and of its length again. A stretch of 1
    or more and a non-positive rest stretch are refused."""
    n, s = 10, 0.2
    rod, bending, solver, state, discrete = bent_cantilever(n, 0.6 * np.pi, stretch=s)
    np.testing.assert_allclose(state.positions[n], (1.0 + s) * discrete, atol=1e-7)
    np.testing.assert_allclose(rod.linearise(state.positions).dets, 1.0 + s, atol=1e-9)
    state = released(bending, solver, state)
    np.testing.assert_allclose(state.positions[: n + 1], rod.rest_positions[: n + 1], atol=1e-7)
    with pytest.raises(ModelError, match="max stretch"):
        CurvatureActuation(rod, [Bending("all", (0,), (1, 0, 0), 0.01, max_stretch=1.0)])
    with pytest.raises(ModelError, match="rest stretch"):
        rod.set_rest_stretch(0.0)


def test_a_contracting_bending_shortens_its_beam_whichever_way_it_bends() -> None:
    """Bending.max_contraction c (a cable-bent trunk shortens as it curls, either way): at
    command +1 or -1 each element keeps its turn and shortens by 1 - c, so the tip is the
    discrete arc's (bent_cantilever) times 1 - c, mirrored for -1, to solver precision;
    released, the rod is straight and of its length again. A contraction outside [0, 1) is
    refused."""
    n, c, turn = 10, 0.08, 0.6 * np.pi
    _, _, _, _, discrete = bent_cantilever(n, turn)
    rod = cantilever(n)
    bending = CurvatureActuation(
        rod, [Bending("all", tuple(range(n)), (1, 0, 0), turn / L, max_contraction=c)]
    )
    model = Model(rod)
    solver = StaticSolver(model)
    for sign in (1.0, -1.0):
        state = model.rest_state()
        for k in range(1, 10):
            bending.apply([sign * k / 9])
            state = solver.step(state)
        mirrored = discrete * np.array([1.0, 1.0, sign])
        np.testing.assert_allclose(state.positions[n], (1.0 - c) * mirrored, atol=1e-7)
        np.testing.assert_allclose(rod.linearise(state.positions).dets, 1.0 - c, atol=1e-9)
        for k in range(8, -1, -1):
            bending.apply([sign * k / 9])
            state = solver.step(state)
        np.testing.assert_allclose(state.positions[: n + 1], rod.rest_positions[: n + 1], atol=1e-7)
    trunk = trunk_proxy(lower_contraction=0.1, upper_contraction=0.2)
    assert [b.max_contraction for b in trunk.actuation.bendings] == [0.1, 0.1, 0.2, 0.2]
    for bad in (-0.1, 1.0):
        with pytest.raises(ModelError, match="max contraction"):
            CurvatureActuation(rod, [Bending("all", (0,), (1, 0, 0), 0.01, max_contraction=bad)])


def test_rest_curvature_and_a_small_tip_load_superpose() -> None:
    """Small rest curvature (tip rise 1e-3 L) and a small tip load along z (Timoshenko
    deflection w = P L^3 / (3 E I) + P L / (k G A), met by the rod to its O(1/N^2) bending
    error, tests/fem/test_rod.py): the tip under both is the sum of the tip under each, to the
    geometric nonlinearity's order (1e-3 of either)."""
    n = 16
    rod = cantilever(n)
    inertia = rod.section.inertia[0]
    p = 1e-3 * 3 * E * inertia / L**2
    kappa = 2e-3 / L  # rise kappa L^2 / 2 = 1e-3 L, about -d1 = -y: towards +z
    bending = CurvatureActuation(rod, [Bending("all", tuple(range(n)), (-1, 0, 0), kappa)])
    model = Model(rod, actuators=[tip_load(rod, [0.0, 0.0, 1.0])])
    solver = StaticSolver(model)

    def tip(u: float, load: float) -> np.ndarray:
        bending.apply([u])
        return solver.step(model.rest_state(), [load]).positions[n] - rod.rest_positions[n]

    both, arc, loaded = tip(1.0, p), tip(1.0, 0.0), tip(0.0, p)
    assert arc[2] == pytest.approx(kappa * L**2 / 2, rel=2e-3)
    timoshenko = p * L**3 / (3 * E * inertia) + p * L / (0.9 * E / 2 * rod.section.area)
    assert loaded[2] == pytest.approx(timoshenko, rel=1.5e-3)
    np.testing.assert_allclose(both, arc + loaded, atol=2e-3 * loaded[2])


def test_per_element_stiffness_and_density_of_a_rod() -> None:
    """Two halves of a cantilever, the outer one 4 times stiffer: a tip moment M bends each
    half at M / (E_k I), so the tip turns by M (L / 2) (1 / E + 1 / (4 E)) / I; the mass is
    the sum of the halves' densities times their volumes."""
    n = 10
    base = cantilever(n)
    points = base.rest_positions[: n + 1]
    moduli = np.where(np.arange(n) < n // 2, E, 4 * E)
    densities = np.where(np.arange(n) < n // 2, 1e-6, 3e-6)
    rod = RodBody(
        points,
        RodSection.circle(RADIUS),
        Material(E, 0.0),
        clamped=[0],
        normal=(0.0, 1.0, 0.0),
        young_moduli=moduli,
        densities=densities,
    )
    area = rod.section.area
    assert rod.total_mass == pytest.approx(area * L / 2 * 4e-6)
    assert rod.node_masses[: n + 1].sum() == pytest.approx(rod.total_mass)
    # Curvature as actuation in the stiff half only: the other stays straight.
    CurvatureActuation(rod, [Bending("outer", tuple(range(n // 2, n)), (1, 0, 0), 0.01)]).apply(
        [1.0]
    )
    state = StaticSolver(Model(rod)).step(Model(rod).rest_state())
    np.testing.assert_allclose(state.positions[: n // 2 + 1], points[: n // 2 + 1], atol=1e-9)
    with pytest.raises(ModelError, match="must lie in"):
        CurvatureActuation(rod, [Bending("bad", (n,), (1, 0, 0), 0.01)])


def test_the_multigait_proxy_has_19_nodes_and_curls_its_legs_on_the_floor() -> None:
    proxy = multigait_proxy()
    assert proxy.rod.n_centreline == 19
    assert proxy.actuation.names == list(CHAMBERS)  # one bending a chamber, the FEM's order
    solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
    proxy.apply([0.0, 1.0, 1.0, 0.0, 0.0])
    for _ in range(60):
        state = solver.step(state)
    x = proxy.skeleton(state.positions)
    # An inflated leg arches, ends down (its middle rises by over 3 mm), and draws its tip in;
    # the deflated ones stay flat on the floor; nothing goes through it.
    tips, middles = [6, 10], [4, 5, 8, 9]
    assert np.all(x[middles, 2] > 3.15 + 3.0)
    assert np.all(x[tips, 0] > 0.3)
    np.testing.assert_allclose(x[11:, 2], 3.15, atol=0.5)  # the roots lift by 0.22 mm
    assert x[:, 2].min() > 3.15 - 0.1


def test_the_multigait_proxys_cross_beams_take_their_own_stiffness() -> None:
    """`cross_stiffness`: the four cross beams' Young's modulus, by default the centre's (given
    the centre's, the proxy moves as the default one to the last bit), carried in the proxy's
    parameters; stiffer corners hold the centre higher when every chamber is on."""
    default = multigait_proxy()
    same = multigait_proxy(cross_stiffness=default.parameters["centre_stiffness"])
    stiff = multigait_proxy(cross_stiffness=10000.0)
    assert stiff.parameters["cross_stiffness"] == 10000.0
    assert "cross_stiffness" not in default.parameters
    shapes = []
    for proxy in (default, same, stiff):
        solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
        proxy.apply([1.0] * 5)
        for _ in range(60):
            state = solver.step(state)
        shapes.append(proxy.skeleton(state.positions))
    np.testing.assert_array_equal(shapes[1], shapes[0])
    assert shapes[2][1, 2] > shapes[0][1, 2] + 1.0  # the centre's middle node


def test_the_trunk_proxy_bends_both_ways_and_translates_its_base() -> None:
    proxy = trunk_proxy(cube_position=None)
    assert proxy.rod.n_centreline == 30 and proxy.n_controls == 5
    solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
    for k in range(50):  # ramped over 10 steps, the base by 2 mm a step
        ramp = min(k + 1, 10) / 10
        proxy.apply([-ramp, 0.0, -ramp, 0.0, -20.0 * ramp])
        state = solver.step(state)
    x = proxy.skeleton(state.positions)
    assert x[0, 2] == pytest.approx(-20.0)
    assert x[-1, 1] > 25.0  # bent about -d1 = -x: the tip rose along y


def test_skinning_is_the_fem_surface_at_rest_and_moves_rigidly_with_the_skeleton() -> None:
    from pliant.mesh import multigait as geometry

    proxy = multigait_proxy()
    mesh = geometry.multigait(mesh_size=12.0)
    surface = mesh.points[np.unique(mesh.boundary_triangles())]
    skin = Skinning(proxy.rod, surface, neighbours=3)
    rest = proxy.rod.rest_positions
    np.testing.assert_allclose(skin.positions(rest), surface, atol=1e-9)
    turn = exp_map(np.array([0.3, -0.7, 1.2]))
    shift = np.array([4.0, -2.0, 7.0])
    n = proxy.rod.n_centreline
    moved = proxy.rod.advance(rest, np.vstack([np.zeros((n, 3)), np.tile(log_map(turn), (n, 1))]))
    moved[:n] = rest[:n] @ turn.T + shift
    np.testing.assert_allclose(skin.positions(moved), surface @ turn.T + shift, atol=1e-9)


def test_a_skinned_points_rows_are_its_first_variation() -> None:
    """The rows of a skinned point (translations and spins of its carrying nodes) against
    finite differences of its skinned position along a random rod increment, in a bent
    state; the first-order displacement is the same product."""
    proxy = multigait_proxy()
    rod = proxy.rod
    surface = np.array([[5.0, 29.0, 0.0], [68.0, 0.0, 0.0], [130.0, -25.0, 6.3]])
    skin = Skinning(rod, surface, neighbours=2)
    rng = np.random.default_rng(3)
    n = rod.n_nodes
    x = rod.advance(rod.rest_positions, 0.2 * rng.standard_normal((n, 3)))
    dq = rng.standard_normal((n, 3))
    eps = 1e-6
    slope = skin.positions(rod.advance(x, eps * dq)) - skin.positions(rod.advance(x, -eps * dq))
    slope /= 2 * eps
    directions = rng.standard_normal((3, 2, 3))
    rows = skin.rows(x, np.arange(3), directions)
    product = np.einsum("rkj,rkj->r", rows.values, dq[rows.nodes])
    expected = np.einsum("krj,kj->kr", directions, slope).ravel()
    np.testing.assert_allclose(product, expected, rtol=1e-6)
    np.testing.assert_allclose(skin.displacement(x, dq), slope, rtol=1e-6)


def test_the_multigait_proxy_touches_the_floor_through_the_fem_surface() -> None:
    """contact="surface": the FEM's 45 colliding points and 45 of its top face skinned onto
    the skeleton. At rest the skeleton lies at mid-thickness as with node balls; with the
    front legs curled, no skinned point goes through the floor and the tips rest on their
    tip's edge (with the default, uncalibrated curvature, a leg curls past the vertical and
    rests on the edge of its top face)."""
    proxy = multigait_proxy(contact="surface")
    points = proxy.model.contacts.points
    assert len(points) == 90 and not points.linear
    solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
    for _ in range(20):
        state = solver.step(state)
    np.testing.assert_allclose(proxy.skeleton(state.positions)[:, 2], 3.15, atol=0.02)
    proxy.apply([0.0, 1.0, 1.0, 0.0, 0.0])
    for _ in range(60):
        state = solver.step(state)
    skin = points.positions(state.positions)
    assert skin[:, 2].min() > -0.05
    x = proxy.skeleton(state.positions)
    assert np.all(x[[4, 5, 8, 9], 2] > 3.15 + 3.0)  # the front legs arch
    tips = np.linalg.norm(skin[:, None, :] - x[None, [6, 10]], axis=2).min(axis=1) < 10.0
    assert np.sum(tips & (skin[:, 2] < 0.05)) >= 2  # both tips touch by skinned points
    with pytest.raises(ModelError, match="contact must be"):
        multigait_proxy(contact="balls")


def test_every_fifth_position_is_an_optimisation_position() -> None:
    optimisation, validation = split(12)
    assert optimisation.tolist() == [0, 5, 10]
    assert sorted([*optimisation, *validation]) == list(range(12))


def test_calibration_recovers_a_proxys_own_parameters(tmp_path) -> None:
    """Synthetic data: a 9-node Trunk proxy (no floor in reach, no cube) follows the
    thesis' calibration actions (held 15 steps of 0.02 s each, then rest) with known max
    curvatures of both beams and the lower beam's stiffness (which its sag under gravity
    reveals); TPE searching a box of +-25 % around them finds the curvatures within 3 % and
    the stiffness within 5 % in 40 trials (measured with the sampler seeded per trial for an
    exact resume, issue 64: stiffness 4.3 % off; with the sampler seeded once, before: 1.5 %,
    1.1 %, 2.1 %, matched points 0.64 mm off on average, out of a trunk 195 mm long). The
    study stored in SQLite resumes: a second call adds the missing trials."""
    truth = {"lower_curvature": 0.01, "upper_curvature": 0.03, "lower_stiffness": 3000.0}
    commands = command_sequence(
        [[0, -1, 0, 0, 0], [0, 0, 0, -0.5, 0], [0, 1, 0, -1, 0], [0, 0, 0, 0, 0]], 15
    )

    def simulate(parameters: dict[str, float]) -> np.ndarray:
        proxy = trunk_proxy(nodes=9, cube_position=None, floor_height=-1000.0, **parameters)
        return rollout(proxy, commands, lambda s: proxy.skeleton(s.positions), dt=0.02)

    reference = simulate(truth)
    space = {name: (0.75 * value, 1.25 * value) for name, value in truth.items()}
    storage = f"sqlite:///{tmp_path / 'calibration.db'}"
    first = calibrate(simulate, reference, space, trials=20, storage=storage, safety=0.9)
    assert first.trials == 20
    result = calibrate(simulate, reference, space, trials=40, storage=storage, safety=0.9)
    assert result.trials == 40
    assert result.optimisation_error <= first.optimisation_error
    for name, value in truth.items():
        rel = 0.05 if name.endswith("stiffness") else 0.03
        assert result.parameters[name] == pytest.approx(value, rel=rel), name
    assert result.optimisation_error < 1.0 and result.validation_error < 1.0
    used = result.proxy_parameters
    assert used["upper_curvature"] == pytest.approx(0.9 * result.parameters["upper_curvature"])
    assert used["lower_stiffness"] == result.parameters["lower_stiffness"]


def test_a_mass_constraint_holds_a_parameter_the_positions_do_not_see() -> None:
    """Synthetic: the points follow a stiffness-like parameter `a` and ignore `density` (as
    positions barely see a proxy's mass); mass = 10 density. Unconstrained, TPE leaves the
    density wherever it fell; held within 5 % of a 25 g target the best trial's mass is
    there, `a` is still found, only feasible trials were simulated, and a target no box
    value reaches is a ModelError."""
    reference = np.linspace(0.0, 1.0, 30)[:, None, None] * np.ones((30, 2, 3))
    calls = []

    def simulate(parameters: dict[str, float]) -> np.ndarray:
        calls.append(parameters)
        return reference * parameters["a"] / 1.3

    space = {"a": (1.0, 2.0), "density": (1.0, 4.0)}

    def mass(parameters: dict[str, float]) -> float:
        return 10.0 * parameters["density"]

    result = calibrate(
        simulate, reference, space, trials=40, mass=mass, target_mass=25.0, mass_tolerance=0.05
    )
    assert abs(result.mass / 25.0 - 1.0) <= 0.05
    assert result.mass == pytest.approx(mass(result.parameters))
    assert result.parameters["a"] == pytest.approx(1.3, rel=0.05)
    assert len(calls) == result.feasible_trials < result.trials == 40
    with pytest.raises(ModelError, match="within 5%"):
        calibrate(simulate, reference, space, trials=5, mass=mass, target_mass=100.0,
                  mass_tolerance=0.05)  # fmt: skip
    with pytest.raises(ModelError, match="mass function"):
        calibrate(simulate, reference, space, trials=5, target_mass=25.0, mass_tolerance=0.05)


def test_travel_is_the_centroids_move_over_each_interval() -> None:
    """travel(points, n): the centroid's displacement over the floor (x, y) from the end of
    one interval of n steps to the end of the next (the first from the first position), a
    last incomplete interval left out, its height not counted; travel_error the mean
    distance between two such sequences."""
    t = np.arange(23, dtype=float)
    points = np.zeros((23, 4, 3))
    points[:, :, 0] = 2.0 * t[:, None]  # 2 mm a step along x
    points[:, :2, 1] = 1.0  # a shape: the centroid's y is 0.5
    points[:, 0, 2] = np.sin(t)  # a leg lifting: not travel
    moves = travel(points, 5)
    np.testing.assert_allclose(moves, [[8.0, 0], [10.0, 0], [10.0, 0], [10.0, 0]], atol=1e-12)
    slower = points.copy()
    slower[:, :, 0] *= 0.5
    assert travel_error(points, slower, 5) == pytest.approx(np.mean([4.0, 5.0, 5.0, 5.0]))
    for interval in (0, 24):
        with pytest.raises(ModelError, match="does not fit"):
            travel(points, interval)


def test_a_travel_term_joins_the_loss_and_is_reported() -> None:
    """Synthetic: points of a fixed shape scaled by `a`, drifting `c` mm a step. With a travel
    term over 10-step intervals both are found (5 %) in 80 trials; the loss minimised is the
    point error plus the weight times the travel error, each reported, the travel error the
    best parameters' own; bad travel settings are ModelErrors before any trial."""
    shape = np.array([[0.0, 1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, 0.0, 0.0]])
    steps = np.arange(40, dtype=float)[:, None, None]

    def simulate(parameters: dict[str, float]) -> np.ndarray:
        drift = parameters["c"] * steps * np.array([1.0, 0.0, 0.0])
        return parameters["a"] * shape[None] * (1.0 + 0.1 * np.sin(steps)) + drift

    reference = simulate({"a": 1.3, "c": 0.2})
    space = {"a": (1.0, 2.0), "c": (0.0, 0.4)}
    result = calibrate(simulate, reference, space, trials=80, travel_weight=2.0,
                       travel_interval=10)  # fmt: skip
    assert result.parameters["a"] == pytest.approx(1.3, rel=0.05)
    assert result.parameters["c"] == pytest.approx(0.2, rel=0.05)
    assert result.travel_error == pytest.approx(
        travel_error(reference, simulate(result.parameters), 10)
    )
    assert result.loss == pytest.approx(result.optimisation_error + 2.0 * result.travel_error)
    # started from the truth (a name outside the box ignored): the first trial is exact
    truth = {"a": 1.3, "c": 0.2, "other": 0.0}
    plain = calibrate(simulate, reference, space, trials=3, start=truth)
    assert plain.travel_error is None and plain.loss == pytest.approx(plain.optimisation_error)
    assert plain.parameters == {"a": 1.3, "c": 0.2} and plain.optimisation_error < 1e-12
    with pytest.raises(ModelError, match="outside the search box"):
        calibrate(simulate, reference, space, trials=1, start={"c": 0.5})
    with pytest.raises(ModelError, match="interval"):
        calibrate(simulate, reference, space, trials=1, travel_weight=1.0)
    with pytest.raises(ModelError, match="does not fit"):
        calibrate(simulate, reference, space, trials=1, travel_weight=1.0, travel_interval=50)
    with pytest.raises(ModelError, match="travel weight"):
        calibrate(simulate, reference, space, trials=1, travel_weight=-1.0, travel_interval=5)


def test_the_calibrate_command_fits_a_saved_reference_and_resumes(tmp_path) -> None:
    """`pliant proxy calibrate multigait --reference REF`: a short reference (the default
    proxy's own skinned underside corners, 20 steps of the rear legs bending) and 3 trials;
    the report holds the errors and the safety-scaled curvatures; a second call with more
    trials resumes the SQLite study."""
    import json

    from typer.testing import CliRunner

    from pliant.cli import app
    from pliant.proxy.references import Reference, setup

    surface = np.array([[0.0, 29.0, 0.0], [136.0, -29.0, 0.0], [68.0, 0.0, 0.0]])
    commands = np.tile([0.0, 0.0, 0.0, 1.0, 1.0], (20, 1))
    draft = Reference(commands, np.zeros((20, 3, 3)), surface, 0.01)
    points = setup("multigait").simulate(draft)(dict(multigait_proxy().parameters))
    Reference(commands, points, surface, 0.01).save(tmp_path / "reference.npz")
    runner = CliRunner()
    args = ["proxy", "calibrate", "multigait", "--reference", str(tmp_path / "reference.npz")]
    for trials in (2, 3):
        result = runner.invoke(app, [*args, "--trials", str(trials), "--out", str(tmp_path)])
        assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["trials"] == 3
    assert np.isfinite(report["optimisation_error_mm"]) and np.isfinite(
        report["validation_error_mm"]
    )
    for name in ("leg_curvature", "centre_curvature"):
        assert report["proxy_parameters"][name] == pytest.approx(0.9 * report["parameters"][name])
    # A mass constraint needs the FEM's mass in the reference; with it, the report's proxy
    # is within the tolerance (a study of its own).
    constrained = [*args, "--trials", "10", "--mass-tolerance", "0.5", "--out", str(tmp_path)]
    result = runner.invoke(app, constrained)
    assert result.exit_code == 2 and "no FEM mass" in result.output
    fem_mass = multigait_proxy().rod.total_mass
    Reference(commands, points, surface, 0.01, fem_mass).save(tmp_path / "reference.npz")
    result = runner.invoke(app, constrained)
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["trials"] == 10 and report["mass_tolerance"] == 0.5
    assert abs(report["proxy_mass_kg"] / fem_mass - 1.0) <= 0.5


def test_the_calibrate_command_fits_the_travel_and_the_friction(tmp_path) -> None:
    """`--travel-weight W --friction LOW,HIGH --start REPORT`: a study of its own
    (multigait-travel1-friction; `--contact surface` another, multigait-surface;
    `--travel-actions 2` another, its travel one move over both actions; `--neutral
    underside` another, the beams bent about their underside), the
    friction searched in its box from the report's value, and the report's travel block the
    FEM's and the proxy's centroid moves over each 0.6 s action (2 in a 1.2 s reference) with
    their mean distance; a robot without actions or without a fitted friction refuses them,
    as a start that is no report and an unknown contact (exit 2)."""
    import json

    import optuna
    from typer.testing import CliRunner

    from pliant.cli import app
    from pliant.proxy.references import Reference, setup

    surface = np.array([[0.0, 29.0, 0.0], [136.0, -29.0, 0.0], [68.0, 0.0, 0.0]])
    commands = np.repeat([[0.0, 0.0, 0.0, 1.0, 1.0], [0.0, 1.0, 1.0, 1.0, 1.0]], 60, axis=0)
    draft = Reference(commands, np.zeros((120, 3, 3)), surface, 0.01)
    points = setup("multigait").simulate(draft)(dict(multigait_proxy().parameters))
    Reference(commands, points, surface, 0.01).save(tmp_path / "reference.npz")
    runner = CliRunner()
    args = ["proxy", "calibrate", "multigait", "--reference", str(tmp_path / "reference.npz")]
    (tmp_path / "start.json").write_text(json.dumps({"parameters": {"friction": 0.6}}))
    options = ["--travel-weight", "1", "--friction", "0.5,0.9", "--trials", "2"]
    options += ["--start", str(tmp_path / "start.json")]
    result = runner.invoke(app, [*args, *options, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["study"] == "multigait-travel1-friction"
    assert 0.5 <= report["parameters"]["friction"] <= 0.9
    study = optuna.load_study(
        study_name="multigait-travel1-friction", storage=f"sqlite:///{tmp_path / 'multigait.db'}"
    )
    assert study.trials[0].params["friction"] == 0.6  # the start's
    surface = ["--contact", "surface", "--trials", "1", "--out", str(tmp_path)]
    result = runner.invoke(app, [*args, *surface])
    assert result.exit_code == 0, result.output
    skinned = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert skinned["study"] == "multigait-surface" and skinned["contact"] == "surface"
    moves = report["travel"]
    assert moves["interval_steps"] == 60 and len(moves["fem_mm"]) == len(moves["proxy_mm"]) == 2
    distance = np.linalg.norm(np.subtract(moves["fem_mm"], moves["proxy_mm"]), axis=1).mean()
    assert moves["error_mm"] == pytest.approx(distance, abs=1e-2)
    assert moves["loss"] == pytest.approx(report["optimisation_error_mm"] + moves["error_mm"])
    cycle = ["--travel-weight", "1", "--travel-actions", "2", "--trials", "1"]
    result = runner.invoke(app, [*args, *cycle, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["study"] == "multigait-travel1x2"
    moves = report["travel"]  # one move over both actions
    assert moves["interval_steps"] == 120 and moves["actions"] == 2 and len(moves["fem_mm"]) == 1
    result = runner.invoke(
        app, [*args, "--neutral", "underside", "--trials", "1", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["study"] == "multigait-underside" and report["neutral"] == "underside"
    cross = ["--cross-stiffness", "1000,20000", "--trials", "1", "--out", str(tmp_path)]
    result = runner.invoke(app, [*args, *cross])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait_calibration.json").read_text())
    assert report["study"] == "multigait-cross"
    assert 1000 <= report["parameters"]["cross_stiffness"] <= 20000
    for refused, needle in (
        ([*args, "--travel-actions", "2"], "no travel term"),
        (["proxy", "calibrate", "trunk", "--neutral", "underside"], "only the Multigait's"),
        ([*args, "--neutral", "top"], "one of"),
        ([*args, "--travel-weight", "1", "--travel-actions", "3"], "longer than the reference"),
        ([*args, "--travel-weight", "1", "--travel-actions", "0"], "greater than or equal to 1"),
        (["proxy", "calibrate", "trunk", "--friction", "0.1,1"], "only the Multigait"),
        ([*args, "--contact", "balls"], "one of"),
        (["proxy", "calibrate", "trunk-cube", "--travel-weight", "1"], "not a sequence"),
        ([*args, "--friction", "0.9,0.5"], "LOW < HIGH"),
        ([*args, "--contraction", "0,0.2"], "only the Trunk"),
        (["proxy", "calibrate", "trunk", "--cross-stiffness", "1,2"], "has cross beams"),
        ([*args, "--cross-stiffness", "2000,1000"], "0 < LOW < HIGH"),
        (["proxy", "calibrate", "trunk", "--contraction", "0.2,0.1"], "LOW < HIGH"),
        ([*args, "--start", str(tmp_path / "reference.npz")], "not a calibration report"),
    ):
        result = runner.invoke(app, [*refused, "--out", str(tmp_path)])
        assert result.exit_code == 2 and needle in result.output, result.output


def test_the_16_action_calibration_sequence_visits_every_group_state_twice() -> None:
    """MULTIGAIT_PATTERNS: each action changes one group (centre, front, rear) as the
    environment's actions do, ramped over 0.6 s; the 8 on/off states are each held twice and
    the sequence ends where it began."""
    from pliant.proxy.references import MULTIGAIT_PATTERNS, pattern_levels

    assert len(MULTIGAIT_PATTERNS) == 16
    states = []
    for k in range(17):
        level = pattern_levels(MULTIGAIT_PATTERNS, 0.6 * k + 1e-9)
        np.testing.assert_allclose(level[[1, 3]], level[[2, 4]])  # pairs move together
        states.append(tuple(np.round(level[[0, 1, 3]]).astype(int)))
    changes = [np.sum(np.subtract(b, a) != 0) for a, b in zip(states, states[1:], strict=False)]
    assert changes == [1] * 16
    assert {s: states[:-1].count(s) for s in set(states)} == {s: 2 for s in set(states)}
    assert len(set(states)) == 8 and states[0] == states[-1] == (0, 0, 0)
    np.testing.assert_allclose(pattern_levels(MULTIGAIT_PATTERNS, 0.3), [0, 0, 0, 0.5, 0.5])
    with pytest.raises(ModelError, match="integers in"):
        pattern_levels((4, 6), 0.3)


def test_the_hand_gait_as_actions_is_the_robots_demo_actuation() -> None:
    """MULTIGAIT_HAND_GAIT played by pattern_levels gives demo_actuation's volumes at every
    time of its 10.8 s, so the joint calibration's first part is the hand gait."""
    from pliant.proxy.references import MULTIGAIT_HAND_GAIT, pattern_levels
    from pliant.robots.multigait import chamber_amplitudes, demo_actuation

    volumes = chamber_amplitudes()
    for t in np.arange(0.0, 10.8, 0.017):
        np.testing.assert_allclose(
            pattern_levels(MULTIGAIT_HAND_GAIT, t) * volumes, demo_actuation(t), atol=1e-6
        )


def test_calibrating_on_the_patterns_validates_on_the_hand_gait(tmp_path, monkeypatch) -> None:
    """`pliant proxy calibrate multigait-patterns`: the report adds the error on the other
    actions' trajectory (OUT/multigait_reference.npz, the hand gait); a proxy fitted on its
    own trajectory has error 0 there when that trajectory is its own too."""
    import json

    from typer.testing import CliRunner

    from pliant.cli import app
    from pliant.proxy.references import Reference, setup

    surface = np.array([[0.0, 29.0, 0.0], [136.0, -29.0, 0.0], [68.0, 0.0, 0.0]])
    defaults = dict(multigait_proxy().parameters)

    def reference(commands: np.ndarray) -> Reference:
        draft = Reference(commands, np.zeros((len(commands), 3, 3)), surface, 0.01)
        return Reference(commands, setup("multigait").simulate(draft)(defaults), surface, 0.01)

    reference(np.tile([0.0, 0.0, 0.0, 1.0, 1.0], (10, 1))).save(tmp_path / "fit.npz")
    reference(np.tile([1.0, 1.0, 1.0, 0.0, 0.0], (10, 1))).save(
        tmp_path / "multigait_reference.npz"
    )
    # one trial, at the defaults: the search box collapsed onto them
    space = setup("multigait-patterns").space
    for name in list(space):
        monkeypatch.setitem(space, name, (defaults[name], defaults[name] * (1 + 1e-12)))
    args = ["proxy", "calibrate", "multigait-patterns", "--reference", str(tmp_path / "fit.npz")]
    result = CliRunner().invoke(app, [*args, "--trials", "1", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "multigait-patterns_calibration.json").read_text())
    assert report["optimisation_error_mm"] < 1e-6
    assert report["other_actions"]["error_mm"] < 1e-6


def test_the_cube_setup_follows_the_cube_under_the_references_commands() -> None:
    """`trunk-cube`: the matched point is the proxy cube's centre, after the same settling as
    the FEM's; bending both beams towards it (+d2) pushes it along +x."""
    from pliant.proxy.references import Reference, setup

    commands = np.zeros((60, 5))
    commands[:, [1, 3]] = np.linspace(0.0, 0.1, 60)[:, None]
    draft = Reference(commands, np.zeros((60, 1, 3)), np.zeros((1, 3)), 0.01)
    points = setup("trunk-cube").simulate(draft)({"cube_mass": 0.01})
    assert points.shape == (60, 1, 3)
    assert points[-1, 0, 0] > points[0, 0, 0] + 1.0


def test_the_trunk_proxy_pushes_the_cube_in_its_environment() -> None:
    """pliant/TrunkPushProxy-v0: bending both beams a little towards +x (the cube's side)
    pushes the cube along +x; the reward's parts add up."""
    import gymnasium as gym

    import pliant.envs  # noqa: F401  (registers the environments)

    env = gym.make("pliant/TrunkPushProxy-v0")
    env.reset(seed=0)
    start = env.unwrapped.cube().copy()
    _, reward, _, _, info = env.step(np.array([0.0, 0.15, 0.0, 0.15, 0.0]))
    assert env.unwrapped.cube()[0] > start[0] + 10.0
    assert reward == pytest.approx(sum(info["reward_parts"].values()))


def test_the_trunk_proxy_touches_the_cube_through_the_fem_trunks_surface() -> None:
    """trunk_proxy(contact="surface"): the FEM Trunk's 191 colliding points skinned onto the
    skeleton, the FEM's own at rest; bent onto the cube, the trunk pushes it along +x and no
    skinned point enters it by more than 0.1 mm, where the tapered tip is thinner than the
    node balls (radius 10 mm all along)."""
    from pliant.robots.trunk_cube import surface_points

    proxy = trunk_proxy(contact="surface")
    skin = proxy.model.contacts.points
    rest = proxy.rod.rest_positions
    np.testing.assert_allclose(skin.positions(rest), surface_points(), atol=1e-9)
    tip = surface_points()[surface_points()[:, 2] > 190.0]
    assert np.linalg.norm(tip[:, :2], axis=1).max() < 0.6 * 10.0  # thinner than a ball
    solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
    start = state.rigid_positions[0].copy()
    half = 15.0
    deepest = 0.0
    for k in range(60):
        ramp = min(k + 1, 30) / 30
        proxy.apply([0.0, 0.15 * ramp, 0.0, 0.15 * ramp, 0.0])
        state = solver.step(state)
        local = skin.positions(state.positions) - state.rigid_positions[0]
        local = local @ state.rigid_rotations[0]
        inside = half - np.abs(local).max(axis=1)
        deepest = max(deepest, float(inside.max()))
    assert state.rigid_positions[0][0] > start[0] + 10.0
    assert deepest < 0.1


def test_a_multigait_proxy_bent_about_its_underside_keeps_the_underside_s_length() -> None:
    """neutral="underside": each bending stretches its beam by kappa h (h the skeleton's
    height over the underside), so that the underside skinned onto a front leg keeps its
    length as the leg curls fully (weightless, ramped over 1 s, then held 1 s): within 1 %,
    as the FEM Multigait's underside does, where bent about its axis it shortens by 14 %."""
    from pliant.robots.multigait import face_points

    underside = face_points(top=False)
    line = np.flatnonzero((underside[:, 0] <= 45.1) & (np.abs(underside[:, 1] - 13.0) < 0.2))
    line = line[np.argsort(underside[line, 0])]
    rest = np.linalg.norm(np.diff(underside[line], axis=0), axis=1).sum()
    lengths = {}
    for neutral in ("axis", "underside"):
        proxy = multigait_proxy(neutral=neutral, gravity=(0.0, 0.0, 0.0))
        leg = proxy.actuation.bendings[1]
        assert leg.max_stretch == pytest.approx(
            (neutral == "underside") * leg.max_curvature * 6.3 / 2
        )
        skin = Skinning(proxy.rod, underside, neighbours=2)
        solver, state = ImplicitEuler(proxy.model, 0.01), proxy.model.rest_state()
        for k in [*range(1, 101), *[100] * 100]:
            proxy.apply([0.0, k / 100, k / 100, 0.0, 0.0])
            state = solver.step(state)
        points = skin.positions(state.positions)[line]
        lengths[neutral] = np.linalg.norm(np.diff(points, axis=0), axis=1).sum() / rest
    assert abs(lengths["underside"] - 1.0) < 0.01
    assert lengths["axis"] < 0.9
    with pytest.raises(ModelError, match="neutral"):
        multigait_proxy(neutral="top")


def test_a_calibration_reports_proxy_keywords_carry_its_contact() -> None:
    """fitted_proxy: the fitted parameters as floats, the contact only where it is not the
    default node balls, the neutral layer only where it is not the beams' axis; a report
    without numeric parameters, with an unknown contact or layer is refused."""
    from pliant.proxy.calibrate import fitted_proxy

    assert fitted_proxy({"parameters": {"cube_mass": 0.01}}) == {"cube_mass": 0.01}
    assert fitted_proxy({"parameters": {"friction": 1}, "contact": "surface"}) == {
        "friction": 1.0,
        "contact": "surface",
    }
    for bad in ({}, {"parameters": {"friction": "high"}}, {"parameters": [1.0]}):
        with pytest.raises(ModelError, match="not a calibration report"):
            fitted_proxy(bad)
    with pytest.raises(ModelError, match="contact"):
        fitted_proxy({"parameters": {}, "contact": "balls"})
    report = {"parameters": {"friction": 1}, "contact": "surface", "neutral": "underside"}
    assert fitted_proxy(report)["neutral"] == "underside"
    assert "neutral" not in fitted_proxy({**report, "neutral": "axis"})
    with pytest.raises(ModelError, match="neutral"):
        fitted_proxy({**report, "neutral": "top"})
