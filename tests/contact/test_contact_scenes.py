"""Contact scenes of the bench: the contacts they are timed with are there."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from pliant import robots
from pliant.bench import TRUNK_CUBE_WARMUP, trunk_cables_cube
from pliant.bench.timing import _contact_counts
from pliant.errors import ContactMarginWarning
from pliant.solvers import ImplicitEuler

REFERENCE_MESHES = Path(__file__).resolve().parents[3] / "shared" / "meshes"


def test_reference_trunk_touches_the_cube_over_the_bench_window() -> None:
    """`pliant bench` times SOFA's trunk_cables_cube.scn for 20 steps (its default) after its
    warm-up: some of the trunk's points press on the cube at each of them, and the cube lies
    on the floor."""
    scene = trunk_cables_cube(REFERENCE_MESHES)
    if scene is None:
        pytest.skip("SOFA's reference scenes are not beside the repository (../shared)")
    model, commands = scene.model, scene.commands()
    solver, state = ImplicitEuler(model, 0.01), model.rest_state()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactMarginWarning)  # the trunk's first fall
        for _ in range(TRUNK_CUBE_WARMUP):
            state = solver.step(state, commands)
    pressing = []
    for _ in range(20):
        state = solver.step(state, commands)
        keys, forces = state.contact_forces.keys, state.contact_forces.forces
        on_cube = (keys[:, 0] < len(model.contacts.points)) & (keys[:, 1] == 1)
        pressing.append(int(np.count_nonzero(np.linalg.norm(forces[on_cube], axis=1))))
        assert _contact_counts(model, state)[1] == on_cube.sum()
    assert min(pressing) >= 1, pressing
    n_points = len(model.contacts.points)
    assert (state.contact_forces.keys[:, 0] >= n_points).sum() == 4  # the cube's corners


def test_sofa_algorithm_solves_the_step_of_the_default_solver() -> None:
    """The bench's "sofa-algorithm" (every contact within the margin, every column, a
    factorisation each step) solves the same steps as Pliant's fresh tangent with screening
    and kept columns: its rate measures the algorithm, not another problem."""
    from pliant.bench import POLICY_OPTIONS

    model = robots.build("trunk_cube")
    demo = robots.entry("trunk_cube").demo_actuation
    sofa = ImplicitEuler(model, 0.01, **POLICY_OPTIONS["sofa-algorithm"])
    ours = ImplicitEuler(model, 0.01, tangent="fresh")
    state, touching = model.rest_state(), 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactMarginWarning)
        for _ in range(40):
            a, b = sofa.step(state, demo(state.time)), ours.step(state, demo(state.time))
            assert np.abs(a.positions - b.positions).max() < 1e-6
            assert ours.last_report.contact is None or sofa.last_report.contact.screened == 0
            touching += int(np.any(b.contact_forces.forces != 0.0))
            state = b
    assert touching > 10
