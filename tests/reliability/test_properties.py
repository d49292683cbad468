"""Property-based tests (Hypothesis) over the public API (issue 22): for any input, a call
returns finite values or raises a PliantError; never another exception, never a NaN, never a
dead interpreter.

The inputs that once ended the interpreter (states of another shape against the compiled
kernels, mesh files that meshio answers with sys.exit) are tested in a child pytest run
(PLIANT_PROPERTIES_CHILD=1): a regression fails `test_isolated_properties_in_a_child`, not
the whole run. CI runs the "ci" profile (a few hundred examples in all, about a minute);
HYPOTHESIS_PROFILE=nightly runs twenty times as many.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import two_cable_beam
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from typer.testing import CliRunner

from pliant.cli import app
from pliant.constraints.control import DirectControl, InverseControl
from pliant.errors import DivergenceError, PliantError
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational, NeoHookean
from pliant.mesh import TetMesh, box_beam, load_mesh, save_mesh
from pliant.mesh.quality import validate_mesh
from pliant.model import State
from pliant.solvers import ImplicitEuler, StaticSolver

settings.register_profile(
    "ci", max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "nightly", max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
PROFILE = settings.get_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
CHILD = os.environ.get("PLIANT_PROPERTIES_CHILD") == "1"
crash_prone = pytest.mark.skipif(not CHILD, reason="runs in a child process")

MODEL = two_cable_beam()
N = MODEL.body.n_nodes

# Numbers as a hostile user gives them: any float (NaN, infinities, huge, tiny), integers,
# NumPy scalars, booleans, text, None, complex.
anything = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.floats(-1e3, 1e3).map(np.float32),
    st.integers(-1000, 1000).map(np.int64),
    st.booleans(),
    st.text(max_size=4),
    st.none(),
    st.complex_numbers(max_magnitude=10),
)


def finite_state(state: State) -> None:
    for array in (state.positions, state.velocities, state.actuation, state.displacement):
        assert np.all(np.isfinite(array))
    assert np.isfinite(state.time)


# ---------------------------------------------------------------------------------------------
# Materials, meshes and bodies


@PROFILE
@given(young=anything, poisson=anything, law=st.sampled_from([Corotational, NeoHookean]))
def test_materials_are_valid_or_refused(young, poisson, law) -> None:
    try:
        material = law(young, poisson)
    except PliantError:
        return
    assert material.young_modulus > 0 and 0 <= material.poisson_ratio < 0.5
    assert np.isfinite(material.mu) and np.isfinite(material.lam)


@PROFILE
@given(
    points=hnp.arrays(
        np.float64,
        st.tuples(st.integers(0, 12), st.sampled_from([2, 3, 4])),
        elements=st.one_of(st.floats(-10, 10), st.sampled_from([np.nan, np.inf])),
    ),
    tets=hnp.arrays(
        np.int64,
        st.tuples(st.integers(0, 8), st.sampled_from([3, 4])),
        elements=st.integers(-2, 14),
    ),
)
def test_mesh_arrays_are_validated_or_refused(points, tets) -> None:
    try:
        validate_mesh(points, tets)
    except PliantError:
        return
    mesh = TetMesh(points, tets)
    assert np.all(np.isfinite(mesh.points)) and np.all(mesh.signed_volumes() > 0)


@PROFILE
@given(
    shift=hnp.arrays(np.float64, 3, elements=st.floats(-5, 5)),
    node=st.integers(0, 11),
    density=anything,
)
def test_bodies_of_perturbed_meshes_are_usable_or_refused(shift, node, density) -> None:
    mesh = box_beam(10.0, 5.0, 5.0, 2, 1, 1)
    points = mesh.points.copy()
    points[node] += shift
    try:
        body = TetBody(TetMesh(points, mesh.tets), Corotational(100.0, 0.3), density=density)
    except PliantError:
        return
    assert body.n_nodes == mesh.n_nodes and np.all(np.isfinite(body.gravity_forces()))


@crash_prone
@PROFILE
@given(
    content=st.binary(max_size=2000),
    suffix=st.sampled_from([".vtk", ".vtu", ".msh", ".xdmf", ".obj"]),
    from_good=st.booleans(),
    cut=st.floats(0, 1),
)
def test_crash_prone_mesh_files_load_or_raise_mesh_errors(
    tmp_path_factory, content, suffix, from_good, cut
) -> None:
    """Random bytes, or a good file truncated and overwritten with them."""
    folder = tmp_path_factory.mktemp("mesh")
    path = folder / f"mesh{suffix}"
    if from_good and suffix in (".vtk", ".vtu", ".msh"):
        save_mesh(box_beam(10.0, 5.0, 5.0, 2, 1, 1), path)
        data = path.read_bytes()
        start = int(cut * len(data))
        content = data[:start] + content + data[start + len(content) :]
    path.write_bytes(content)
    try:
        mesh = load_mesh(path)
    except PliantError:
        return
    assert np.all(np.isfinite(mesh.points)) and np.all(mesh.signed_volumes() > 0)


# ---------------------------------------------------------------------------------------------
# States, controls and solver settings


DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.complex128])
state_arrays = st.one_of(
    st.tuples(
        hnp.arrays(
            np.float64,
            st.tuples(
                st.sampled_from([0, 1, N - 1, N, N + 1, 3 * N]), st.sampled_from([1, 2, 3, 4])
            ),
            elements=st.floats(-100, 100),
        ),
        DTYPES,
    ).map(lambda pair: pair[0].astype(pair[1])),
    # the rest state, moved a little: the usual case
    hnp.arrays(np.float64, (N, 3), elements=st.floats(-0.5, 0.5)).map(
        lambda noise: MODEL.body.rest_positions + noise
    ),
)


@crash_prone
@PROFILE
@given(
    positions=state_arrays,
    velocities=state_arrays,
    actuation=hnp.arrays(np.float64, st.integers(0, 4), elements=st.floats(-1e3, 1e3)),
    time=st.one_of(st.floats(allow_nan=True, allow_infinity=True), anything),
    step=st.one_of(st.integers(-3, 10**9), anything),
    static=st.booleans(),
)
def test_crash_prone_states_step_or_raise_state_errors(
    positions, velocities, actuation, time, step, static
) -> None:
    """Any arrays as a state of the model: a finite state or a PliantError, before any
    compiled kernel reads past an array."""
    state = State(positions, velocities, time, step, actuation, actuation.copy())
    solver = StaticSolver(MODEL) if static else ImplicitEuler(MODEL, 0.01)
    try:
        new = solver.step(state, [0.1, 0.0])
    except PliantError:
        return
    finite_state(new)


@crash_prone
@PROFILE
@given(
    state_file=st.binary(max_size=600),
    keep=st.integers(0, 4000),
    flip=st.integers(0, 4000),
)
def test_crash_prone_state_files_load_or_raise_state_errors(
    tmp_path_factory, state_file, keep, flip
) -> None:
    folder = tmp_path_factory.mktemp("state")
    good = folder / "good.npz"
    MODEL.rest_state().save(good)
    data = bytearray(good.read_bytes()[:keep] + state_file)
    if data:
        data[flip % len(data)] ^= 0x5A
    bad = folder / "bad.npz"
    bad.write_bytes(bytes(data))
    try:
        state = State.load(bad, MODEL)
    except PliantError:
        return
    finite_state(ImplicitEuler(MODEL, 0.01).step(state))


commands = st.one_of(
    anything,
    hnp.arrays(
        np.float64,
        st.one_of(st.just((2,)), hnp.array_shapes(max_dims=2, max_side=3)),
        elements=st.floats(allow_nan=True, allow_infinity=True),
    ),
    st.lists(st.one_of(st.floats(-20, 20), st.text(max_size=2)), max_size=3),
)


@PROFILE
@given(control=commands, mode=st.sampled_from([None, "force", "displacement"]))
def test_any_commands_give_a_finite_state_or_a_pliant_error(control, mode) -> None:
    model = two_cable_beam()
    if mode is not None:
        for actuator in model.actuators:
            actuator.mode = mode
    try:
        new = ImplicitEuler(model, 0.01).step(model.rest_state(), control)
    except PliantError:
        return
    finite_state(new)


@PROFILE
@given(
    goal=st.tuples(
        hnp.arrays(
            np.float64, hnp.array_shapes(max_dims=2, max_side=4), elements=st.floats(-1e4, 1e4)
        ),
        st.sampled_from([np.float64, np.int64, np.float32]),
    ).map(lambda pair: pair[0].astype(pair[1])),
    regularisation=anything,
    static=st.booleans(),
)
def test_inverse_control_gives_a_finite_best_effort_or_a_pliant_error(
    goal, regularisation, static
) -> None:
    """Goals anywhere, reachable or 10 m away: the closest configuration the bounds allow
    (never a QP 'divergence' for a goal out of reach), or a PliantError for bad settings."""
    model = two_cable_beam(max_displacement=5.0)
    control = InverseControl(goals=goal, regularisation=regularisation)
    solver = StaticSolver(model) if static else ImplicitEuler(model, 0.01)
    state = model.rest_state()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            for _ in range(3):
                state = solver.step(state, control)
        except PliantError as exc:
            assert "ProxQP" not in str(exc), exc  # a goal out of reach is no QP failure
            return
    finite_state(state)
    assert np.all(np.abs(state.displacement) <= 5.0 + 1e-6)  # the cables' course held


counts = st.one_of(st.integers(-3, 30), st.floats(allow_nan=True), st.text(max_size=2))


@PROFILE
@given(
    dt=anything,
    rtol=anything,
    tolerance=anything,
    max_iterations=counts,
    augmentation=anything,
)
def test_solver_settings_work_or_raise_pliant_errors(
    dt, rtol, tolerance, max_iterations, augmentation
) -> None:
    for make in (
        lambda: ImplicitEuler(MODEL, dt, rtol=rtol),
        lambda: StaticSolver(
            MODEL, tolerance=tolerance, max_iterations=max_iterations, augmentation=augmentation
        ),
    ):
        try:
            solver = make()
            new = solver.step(MODEL.rest_state(), DirectControl(np.array([0.2, 0.0])))
        except PliantError:
            continue
        finite_state(new)


@PROFILE
@given(
    steps=st.lists(
        hnp.arrays(np.float64, 2, elements=st.floats(-3.0, 3.0)), min_size=1, max_size=12
    ),
    dt=st.sampled_from([0.001, 0.01, 0.1, 1.0]),
)
def test_random_actions_never_return_a_broken_state(steps, dt) -> None:
    """Every state a step returns is usable: finite, no inverted element (a step that would
    make one raises DivergenceError itself, not the next one)."""
    model = two_cable_beam(max_displacement=3.0)
    sim = ImplicitEuler(model, dt)
    state = model.rest_state()
    for command in steps:
        try:
            state = sim.step(state, command)
        except DivergenceError:
            return
        finite_state(state)
        volumes = TetMesh(state.positions, model.body.tets).signed_volumes()
        assert np.all(volumes > 0)


# ---------------------------------------------------------------------------------------------
# The command line

runner = CliRunner()
option_values = st.one_of(
    st.text(alphabet="0123456789.-+eEnaifx,:", min_size=1, max_size=8),
    st.sampled_from(["nan", "inf", "-1", "0", "1e400", "", "a,b", "1,2,3", "0:1", "1:0"]),
)


@PROFILE
@given(
    command=st.sampled_from(
        [
            ("run", "--duration"),
            ("run", "--dt"),
            ("run", "--frames"),
            ("inverse", "--goals"),
            ("inverse", "--max-steps"),
            ("condensed train", "--epochs"),
            ("condensed train", "--hidden"),
            ("condensed train", "--learning-rate"),
            ("condensed control", "--pid"),
            ("condensed collect", "--bounds"),
            ("condensed collect", "--workers"),
            ("condensed collect", "--test-fraction"),
            ("condensed design", "--grid"),
        ]
    ),
    value=option_values,
)
def test_cli_options_fail_with_one_line_never_a_traceback(command, value) -> None:
    """The target (a robot named 'octopus', files that do not exist) always fails, so every
    call ends in an error: one red line, exit 2 (usage) or 1 (runtime)."""
    name, option = command
    target = {
        "run": ["octopus"],
        "inverse": ["octopus"],
        "condensed train": ["none.h5", "--out", "m.pt"],
        "condensed control": ["none.pt"],
        "condensed collect": ["octopus", "--out", "d.h5", "--bounds", "0:1"],
        "condensed design": ["none.pt"],
    }[name]
    with tempfile.TemporaryDirectory() as folder, contextlib.chdir(folder):
        result = runner.invoke(app, [*name.split(), *target, option, value])
        assert not Path("m.pt").exists() and not Path("d.h5").exists()
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code in (1, 2), result.output
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert isinstance(result.exception, SystemExit)


# ---------------------------------------------------------------------------------------------
# The crash-prone properties, in a child process


@pytest.mark.skipif(CHILD, reason="this is the child")
def test_isolated_properties_in_a_child() -> None:
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", __file__, "-q", "-k", "crash_prone"],
        cwd=root,
        env={**os.environ, "PLIANT_PROPERTIES_CHILD": "1"},
        capture_output=True,
        text=True,
        timeout=1200,
    )
    tail = (proc.stdout + proc.stderr)[-4000:]
    assert proc.returncode == 0, f"child pytest ended with {proc.returncode}:\n{tail}"
    assert " passed" in proc.stdout and "skipped" not in proc.stdout.splitlines()[-1], tail
