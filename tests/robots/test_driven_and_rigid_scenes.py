"""Bodies coupled to what moves them: driven (kinematic) nodes, rigid bodies in contact, and the
scenes built on them (CartStemContact, Soft Gripper, Trunk with a cube)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import mechanical_energy

from pliant.constraints.contact import Contacts
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, rail
from pliant.geometry.collision import Box, Plane, Sphere
from pliant.mesh import box_beam
from pliant.model import Model, State
from pliant.robots import cartstem, gripper, trunk_cube
from pliant.solvers import ImplicitEuler, StaticSolver
from pliant.viz import save_png
from pliant.viz.model_view import RobotCamera

G = 9810.0  # mm/s^2


def _beam_on_cart(motion, *, gravity=(0.0, 0.0, 0.0)) -> Model:
    """A 40 x 6 x 6 mm beam along x (E = 300 kPa, 1e-6 kg/mm^3) whose x = 0 face rides a
    cart moving along y by motion(t)."""
    mesh = box_beam(40.0, 6.0, 6.0, nx=8, ny=1, nz=1)
    base = np.flatnonzero(mesh.points[:, 0] == 0.0)
    body = TetBody(
        mesh,
        Corotational(300.0, 0.3),
        density=1e-6,
        fixed_nodes=base,
        gravity=gravity,
        rayleigh_stiffness=0.01,
    )
    cart = KinematicBody(Box([1.0, 4.0, 4.0], position=[-1.0, 3.0, 3.0]))
    cart.trajectory = rail([-1.0, 3.0, 3.0], [0.0, 1.0, 0.0], motion)
    return Model(body, drivers=[DrivenNodes(base, cart, name="cart")], name="beam_on_cart")


def test_beam_on_an_accelerating_cart_lags_by_its_static_deflection() -> None:
    """Cart at constant acceleration a along y: in the cart's frame the beam carries the
    inertial load -m a, so once the transient has died out its tip lags the base by the static
    deflection of the same beam under a gravity -a y. Exact for implicit Euler (the steady
    state in the cart's frame is a rigid translation per step, on which K vanishes) only if the
    free DoFs feel the driven nodes' motion within the step; one step late, the stiffness term
    h^2 K_ff v alone would pull the tip by a force growing with the cart's speed."""
    a = 1000.0
    model = _beam_on_cart(lambda t: 0.5 * a * t * t)
    solver = ImplicitEuler(model, 0.01, tangent="fresh")
    state = model.rest_state()
    tip = np.flatnonzero(model.body.rest_positions[:, 0] == 40.0)
    lags = []
    for _ in range(150):
        state = solver.step(state)
        if state.step in (100, 150):
            lags.append(state.positions[tip, 1].mean() - 0.5 * a * state.time**2 - 3.0)
    static_model = _beam_on_cart(lambda t: 0.0, gravity=(0.0, -a, 0.0))
    equilibrium = StaticSolver(static_model).step(static_model.rest_state())
    deflection = equilibrium.positions[tip, 1].mean() - 3.0
    # Euler-Bernoulli gives rho A a L^4 / (8 E I) = 0.356 mm; one tetrahedral cell across the
    # section locks in bending (0.090 mm), the same way in both solves.
    assert deflection < -0.05
    for lag in lags:
        assert abs(lag - deflection) < 1e-6 * abs(deflection), (lag, deflection)


def test_a_body_carried_at_constant_velocity_keeps_zero_internal_force() -> None:
    """The base driven at constant velocity V and every node starting at V: the whole beam
    translates rigidly, x(t) = X + V t at every node, and no internal force appears."""
    speed = 80.0
    model = _beam_on_cart(lambda t: speed * t)
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    state.velocities[:] = [0.0, speed, 0.0]
    for _ in range(20):
        state = solver.step(state)
    rest = model.body.rest_positions
    assert np.abs(state.positions - rest - [0.0, speed * state.time, 0.0]).max() < 1e-9
    assert np.abs(model.body.linearise(state.positions).forces).max() < 1e-9


def test_driven_nodes_must_be_held() -> None:
    mesh = box_beam(40.0, 6.0, 6.0, nx=4, ny=1, nz=1)
    body = TetBody(mesh, Corotational(300.0, 0.3), density=1e-6)
    cart = KinematicBody(Box([1.0, 1.0, 1.0]))
    with pytest.raises(Exception, match="must be fixed nodes"):
        Model(body, drivers=[DrivenNodes([0, 1], cart)])


def _soft_block(**contact) -> TetBody:
    """A 20 mm soft cube (E = 100 kPa, 8 g) standing on the floor z = 0, its bottom held."""
    mesh = box_beam(20.0, 20.0, 20.0, nx=3, ny=3, nz=3)
    return TetBody(
        mesh,
        Corotational(100.0, 0.3),
        density=1e-6,
        fixed_nodes=np.flatnonzero(mesh.points[:, 2] == 0.0),
        gravity=(0.0, 0.0, -G),
        rayleigh_mass=5.0,
    )


def test_rigid_box_resting_on_a_soft_block_weighs_on_it() -> None:
    """A 5 g rigid box set 0.2 mm above the block falls on it and comes to rest: the contact
    forces of the box on the block add up to the box's weight m g (its equilibrium), the box's
    velocity vanishes, and no block node is inside it."""
    box = RigidBody(Box([8.0, 8.0, 4.0], position=[10.0, 10.0, 24.2]), 0.005, friction=0.5)
    model = Model(
        _soft_block(), contacts=Contacts([Plane()], friction=0.5, margin=1.0), rigid_bodies=[box]
    )
    solver = ImplicitEuler(model, 0.005)
    state = model.rest_state()
    for _ in range(200):
        state = solver.step(state)
    on_box = state.contact_forces.keys[:, 1] == 1  # shape 1: the box, after the floor
    force = state.contact_forces.forces[on_box].sum(axis=0)
    weight = box.mass * G
    assert abs(-force[2] - weight) < 1e-6 * weight, (force, weight)
    assert np.abs(force[:2]).max() < 1e-6 * weight
    assert np.abs(state.rigid_velocities).max() < 1e-6
    assert np.abs(state.rigid_angular_velocities).max() < 1e-6
    box.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    assert box.shape.signed_distance(state.positions).gap.min() > -model.contacts.tolerance


def test_sphere_dropped_on_a_soft_slab_loses_energy_and_comes_to_rest() -> None:
    """A 4 g rigid sphere dropped from 3 mm onto the block: the impact exchanges momentum
    (the block moves), the total energy never grows beyond what the contact solver's
    tolerance allows, and the sphere ends at rest on the block's top nodes."""
    sphere = RigidBody(Sphere(5.0, position=[10.0, 10.0, 28.0]), 0.004, friction=0.3)
    model = Model(
        _soft_block(), contacts=Contacts([Plane()], friction=0.3, margin=1.0), rigid_bodies=[sphere]
    )
    solver = ImplicitEuler(model, 0.005)
    state = model.rest_state()
    energies, block_speed = [mechanical_energy(model, state)], 0.0
    for _ in range(200):
        state = solver.step(state)
        energies.append(mechanical_energy(model, state))
        block_speed = max(block_speed, np.abs(state.velocities).max())
    allowance = 10 * (model.body.total_mass + sphere.mass) * G * model.contacts.tolerance
    assert np.diff(energies).max() <= allowance, np.diff(energies).max()
    assert energies[-1] < energies[0] - 0.5 * sphere.mass * G * 3.0  # the fall's energy is lost
    assert block_speed > 1.0  # the block took momentum from the sphere
    assert np.abs(state.rigid_velocities).max() < 1e-3
    # At rest in the pocket of the four top nodes around it: touching them, not inside.
    sphere.shape.set_pose(state.rigid_positions[0], state.rigid_rotations[0])
    gap = sphere.shape.signed_distance(state.positions).gap
    assert -model.contacts.tolerance < gap.min() < 1e-3
    assert np.count_nonzero(gap < 1e-3) == 4


def test_coupled_state_saves_and_replays_exactly(tmp_path) -> None:
    """A state with rigid bodies and driven nodes copies, saves and loads bit for bit, and the
    steps from the restored state repeat the original ones exactly."""
    sphere = RigidBody(Sphere(5.0, position=[10.0, 10.0, 26.0]), 0.004)
    model = Model(_soft_block(), contacts=Contacts([Plane()], margin=1.0), rigid_bodies=[sphere])
    solver = ImplicitEuler(model, 0.005)
    state = model.rest_state()
    for _ in range(40):
        state = solver.step(state)
    assert len(state.contact_forces.keys) > 0
    state.save(tmp_path / "s.npz")
    restored = State.load(tmp_path / "s.npz")
    assert restored.allclose(state) and restored.allclose(state.copy())
    runs = []
    for start in (state, restored):
        solver.system.invalidate()
        s = start
        for _ in range(5):
            s = solver.step(s)
        runs.append(s)
    assert runs[0].allclose(runs[1])


SCENES = {
    "cartstem_contact": (cartstem.cartstem_contact, cartstem.demo_actuation),
    "soft_gripper": (gripper.soft_gripper, gripper.demo_actuation),
    "trunk_cube": (trunk_cube.trunk_cube, trunk_cube.demo_actuation),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_builds_steps_and_renders(name, tmp_path) -> None:
    """20 steps of the scripted actuation move the body (and the driven nodes by their
    carrier's motion, none of which is yet under way at t = 0), then a PNG is rendered."""
    build, demo = SCENES[name]
    model = build()
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    start = 0.5 if name == "cartstem_contact" else 0.0  # the cart's ramp is slow at first
    state.time = start
    state.positions = model.drive(state.positions, start)
    for _ in range(20):
        state = solver.step(state, demo(state.time))
    assert np.all(np.isfinite(state.positions))
    assert np.abs(state.positions - model.body.rest_positions).max() > 0.5
    for driver in model.drivers:
        assert np.array_equal(state.positions[driver.nodes], driver.positions(state.time))
    camera = RobotCamera(model)
    image = camera.frame(state)
    assert np.any(image != image[0, 0], axis=-1).mean() > 0.01
    assert save_png(image, tmp_path / f"{name}.png").stat().st_size > 0


class _CartSchedule:
    """A cart displacement s(t) (mm) planned one control period ahead: piecewise linear."""

    def __init__(self) -> None:
        self.times, self.values = [0.0], [0.0]

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.times, self.values))

    def move(self, start: float, stop: float, target: float) -> None:
        """From `start` on, forget the plan and go linearly to `target` at `stop`."""
        keep = [i for i, t in enumerate(self.times) if t <= start]
        now = self(start)
        self.times = [self.times[i] for i in keep] + [start + 1e-9, stop]
        self.values = [self.values[i] for i in keep] + [now, target]


def test_cartstem_contact_qp_stalls_but_bending_on_the_far_obstacle_reaches_the_goal() -> None:
    """Thesis §3.3.2, Fig. 3.11. Goal: tip at x = 25 mm, above the right obstacle (inner face at
    x = 20). A one-actuator QP on the cart's move per control period (|ds| <= 2.5 mm), with the
    tip's response linearised on each side (the two contact configurations a QPCC sees),
    drives the cart right until the beam touches the obstacle; there moving right swings the
    tip left and moving left moves it left too: the QP stops, 10 mm short. Bending the beam
    over the left obstacle instead swings the tip over the right one to the goal."""
    period, max_move, goal = 5, 2.5, 25.0
    schedule = _CartSchedule()
    model = cartstem.cartstem_contact(cart_motion=schedule)
    solver = ImplicitEuler(model, 0.01)

    def run(state: State, move: float) -> State:
        schedule.move(state.time, state.time + period * solver.dt, schedule(state.time) + move)
        for _ in range(period):
            state = solver.step(state)
        return state

    def tip(state: State) -> float:
        return float(model.effectors[0].position(state.positions)[0, 0])

    state = model.rest_state()
    moves = []
    for _ in range(8):
        still = tip(run(state, 0.0))
        error = still - goal
        best, best_error = 0.0, abs(error)
        for side in (1.0, -1.0):
            slope = (tip(run(state, 0.5 * side)) - still) / (0.5 * side)
            move = float(np.clip(-error / slope, *sorted((0.0, side * max_move))))
            if abs(error + slope * move) < best_error - 1e-6:
                best, best_error = move, abs(error + slope * move)
        moves.append(best)
        state = run(state, best)
    assert moves[:3] == [max_move] * 3  # straight towards the goal while free
    assert moves[-2:] == [0.0, 0.0]  # stalled on the obstacle
    assert len(state.contact_forces.keys) > 0
    assert 10.0 < goal - tip(state) < 11.0  # the beam's face on the obstacle's, x = 20 - 5

    # The scripted move: left at full speed, slowing down to 5 mm/s for the last 10 mm of the
    # tip (the tip swings 3.5 mm per mm of cart once the beam bears on the obstacle).
    state = model.rest_state()
    while tip(state) < goal and state.time < 4.0:
        state = run(state, -max_move if tip(state) < goal - 10.0 else -0.25)
    for _ in range(10):
        state = run(state, 0.0)
    assert abs(tip(state) - goal) < 1.5  # SofaGym's success threshold: 0.15 cm
    assert schedule(state.time) < -15.0  # the cart went left, past the left contact
