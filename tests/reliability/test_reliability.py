"""Bad input gets a typed error where it enters (issue 22): states of another model, state and
mesh files that cannot be read, solver settings, controls, materials, builder keywords, and
the command line's one red line. The cases that used to end the interpreter run in a child
process, so that a regression fails one test instead of the whole run."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import two_cable_beam
from typer.testing import CliRunner

from pliant import robots
from pliant.cli import app
from pliant.constraints.control import InverseControl
from pliant.errors import (
    ConstraintError,
    MaterialError,
    MeshError,
    MeshFileError,
    ModelError,
    PliantError,
    SolverError,
    StateError,
)
from pliant.fem.material import Corotational, NeoHookean
from pliant.mesh import TetMesh, box_beam, load_mesh, save_mesh
from pliant.mesh.quality import validate_mesh
from pliant.model import State
from pliant.solvers import ImplicitEuler, StaticSolver

ROOT = Path(__file__).resolve().parents[2]


def run_isolated(code: str, timeout: float = 300) -> list[dict]:
    """Run `code` in a fresh interpreter; it prints one JSON object per line. Returns them,
    after checking that the interpreter ended normally (an abort is a failed test here, not a
    dead test run)."""
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert proc.returncode == 0, f"the interpreter died ({proc.returncode}):\n{proc.stderr[-3000:]}"
    return [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]


# Prints, for each case, the exception's class and whether it is a PliantError.
CASES_PRELUDE = """
import json
import numpy as np
from pliant.errors import PliantError
from pliant.model import State
from pliant.solvers import ImplicitEuler, StaticSolver
from tests.conftest import two_cable_beam

def case(name, call):
    try:
        call()
        out = {"case": name, "error": None, "typed": False}
    except Exception as exc:
        out = {"case": name, "error": type(exc).__name__, "typed": isinstance(exc, PliantError)}
    print(json.dumps(out), flush=True)

model = two_cable_beam()
other = two_cable_beam(max_displacement=2.0)
"""


def test_a_state_of_another_model_is_refused_before_any_kernel_runs(tmp_path) -> None:
    """Issue 22, class 1: a state of another mesh, a truncated array, a wrong column count,
    another model's actuator count or rigid bodies: StateError in every solver entry, never
    an abort inside the compiled kernels."""
    code = (
        CASES_PRELUDE
        + f"""
from pliant.mesh import box_beam
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.model import Model
import numpy as np

fine = box_beam(60.0, 10.0, 10.0, 24, 3, 3)
x = fine.points
big = Model(TetBody(fine, Corotational(100.0, 0.3), density=1e-6,
                    fixed_nodes=np.flatnonzero(x[:, 0] <= 1e-9)))
bad = {{}}
bad["another mesh"] = big.rest_state()
s = model.rest_state(); s.positions = s.positions[:-3]; bad["truncated"] = s
s = model.rest_state(); s.positions = s.positions[:, :2].copy(); bad["two columns"] = s
s = model.rest_state(); s.velocities = s.velocities[:-1]; bad["short velocities"] = s
s = model.rest_state(); s.actuation = np.zeros((2, 2)); bad["actuators"] = s
s = model.rest_state(); s.displacement = np.zeros((7, 1)); bad["displacements"] = s
s = model.rest_state(); s.rigid_positions = np.zeros((2, 3)); bad["rigid bodies"] = s
s = model.rest_state(); s.time = float("nan"); bad["NaN time"] = s
s = model.rest_state(); s.positions = s.positions.copy(); s.positions[3, 1] = np.inf
bad["inf position"] = s
s = model.rest_state(); s.positions = s.positions.astype(complex); bad["complex"] = s
dynamic, static = ImplicitEuler(model, 0.01), StaticSolver(model)
for name, state in bad.items():
    case("dynamic step: " + name, lambda: dynamic.step(state))
    case("static step: " + name, lambda: static.step(state))
    case("dynamic condense: " + name, lambda: dynamic.condense(state))
    case("static condense: " + name, lambda: static.condense(state))
big.rest_state().save({str(tmp_path / "big.npz")!r})
case("load against the model", lambda: State.load({str(tmp_path / "big.npz")!r}, model))
s = model.rest_state(); s.actuation = np.zeros(5); s.save({str(tmp_path / "five.npz")!r})
case("load another actuator count", lambda: State.load({str(tmp_path / "five.npz")!r}, model))
"""
    )
    results = run_isolated(code)
    assert len(results) == 4 * 10 + 2
    wrong = [r for r in results if r["error"] != "StateError"]
    assert not wrong, wrong


def test_a_state_of_the_same_body_under_other_actuators_steps_without_them() -> None:
    """Refused but valid: the last step's actuator forces only start the next step; those of
    another actuator count (a state released from another model of the same body) are
    dropped, not refused, when stepping (State.load against a model refuses them)."""
    model = two_cable_beam()
    bent = ImplicitEuler(model, 0.01).step(model.rest_state(), [0.5, 0.0])
    bent.actuation, bent.displacement = np.ones(5), np.ones(5)
    released = ImplicitEuler(model, 0.01).step(bent)
    assert released.actuation.shape == (2,) and np.all(np.isfinite(released.positions))


def test_states_of_other_real_dtypes_step_like_float64() -> None:
    """Refused but valid: float32 or integer arrays are numbers; the step reads them as
    float64 and gives the float64 step's result."""
    model = two_cable_beam()
    sim = ImplicitEuler(model, 0.01)
    reference = sim.step(model.rest_state(), [0.5, 0.0])
    state = model.rest_state()
    state.positions = state.positions.astype(np.float32).astype(np.float64)
    state.velocities = np.zeros(state.velocities.shape, dtype=np.int64)
    again = ImplicitEuler(model, 0.01).step(state, [0.5, 0.0])
    np.testing.assert_allclose(again.positions, reference.positions, atol=1e-5)


def test_state_files_fail_with_state_errors(tmp_path) -> None:
    model = two_cable_beam()
    good = tmp_path / "good.npz"
    model.rest_state().save(good)
    assert State.load(good, model).allclose(model.rest_state())
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "garbage.npz").write_bytes(b"\x00garbage" * 100)
    (tmp_path / "truncated.npz").write_bytes(good.read_bytes()[:300])
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    flipped = bytearray(good.read_bytes())
    flipped[len(flipped) // 2] ^= 0xFF
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    for name in ("missing", "empty", "garbage", "truncated", "other", "flipped"):
        with pytest.raises(StateError):
            State.load(tmp_path / f"{name}.npz", model)


def test_a_failed_save_raises_state_error_and_leaves_no_temporary_file(
    tmp_path, monkeypatch
) -> None:
    state = two_cable_beam().rest_state()
    with pytest.raises(StateError, match="folder"):
        state.save(tmp_path)
    with pytest.raises(StateError):
        state.save(tmp_path / "no" / "such" / "folder.npz")

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    target = tmp_path / "state.npz"
    target.write_bytes(b"the previous state")
    monkeypatch.setattr(np, "savez", full_disk)
    with pytest.raises(StateError, match="No space left"):
        state.save(target)
    assert target.read_bytes() == b"the previous state"  # the old file is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.npz"]


@pytest.mark.parametrize(
    "content",
    [
        b"",
        b"garbage\x00\x01" * 100,
        b"# vtk DataFile Version 2.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0",
    ],
    ids=["empty", "garbage", "truncated"],
)
@pytest.mark.parametrize("suffix", [".vtk", ".vtu", ".msh"])
def test_unreadable_mesh_files_raise_mesh_file_error(tmp_path, content, suffix) -> None:
    """meshio ends the interpreter (sys.exit) on some of these: MeshFileError instead."""
    path = tmp_path / f"mesh{suffix}"
    path.write_bytes(content)
    with pytest.raises(MeshFileError):
        load_mesh(path)


@pytest.mark.parametrize("suffix", [".vtk", ".vtu"])
def test_damaged_copies_of_a_good_mesh_file_load_or_raise_mesh_errors(tmp_path, suffix) -> None:
    good = tmp_path / f"good{suffix}"
    save_mesh(box_beam(10.0, 5.0, 5.0, 3, 2, 2), good)
    data = good.read_bytes()
    rng = np.random.default_rng(0)
    for k in range(12):
        damaged = bytearray(data[: rng.integers(1, len(data))] if k % 2 else data)
        for i in rng.integers(0, len(damaged), 4):
            damaged[i] = int(rng.integers(0, 256))
        path = tmp_path / f"bad{k}{suffix}"
        path.write_bytes(bytes(damaged))
        try:
            mesh = load_mesh(path)
        except MeshError:
            continue
        assert np.all(np.isfinite(mesh.points)) and mesh.tets.shape[1] == 4


def test_coincident_nodes_are_refused_as_a_crack() -> None:
    mesh = box_beam(10.0, 5.0, 5.0, 2, 1, 1)
    points = np.vstack([mesh.points, mesh.points[[4]]])
    tets = mesh.tets.copy()
    first = np.flatnonzero(np.any(tets == 4, axis=1))[0]
    tets[first][tets[first] == 4] = len(points) - 1  # one element uses the twin
    with pytest.raises(MeshError, match="coincide"):
        validate_mesh(points, tets)
    validate_mesh(mesh.points, mesh.tets)  # the original is fine
    TetMesh(mesh.points, mesh.tets)


@pytest.mark.parametrize("value", [np.float32(180), np.int64(180), np.float64(180), 180])
def test_numpy_scalars_are_valid_material_parameters(value) -> None:
    for law in (Corotational, NeoHookean):
        material = law(value, np.float32(0.45))
        assert material.young_modulus == 180.0 and isinstance(material.young_modulus, float)
        assert np.isfinite(material.lam) and material.mu > 0


@pytest.mark.parametrize("value", [True, "180", None, float("nan"), 1j, -1.0, [180.0]])
def test_non_numbers_are_invalid_material_parameters(value) -> None:
    with pytest.raises(MaterialError):
        Corotational(value, 0.3)


SOLVER_ERRORS = [
    (lambda m: ImplicitEuler(m, "0.01"), "dt"),
    (lambda m: ImplicitEuler(m, None), "dt"),
    (lambda m: ImplicitEuler(m, 1e-200), "dt"),
    (lambda m: ImplicitEuler(m, float("nan")), "dt"),
    (lambda m: ImplicitEuler(m, 0.01, rtol=float("nan")), "rtol"),
    (lambda m: ImplicitEuler(m, 0.01, screen_gap=-1.0), "screen_gap"),
    (lambda m: StaticSolver(m, max_iterations=0), "max_iterations"),
    (lambda m: StaticSolver(m, max_iterations=2.5), "max_iterations"),
    (lambda m: StaticSolver(m, tolerance=float("nan")), "tolerance"),
    (lambda m: StaticSolver(m, tolerance=0.0), "tolerance"),
    (lambda m: StaticSolver(m, augmentation=float("nan")), "augmentation"),
    (lambda m: StaticSolver(m, augmentation=-1.0), "augmentation"),
]


@pytest.mark.parametrize(("make", "name"), SOLVER_ERRORS)
def test_solver_settings_are_checked_where_they_enter(make, name) -> None:
    with pytest.raises(SolverError, match=name):
        make(two_cable_beam())


def test_numpy_time_steps_and_integer_iterations_are_accepted() -> None:
    model = two_cable_beam()
    assert ImplicitEuler(model, np.float32(0.01)).dt == pytest.approx(0.01)
    assert StaticSolver(model, max_iterations=np.int64(5)).max_iterations == 5


@pytest.mark.parametrize(
    "control", ["abc", [1j, 0.0], np.zeros((2, 2)), [[1.0], [2.0, 3.0]], [0.5]]
)
def test_bad_commands_raise_model_errors(control) -> None:
    model = two_cable_beam()
    with pytest.raises(ModelError):
        ImplicitEuler(model, 0.01).step(model.rest_state(), control)


@pytest.mark.parametrize(
    ("control", "error"),
    [
        (InverseControl(regularisation=-1.0), ModelError),
        (InverseControl(regularisation=float("nan")), ModelError),
        (InverseControl(course="medium"), ModelError),
        (InverseControl(goals=np.zeros(4)), ConstraintError),
        (InverseControl(goals=np.array(["a", "b", "c"])), ConstraintError),
    ],
)
def test_inverse_settings_are_named_not_reported_as_divergence(control, error) -> None:
    model = two_cable_beam()
    with pytest.raises(error):
        StaticSolver(model).step(model.rest_state(), control)


def test_unknown_builder_keywords_are_named() -> None:
    with pytest.raises(ModelError, match="stiffness") as info:
        robots.build("finger", stiffness=3)
    assert "young_modulus" in str(info.value)  # and the keywords it takes


# ---------------------------------------------------------------------------------------------
# The command line: one red line, exit 2 for usage, 1 for runtime; --debug for the traceback

runner = CliRunner()

USAGE_ERRORS = [
    ["run", "finger", "--duration", "nan"],
    ["run", "finger", "--duration", "-1"],
    ["run", "finger", "--frames", "-5"],
    ["run", "finger", "--solver", "static", "--dt", "0"],
    ["run", "finger", "--solver", "explicit"],
    ["run", "finger", "--out", "{file}"],
    ["run", "octopus"],
    ["inverse", "multigait"],
    ["inverse", "diamond", "--goals", "0"],
    ["inverse", "diamond", "--max-steps", "0"],
    ["bench", "--meshes", "/nonexistent", "--quick"],
    ["bench", "--repeats", "0"],
    ["bench", "--out", "{folder}"],
    [
        "condensed",
        "collect",
        "finger",
        "--out",
        "{folder}/d.h5",
        "--bounds",
        "0:1",
        "--workers",
        "-2",
    ],
    [
        "condensed",
        "collect",
        "finger",
        "--out",
        "{folder}/d.h5",
        "--bounds",
        "0:1",
        "--samples",
        "0",
    ],
    [
        "condensed",
        "collect",
        "finger",
        "--out",
        "{folder}/d.h5",
        "--bounds",
        "0:1",
        "--test-fraction",
        "nan",
    ],
    ["condensed", "collect", "finger", "--out", "{folder}/d.h5", "--bounds", "a:b"],
    ["condensed", "train", "{file}", "--out", "{folder}/m.pt", "--hidden", "abc"],
    ["condensed", "train", "{file}", "--out", "{folder}/m.pt", "--learning-rate", "nan"],
    ["condensed", "train", "{file}", "--out", "{folder}/m.pt", "--epochs", "0"],
    ["condensed", "control", "{file}", "--pid", "a,b"],
    ["condensed", "control", "{file}", "--goals", "0"],
    ["condensed", "design", "{file}", "--grid", "0,1"],
    ["condensed", "evaluate"],
    ["condensed", "design", "{file}", "--weights", "1,2,3"],
    ["condensed", "calibrate", "{file}", "--truth", "poisson_ratio=abc", "--start", "x=1"],
    ["nosuch"],
    ["reduce", "diamond", "--pod-tolerance", "2", "--out", "{folder}"],
    ["trajopt", "diamond", "--horizon", "-1", "--out", "{folder}"],
    ["trajopt", "diamond", "--backend", "torch", "--out", "{folder}"],
    ["trajopt", "diamond-mpc", "--steps", "0", "--out", "{folder}"],
    ["proxy", "calibrate", "multigait", "--trials", "0", "--out", "{folder}"],
    ["proxy", "calibrate", "octopus", "--out", "{folder}"],
    ["graph", "train", "nosuch", "--out", "{folder}"],
    ["graph", "train", "Corridor", "--config", "{file}", "--out", "{folder}"],
]

RUNTIME_ERRORS = [
    [
        "condensed",
        "collect",
        "finger",
        "--out",
        "{folder}/d.h5",
        "--bounds",
        "0:1",
        "--set",
        "stiffness=3",
    ],
    ["condensed", "train", "{file}", "--out", "{folder}/m.pt"],
    ["condensed", "evaluate", "{file}", "{file}"],
    ["condensed", "control", "{folder}/none.pt"],
    ["condensed", "verify", "{folder}/none.h5"],
]


def _invoke(args: list[str], tmp_path: Path):
    (tmp_path / "file.txt").write_text("not what the command wants")
    args = [a.format(file=tmp_path / "file.txt", folder=tmp_path) for a in args]
    return runner.invoke(app, args)


def _one_red_line(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert "Traceback" not in result.output
    assert isinstance(result.exception, SystemExit), result.exception
    return lines[0]


@pytest.mark.parametrize("args", USAGE_ERRORS, ids=" ".join)
def test_usage_errors_print_one_line_and_exit_2(args, tmp_path) -> None:
    result = _invoke(args, tmp_path)
    _one_red_line(result)
    assert result.exit_code == 2
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args", RUNTIME_ERRORS, ids=" ".join)
def test_runtime_errors_print_one_line_and_exit_1(args, tmp_path) -> None:
    result = _invoke(args, tmp_path)
    _one_red_line(result)
    assert result.exit_code == 1


def test_debug_lets_the_exception_through(tmp_path) -> None:
    result = runner.invoke(app, ["--debug", "condensed", "verify", str(tmp_path / "none.h5")])
    assert result.exit_code == 1
    assert isinstance(result.exception, PliantError)


def test_an_unexpected_exception_is_one_line_naming_it_a_bug(monkeypatch, tmp_path) -> None:
    def broken(*args, **kwargs):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(robots, "entry", broken)
    result = runner.invoke(app, ["run", "finger", "--out", str(tmp_path)])
    line = _one_red_line(result)
    assert result.exit_code == 1 and "ZeroDivisionError" in line and "--debug" in line


DOCS = ROOT / "docs" / "reliability.md"


@pytest.mark.parametrize("code", re.findall(r"```python\n(.*?)```", DOCS.read_text(), flags=re.S))
def test_the_reliability_page_examples_run(code, capsys) -> None:
    exec(compile(code, str(DOCS), "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    assert "another model" in printed[0] and "dt must be a real number" in printed[1]


@pytest.mark.parametrize(
    ("robot", "solver", "offset"),
    [
        ("diamond", "dynamic", (300.0, 0.0, 0.0)),
        ("diamond", "dynamic", (1e4, 1e4, 0.0)),
        ("diamond", "static", (300.0, 0.0, 0.0)),
        ("diamond", "static", (1e4, 1e4, 0.0)),
        ("trunk", "static", (1e4, 300.0, 0.0)),
    ],
)
def test_a_goal_out_of_reach_gives_the_closest_configuration_and_says_so(
    robot, solver, offset
) -> None:
    """Issue 22, class 7: ProxQP reported these goals PRIMAL_INFEASIBLE within a few steps,
    and the static solver's Newton iterations cycled with the QP's answer (a DivergenceError).
    The best effort moves the effector towards the goal, bounds held, and reports the goal
    out of reach once it settles."""
    from pliant.errors import UnreachableGoalWarning
    from pliant.scenario import track_goals

    model = robots.build(robot)
    rest = model.effectors[0].goals[0].copy()
    goal = rest + np.array(offset)
    step = ImplicitEuler(model, 0.01) if solver == "dynamic" else StaticSolver(model)
    with pytest.warns(UnreachableGoalWarning, match="out of reach"):
        (result,), state = track_goals(model, step, model.rest_state(), goal[None], max_steps=60)
    assert result.out_of_reach and np.all(np.isfinite(state.positions))
    moved = result.reached - rest
    assert np.dot(moved, goal - rest) > 0  # towards the goal
    assert result.error < np.linalg.norm(goal - rest)
    for actuator, force, course in zip(
        model.actuators, state.actuation, state.displacement, strict=True
    ):
        assert actuator.min_force - 1e-9 <= force <= actuator.max_force + 1e-9
        # a cable cannot push: only its largest pull is a bound it can hold (within the
        # linearisation error of a step, as in test_robots)
        assert course <= actuator.max_displacement + 0.05


def test_a_static_step_whose_inverse_problem_cycles_holds_the_actuators() -> None:
    """The Diamond's Newton iterations towards a goal 300 mm sideways stalled at a 1e-4 mm
    update, the QP's answer at each iterate moving the equilibrium; after 100 iterations the
    step raised DivergenceError. Now the actuators are held where the last iteration put them
    and Newton converges on that equilibrium, with a warning and `last_report.held`."""
    from pliant.constraints.control import InverseControl
    from pliant.errors import InverseConvergenceWarning

    model = robots.build("diamond")
    goal = model.effectors[0].goals[0] + np.array([300.0, 0.0, 0.0])
    commands = [a.value for a in model.actuators]
    solver = StaticSolver(model)
    with pytest.warns(InverseConvergenceWarning, match="best effort"):
        state = solver.step(model.rest_state(), InverseControl(goals=[goal[None]]))
    assert solver.last_report.held and np.all(np.isfinite(state.positions))
    assert solver.last_report.newton_iterations < solver.max_iterations
    assert [a.value for a in model.actuators] == commands  # the model's commands are kept


def test_unknown_roles_and_infinite_lower_bounds_are_named() -> None:
    from pliant.constraints.base import EmbeddedPoints
    from pliant.constraints.cable import CableActuator

    model = two_cable_beam()
    problem = StaticSolver(model).condense(model.rest_state())
    assert problem.block("effector", "actuator").shape == (3, 2)
    with pytest.raises(ConstraintError, match="no constraint role 'motor'"):
        problem.block("motor", "actuator")
    mesh = box_beam(60.0, 10.0, 10.0, 12, 2, 2)
    points = EmbeddedPoints(mesh, [[20.0, 5.0, 5.0], [59.0, 5.0, 5.0]])
    for bounds in ({"min_force": np.inf}, {"max_displacement": -np.inf}):
        with pytest.raises(ConstraintError, match="admits no finite"):
            CableActuator(points, mesh.points, pull_point=[-10.0, 5.0, 5.0], **bounds)


@pytest.mark.parametrize(
    ("keyword", "value"),
    [
        ("mesh", "x"),
        ("length", None),
        ("height", "x"),
        ("joint_height", [1.0, 2.0]),
        ("resolution", [1.0]),
        ("material", "rubber"),
        ("gravity", (0.0, 0.0)),
        ("gravity", "xyz"),
        ("max_cable_displacement", [1.0, 2.0]),
        ("length", 1e30),
    ],
)
def test_builder_keywords_of_the_wrong_type_are_named(keyword, value) -> None:
    """Checked against the builder's type hints before anything is meshed; a builder that
    fails on a value of the right type (1e30 mm: gmsh cannot mesh it) is a ModelError too."""
    with pytest.raises(ModelError, match=keyword if value != 1e30 else "cannot be built"):
        robots.build("finger", **{keyword: value})


def test_a_static_step_whose_feedback_control_diverges_holds_the_start() -> None:
    """A feedback control whose answer inverts elements (a pull the bounds allow) does not end
    the static step in a DivergenceError: the actuators are held where the step started."""
    from pliant.errors import InverseConvergenceWarning
    from tests.conftest import two_cable_beam

    class Yank:
        """Pulls the top cable with a force no beam can take."""

        roles = ("actuator",)

        def prepare(self, model) -> None:
            pass

        def actuation(self, problem, model, state) -> np.ndarray:
            return np.array([1e9, 0.0])

    model = two_cable_beam()
    start = StaticSolver(model).step(model.rest_state(), [0.5, 0.0])
    solver = StaticSolver(model)
    with pytest.warns(InverseConvergenceWarning, match="held where the step started"):
        state = solver.step(start, Yank())
    assert solver.last_report.held
    np.testing.assert_allclose(state.positions, start.positions, atol=1e-6)
    np.testing.assert_allclose(state.displacement, start.displacement, atol=1e-9)


@pytest.mark.parametrize(
    ("option", "named"),
    [
        (["--env-kwarg", "bogus=3"], "bogus"),
        (["--hyper", "batch_size=abc"], "batch_size"),
        (["--hyper", "learning_rate=-1"], "learning_rate"),
    ],
)
def test_training_options_refused_by_the_environment_or_sb3_are_named(
    option, named, tmp_path
) -> None:
    """The re-run of issue 22 found these: a worker's traceback and 'Connection reset by
    peer' for an unknown environment keyword, 'unexpected TypeError/ValueError' for SB3's."""
    args = ["train", "pliant-test/PointReach-v0", *option, "--steps", "64"]
    result = runner.invoke(app, [*args, "--out", str(tmp_path / "run")])
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert lines[-1].startswith("error: ") and named in lines[-1] and "bug" not in lines[-1]


def test_a_bad_environment_action_is_a_pliant_error_and_gymnasiums() -> None:
    import gymnasium as gym

    from pliant.envs import make

    env = make("pliant/Diamond-v0")
    env.reset(seed=0)
    for action in (np.nan, "left", np.zeros(3)):
        with pytest.raises(PliantError) as info:
            env.step(action)
        assert isinstance(info.value, gym.error.InvalidAction)


REPRODUCIBLE_PUSH = """
import hashlib, json, sys, warnings
import numpy as np
from pliant._proxsuite import BUILD
from pliant.robots.trunk_cube import PushControl, trunk_push
from pliant.solvers import ImplicitEuler

junk = [np.empty(int(n)) for n in np.random.default_rng(SEED).integers(1, 5000, 40)]
model = trunk_push()
solver = ImplicitEuler(model, 0.01)
state = model.rest_state()
control = PushControl(state.rigid_positions[0] + np.array([3.0, 0.0, 0.0]))
warnings.simplefilter("ignore")
for _ in range(10):
    state = solver.step(state, control)
digest = hashlib.sha256(state.positions.tobytes() + state.actuation.tobytes()).hexdigest()
print(json.dumps({"build": BUILD, "digest": digest}))
"""


def test_an_inverse_qp_trajectory_through_contacts_is_the_same_in_every_process() -> None:
    """Ten steps of the Trunk pushing its cube by the QPCC (one ProxQP solve per active-set
    round), in three fresh interpreters whose memory is laid out differently: the same state,
    bit for bit. With proxsuite's AVX-512 build (what it loads by itself on this machine) the
    three runs ended on three different states (measured, PLIANT_PROXSUITE_SIMD=1): its dense
    reductions follow the data's alignment. Pliant loads the baseline build
    (pliant._proxsuite)."""
    runs = [run_isolated(REPRODUCIBLE_PUSH.replace("SEED", str(seed)))[0] for seed in range(3)]
    assert {r["build"] for r in runs} == {"proxsuite_pywrap"}
    assert len({r["digest"] for r in runs}) == 1


def test_proxsuite_imported_before_pliant_keeps_its_build() -> None:
    """A program that imports proxsuite itself before Pliant keeps the build proxsuite chose
    (loading a second one would end the interpreter: nanobind refuses the duplicate types), and
    Pliant reports it."""
    code = "import proxsuite\nfrom pliant._proxsuite import BUILD, proxqp\n"
    code += "import json; print(json.dumps({'build': BUILD, 'same': proxqp is proxsuite.proxqp}))"
    (out,) = run_isolated(code)
    assert out["same"]
    assert out["build"].startswith("proxsuite_pywrap")


def test_a_proxsuite_without_its_baseline_build_still_loads() -> None:
    """Where proxsuite ships no baseline build, Pliant imports it as proxsuite would (its
    vectorised build) instead of failing."""
    probe = "import json, proxsuite.instructionset as i; print(json.dumps({'avx2': i.has_AVX2()}))"
    if not run_isolated(probe)[0]["avx2"]:
        pytest.skip("this CPU runs no vectorised proxsuite build to fall back on")
    code = """
        import importlib, json
        real = importlib.import_module
        def without_baseline(name, package=None):
            if (name, package) == (".proxsuite_pywrap", "proxsuite"):
                raise ModuleNotFoundError("no baseline build (simulated)")
            return real(name, package)
        importlib.import_module = without_baseline
        from pliant._proxsuite import BUILD, proxqp
        qp = proxqp.dense.QP(1, 0, 0)
        print(json.dumps({"build": BUILD}))
    """
    (out,) = run_isolated(code)
    assert out["build"].startswith("proxsuite_pywrap_")


def _contradiction(n: int = 40):
    """A QP whose two inequalities, a.x >= 1 and a.x <= 0.999, have no common point: ProxQP
    with Pliant's tight certificates runs out its iterations on it without certifying."""
    rng = np.random.default_rng(0)
    m = rng.standard_normal((n, n))
    a = rng.standard_normal(n)
    free = np.full(n, 1e20)
    return (
        m @ m.T / n + 1e-3 * np.eye(n),
        rng.standard_normal(n),
        None,
        None,
        np.vstack([a, a]),
        np.array([1.0, -1e20]),
        np.array([1e20, 0.999]),
        -free,
        free,
    )


def test_an_infeasible_qp_is_found_after_the_first_attempt_not_the_full_one() -> None:
    """ProxQP's certificates are too tight to fire here (a full attempt: 1000 iterations,
    unsolved, uncertified); the solve stops after its first bounded attempt, on HiGHS's
    verdict."""
    from pliant.constraints import inverse

    full = inverse._proxqp(_contradiction(), 1e-9, 1000, None)
    assert not full.solved and not full.infeasible and full.iterations == 1000
    res = inverse._solve_qp(*_contradiction(), 1e-9, 1000)
    assert not res.solved and res.infeasible
    assert res.iterations <= inverse.FIRST_OUTER * inverse.FIRST_INNER


def test_a_feasible_qp_past_the_first_attempt_is_solved_by_the_full_one(monkeypatch) -> None:
    """With a first attempt of one iteration, which cannot solve it, a feasible QP is still
    solved, to the answer of one full attempt, bit for bit."""
    from pliant.constraints import inverse

    data = list(_contradiction())
    data[6] = np.array([1e20, 1.5])  # 1 <= a.x <= 1.5: feasible
    full = inverse._proxqp(tuple(data), 1e-9, 1000, None)
    assert full.solved
    monkeypatch.setattr(inverse, "FIRST_OUTER", 1)
    res = inverse._solve_qp(*data, 1e-9, 1000)
    assert res.solved and np.array_equal(res.x, full.x)
