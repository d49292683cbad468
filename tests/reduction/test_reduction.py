"""Model order reduction (pliant.reduction): the reduced step against the full one, ECSW
against its training forces, the reduced tangent against differences of the reduced forces,
a nearby load case, the snapshot file (serial, parallel, on Ray, interrupted) and bad input."""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.cavity import CavityActuator
from pliant.constraints.contact import Contacts
from pliant.errors import ReductionError, SolverError
from pliant.fem.body import TetBody
from pliant.fem.material import NeoHookean
from pliant.fem.membrane import Membrane
from pliant.geometry.collision import Plane
from pliant.mesh import box_beam
from pliant.model import Model
from pliant.reduction import (
    IntegrationDomain,
    LoadCase,
    ReducedImplicitEuler,
    ReducedModel,
    Selection,
    full_basis,
    greedy_nnls,
    hyper_reduce,
    kernels,
    pod,
    snapshots,
)
from pliant.reduction.cavity import CavityPolynomial, WallCavity, reduced_cavity
from pliant.reduction.ecsw import membrane_contributions, tet_contributions
from pliant.reduction.pipeline import RampedCommands, build
from pliant.solvers import ImplicitEuler


def beam(*, cells: tuple[int, int, int] = (6, 2, 2), floor: float | None = None) -> Model:
    """A Neo-Hookean cantilever (60 x 20 x 20 mm) under gravity with a membrane on its
    underside and a cable along its top; optionally a floor `floor` mm below it."""
    mesh = box_beam(60.0, 20.0, 20.0, *cells)
    x = mesh.points
    triangles = mesh.boundary_triangles()
    underside = triangles[np.all(x[triangles][:, :, 2] < 1e-9, axis=1)]
    body = TetBody(
        mesh,
        NeoHookean(200.0, 0.45),
        density=1e-6,
        fixed_nodes=np.flatnonzero(x[:, 0] < 1e-9),
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=0.1,
        rayleigh_stiffness=0.1,
        membranes=[Membrane(x, underside, stretch_stiffness=1000.0, poisson_ratio=0.3)],
    )
    points = EmbeddedPoints(
        mesh, np.array([[10.0, 10.0, 15.0], [30.0, 10.0, 15.0], [55.0, 10, 15]])
    )
    cable = CableActuator(points, x, pull_point=np.array([-5.0, 10.0, 15.0]), name="cable")
    contacts = (
        Contacts([Plane(point=(0.0, 0.0, -floor))], friction=0.5, margin=2.0)
        if floor is not None
        else None
    )
    return Model(body, actuators=[cable], contacts=contacts, name="beam")


def pull(level: float, ramp: int = 20):
    """Cable shortening ramped to `level` mm over `ramp` steps of 0.01 s, then held."""
    return lambda t: np.array([level * min(1.0, t / (0.01 * ramp) + 1e-9)])


def trajectory(solver, state, commands, steps: int) -> list:
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(steps):
            state = solver.step(state, commands(state.time))
            out.append(state)
    return out


@pytest.fixture(scope="module")
def trained():
    """A beam, its snapshots under a 2 mm cable pull, and a reduced model of them."""
    model = beam()
    states = trajectory(ImplicitEuler(model, 0.01), model.rest_state(), pull(2.0), 60)
    positions = np.array([s.positions for s in states])
    reduced = build(model, positions, pod_tolerance=1e-5, tau=1e-3, tau_membrane=1e-3)
    return model, positions, reduced


@pytest.mark.parametrize("floor", [None, 0.2])
def test_every_mode_and_element_reproduce_the_full_step(floor):
    # Phi = I on the free DoFs and xi = 1 on every element: the reduced step is the full
    # step written in other coordinates, so both agree to round-off (fresh tangents, and the
    # full solver's unscreened contact path, which solves the same W and delta_free).
    model = beam(floor=floor)
    full = ImplicitEuler(
        model, 0.01, tangent="fresh", point_compliance=False, contact_screening=False
    )
    reduced = ReducedImplicitEuler(model, full_basis(model.body), None, 0.01, tangent="fresh")
    # With the floor the cable is slack and the beam sags onto it.
    commands = pull(1.0 if floor is None else 0.0)
    a = trajectory(full, model.rest_state(), commands, 30)
    b = trajectory(reduced, reduced.rest_state(), commands, 30)
    moved = np.abs(a[-1].positions - model.body.rest_positions).max()
    assert moved > 0.1
    for s, r in zip(a, b, strict=True):
        np.testing.assert_allclose(r.positions, s.positions, rtol=0, atol=1e-10 * moved)
        np.testing.assert_allclose(r.actuation, s.actuation, rtol=1e-9, atol=1e-12)
    if floor is not None:  # the sagging tip rests on the floor
        assert np.abs(a[-1].contact_forces.forces).max() > 0
        np.testing.assert_allclose(
            b[-1].contact_forces.forces, a[-1].contact_forces.forces, rtol=1e-6, atol=1e-12
        )


def test_contact_compliance_lets_a_contact_give_way_by_its_fraction():
    """With every mode, the beam sagging on the floor: a relative contact compliance c lets
    each contact sink by about c times its mean response, and c = 0 is the contact law."""
    model = beam(floor=0.2)
    basis = full_basis(model.body)
    runs = {}
    for c in (0.0, 1e-2):
        solver = ReducedImplicitEuler(model, basis, None, 0.01, contact_compliance=c)
        runs[c] = trajectory(solver, solver.rest_state(), pull(0.0), 30)[-1]
    floor_z = model.contacts.points.positions(runs[0.0].positions)[:, 2].min()
    soft_z = model.contacts.points.positions(runs[1e-2].positions)[:, 2].min()
    assert np.abs(runs[1e-2].contact_forces.forces).max() > 0
    assert soft_z < floor_z  # the compliant contact gives way
    assert floor_z - soft_z < 0.05 * np.ptp(model.body.rest_positions[:, 2])
    with pytest.raises(SolverError, match="contact compliance"):
        ReducedImplicitEuler(model, basis, None, 0.01, contact_compliance=-1.0)


def test_ecsw_weights_reproduce_the_training_forces_within_tau(trained):
    model, positions, reduced = trained
    basis, domain = reduced.basis, reduced.domain
    projected = np.array([basis.positions(basis.coordinates(q)) for q in positions])
    pick = np.unique(np.linspace(0, len(positions) - 1, 40).round().astype(int))
    parts = [
        (tet_contributions(model.body, basis, projected[pick]), domain.tets, 1e-3),
        (
            membrane_contributions(model.body.membranes[0].membrane, basis, projected[pick]),
            domain.membranes[0],
            1e-3,
        ),
    ]
    for g, selection, tau in parts:
        exact = g.sum(axis=2)  # (s, r): every element, weight 1
        weighted = np.einsum("sre,e->sr", g[:, :, selection.elements], selection.weights)
        assert np.linalg.norm(weighted - exact) <= tau * np.linalg.norm(exact)
        assert np.all(selection.weights > 0)
        assert selection.elements.size < g.shape[2]
    assert domain.tets.elements.size < model.body.n_elements / 2


def test_compiled_membrane_kernel_matches_its_definition(rng):
    model = beam()
    membrane = model.body.membranes[0].membrane
    x = model.body.rest_positions + rng.normal(scale=1.0, size=model.body.rest_positions.shape)
    forces, energy = membrane.element_forces(x)
    t = len(membrane.triangles)
    f, k = np.empty((t, 9)), np.empty((t, 9, 9))
    e = kernels.membrane_forces_tangent(
        x, membrane.triangles, membrane.grads, membrane.areas, membrane.mu, membrane.lam, f, k
    )
    np.testing.assert_allclose(f, forces.reshape(t, 9), rtol=1e-12, atol=1e-12 * np.abs(f).max())
    np.testing.assert_allclose(k, membrane.element_stiffness(x), rtol=1e-12, atol=1e-9)
    assert e == pytest.approx(energy, rel=1e-12)


@pytest.mark.parametrize("kind", [CavityPolynomial, WallCavity])
def test_reduced_cavity_is_the_volume_on_the_basis(kind, rng):
    """Both evaluations of a cavity's row (the exact cubic polynomial of alpha, the compiled
    kernels on the walls) equal the walls' volume at q0 + Phi alpha and dV/dq Phi, to
    round-off, far from the rest shape."""
    cube = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    cavity = CavityActuator(cube.boundary_triangles(), cube.points)
    n, r = cube.points.shape[0], 7
    modes = np.linalg.qr(rng.normal(size=(3 * n, r)))[0].reshape(n, 3, r)
    reduced = kind(cavity.triangles, cube.points, modes)
    assert reduced.rest_volume == pytest.approx(cavity.rest_volume, rel=1e-13)
    for scale in (0.1, 3.0):
        alpha = rng.normal(scale=scale, size=r)
        y = cube.points + modes @ alpha
        change, gradient = reduced.change_and_gradient(alpha, y)
        assert change + reduced.rest_volume == pytest.approx(cavity.volume(y), rel=1e-12)
        assert reduced.change(alpha, y) == pytest.approx(change, rel=1e-12, abs=1e-12)
        jac = cavity.jacobian(y)
        dv = np.zeros((n, 3))
        np.add.at(dv, jac.nodes.reshape(-1), jac.values.reshape(-1, 3))
        expected = dv.reshape(-1) @ modes.reshape(-1, r)
        scale_g = np.abs(expected).max()
        np.testing.assert_allclose(gradient, expected, rtol=1e-11, atol=1e-11 * scale_g)


def test_the_cheaper_cavity_evaluation_is_chosen(rng):
    cube = box_beam(10.0, 10.0, 10.0, 2, 2, 2)
    cavity = CavityActuator(cube.boundary_triangles(), cube.points)
    n = cube.points.shape[0]
    wall = np.unique(cavity.triangles).size
    few = rng.normal(size=(n, 3, 2))
    many = rng.normal(size=(n, 3, int(np.sqrt(3 * wall)) + 1))
    assert isinstance(reduced_cavity(cavity, cube.points, few), CavityPolynomial)
    assert isinstance(reduced_cavity(cavity, cube.points, many), WallCavity)


def test_greedy_nnls_stops_at_its_tolerance_with_non_negative_weights(rng):
    g = rng.random((60, 200))
    b = g @ np.where(rng.random(200) < 0.05, rng.random(200), 0.0)
    for tau in (0.1, 0.01, 1e-4):
        s = greedy_nnls(g, b, tau)
        assert np.all(s.weights >= 0)
        assert np.linalg.norm(g[:, s.elements] @ s.weights - b) <= tau * np.linalg.norm(b)
        assert s.error <= tau


def test_reduced_tangent_is_the_derivative_of_the_reduced_forces(trained):
    # K_r = -d f_r / d alpha (central differences, error O(eps^2)) on the hyper-reduced
    # tetrahedra at a bent configuration of the training run. The membrane's tangent drops
    # the compressive part of its stress (pliant.fem.membrane), so it is checked against the
    # body's own assembled tangent instead: with every element, K_r = Phi^T K Phi.
    model, positions, reduced = trained
    body, basis = model.body, reduced.basis
    alpha = basis.coordinates(positions[-1])
    no_triangle = Selection(np.zeros(0, dtype=np.int64), np.zeros(0))
    tets_only = IntegrationDomain(reduced.domain.tets, (no_triangle,))
    solver = ReducedImplicitEuler(model, basis, tets_only)
    k = solver.stiffness(alpha)
    eps = 1e-6 * max(1.0, np.abs(alpha).max())
    columns = [
        -(solver.internal_forces(alpha + eps * e) - solver.internal_forces(alpha - eps * e))
        / (2 * eps)
        for e in np.eye(alpha.size)
    ]
    np.testing.assert_allclose(np.array(columns).T, k, rtol=0, atol=1e-6 * np.abs(k).max())
    every = ReducedImplicitEuler(model, basis)
    phi = body.gather(basis.modes)
    projected = phi.T @ (body.stiffness_matrix(body.linearise(basis.positions(alpha))) @ phi)
    np.testing.assert_allclose(every.stiffness(alpha), projected, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(
        every.internal_forces(alpha),
        phi.T @ body.gather(body.linearise(basis.positions(alpha)).forces),
        rtol=1e-10,
        atol=1e-10,
    )


def test_a_nearby_load_case_is_reproduced(trained):
    # Trained on a 2 mm pull ramped over 0.2 s; tested on 1.6 mm over 0.3 s: every node
    # within 2 % of the largest displacement of the full model, all along the run (measured:
    # 0.8 % with 7 modes, 17 of 144 tetrahedra and 12 of 24 triangles).
    model, _, reduced = trained
    solver = reduced.solver(model)
    full = trajectory(ImplicitEuler(model, 0.01), model.rest_state(), pull(1.6, 30), 60)
    mor = trajectory(solver, solver.rest_state(), pull(1.6, 30), 60)
    scale = max(np.abs(s.positions - model.body.rest_positions).max() for s in full)
    worst = max(np.abs(r.positions - s.positions).max() for s, r in zip(full, mor, strict=True))
    assert worst < 0.02 * scale
    assert reduced.metadata["tets_selected"] < model.body.n_elements


def test_snapshots_resume_after_an_interruption(tmp_path):
    model = beam()
    case = LoadCase("pull", pull(1.0), 0.2)

    def stop(name, step, steps):
        if step == 10:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        snapshots.collect(model, [case], tmp_path / "s.h5", every=2, progress=stop)
    snapshots.collect(model, [case], tmp_path / "s.h5", every=2)
    snapshots.collect(model, [case], tmp_path / "once.h5", every=2)
    times, resumed = snapshots.load(tmp_path / "s.h5", model)["pull"]
    _, once = snapshots.load(tmp_path / "once.h5", model)["pull"]
    np.testing.assert_allclose(times, 0.02 * np.arange(1, 11))
    # The lagged tangent restarts at every record: the resumed case is the same, bit for bit.
    np.testing.assert_array_equal(resumed, once)
    assert not (tmp_path / "s.h5.parts" / "pull").exists()  # the records are deleted


# Three load cases on the beam resting on a floor (contact forces in the checkpoints), their
# commands values that pickle: cable pulls ramped over 0.1 s and held 0.1 s.
PULLS = [
    LoadCase(f"pull_{level}", RampedCommands([np.array([level])] * 2, 0.1), 0.2)
    for level in (0.5, 1.0, 1.5)
]


def file_contents(path: Path) -> dict:
    """Every dataset's values and every attribute of an HDF5 file, by name."""
    h5py = pytest.importorskip("h5py")
    out = {}
    with h5py.File(path, "r") as f:

        def visit(name, item):
            out.update({f"{name}@{key}": value for key, value in item.attrs.items()})
            if isinstance(item, h5py.Dataset):
                out[name] = item[()]

        f.visititems(visit)
    return out


def assert_same_file(a: Path, b: Path) -> None:
    found, wanted = file_contents(a), file_contents(b)
    assert sorted(found) == sorted(wanted)
    for name, value in wanted.items():
        np.testing.assert_array_equal(found[name], value, err_msg=name)


@pytest.fixture(scope="module")
def serial_pulls(tmp_path_factory) -> Path:
    """PULLS collected in this process, in one go."""
    path = tmp_path_factory.mktemp("serial") / "s.h5"
    return snapshots.collect(beam(floor=0.2), PULLS, path, every=3)


def test_parallel_snapshots_equal_serial_ones_bit_for_bit(serial_pulls, tmp_path):
    path = snapshots.collect(beam(floor=0.2), PULLS, tmp_path / "p.h5", every=3, workers=2)
    assert_same_file(path, serial_pulls)


def test_an_interrupted_parallel_collection_resumes_to_the_same_file(serial_pulls, tmp_path):
    model, path, written = beam(floor=0.2), tmp_path / "p.h5", []

    def stop(name, step, steps):
        written.append(name)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        snapshots.collect(model, PULLS, path, every=3, workers=2, progress=stop)
    assert len(written) == 1
    snapshots.collect(
        model, PULLS, path, every=3, workers=2, progress=lambda name, *_: written.append(name)
    )
    assert written[0] not in written[1:]  # a finished case is not collected again
    assert_same_file(path, serial_pulls)


def test_a_serial_collection_cut_mid_case_resumes_on_workers_to_the_same_file(
    serial_pulls, tmp_path
):
    model, path = beam(floor=0.2), tmp_path / "p.h5"

    def stop(name, step, steps):
        if name == PULLS[1].name and step == 12:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        snapshots.collect(model, PULLS, path, every=3, progress=stop)
    # The unfinished case runs again from rest on a worker (not from its checkpoint).
    snapshots.collect(model, PULLS, path, every=3, workers=2)
    assert_same_file(path, serial_pulls)


def test_a_finished_case_that_fails_its_checksum_is_collected_again(serial_pulls, tmp_path):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "s.h5"
    path.write_bytes(serial_pulls.read_bytes())
    with h5py.File(path, "r") as f:
        chunk = f[f"cases/{PULLS[1].name}/positions"].id.get_chunk_info(2)
    with path.open("r+b") as raw:  # flip bytes inside one recorded configuration
        raw.seek(chunk.byte_offset + 40)
        raw.write(b"\xff" * 8)
    with pytest.warns(snapshots.CorruptCaseWarning, match=PULLS[1].name):
        snapshots.collect(beam(floor=0.2), PULLS, path, every=3)
    assert_same_file(path, serial_pulls)


def test_ray_tasks_give_the_same_snapshots(serial_pulls, tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is not installed (optional extra pliant[ray])")
    try:
        path = snapshots.collect(
            beam(floor=0.2), PULLS, tmp_path / "r.h5", every=3, workers=2, ray_address="local"
        )
    finally:
        ray.shutdown()
    assert_same_file(path, serial_pulls)


def test_local_workers_need_commands_that_pickle(tmp_path):
    with pytest.raises(ReductionError, match="do not pickle"):
        snapshots.collect(beam(), [LoadCase("pull", pull(1.0), 0.02)], tmp_path / "s.h5", workers=2)
    with pytest.raises(ReductionError, match="workers"):
        snapshots.collect(beam(), PULLS, tmp_path / "s.h5", workers=0)


def test_save_and_load_keep_the_reduced_model(trained, tmp_path):
    model, _, reduced = trained
    path = reduced.save(tmp_path / "beam.npz")
    again = ReducedModel.load(path, model)
    np.testing.assert_array_equal(again.basis.modes, reduced.basis.modes)
    np.testing.assert_array_equal(again.domain.tets.weights, reduced.domain.tets.weights)
    assert again.metadata["n_modes"] == reduced.basis.n_modes
    s = reduced.solver(model).step(reduced.solver(model).rest_state(), [0.5])
    t = again.solver(model).step(again.solver(model).rest_state(), [0.5])
    np.testing.assert_array_equal(s.coordinates, t.coordinates)


def test_bad_input_raises_clear_errors(trained, tmp_path):
    model, positions, reduced = trained
    other = beam(cells=(7, 2, 2))
    with pytest.raises(ReductionError, match="another mesh"):
        ReducedModel.load(reduced.save(tmp_path / "beam.npz"), other)
    with pytest.raises(ReductionError, match="modes of shape"):
        ReducedImplicitEuler(other, reduced.basis)
    bad = positions.copy()
    bad[3, 5, 1] = np.nan
    with pytest.raises(ReductionError, match="NaN"):
        pod(model.body, bad)
    with pytest.raises(ReductionError, match="positions or displacements"):
        pod(model.body, positions[:, :-1])
    for tau in (0.0, 1.0, -0.1, np.nan):
        with pytest.raises(ReductionError, match=r"\(0, 1\)"):
            hyper_reduce(model.body, reduced.basis, positions, tau=tau)
    with pytest.raises(ReductionError, match="held nodes"):
        pod(model.body, positions, translation=True)
    path = snapshots.collect(model, [LoadCase("rest", pull(0.0), 0.02)], tmp_path / "s.h5")
    with pytest.raises(ReductionError, match="fingerprint"):
        snapshots.collect(other, [], path)
    with pytest.raises(ReductionError, match="another mesh"):
        snapshots.load(path, other)


DOCS = Path(__file__).parents[2] / "docs" / "reduction.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOCS.read_text(), flags=re.S)


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block{i}" for i in range(len(BLOCKS))])
def test_docs_example_runs(code):
    exec(compile(code, str(DOCS), "exec"), {})


def test_cli_reduces_a_robot_and_reports(tmp_path):
    from typer.testing import CliRunner

    from pliant.cli import app

    # The load cases on two local workers: the scripted and ramped commands pickle.
    args = ["reduce", "finger", "--duration", "0.2", "--phase", "0.1", "--check", "0.1"]
    args += ["--workers", "2"]
    result = CliRunner().invoke(app, [*args, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "finger" / "report.json").read_text())
    assert report["n_modes"] >= 1 and 0 < report["tets_selected"] < report["tets_total"]
    # Within its training script (measured: 0.06 % of the finger's size over 0.1 s).
    assert report["max_error_pct_size"] < 0.5
    assert (tmp_path / "finger" / "reduced.npz").exists()
    bad = CliRunner().invoke(app, ["reduce", "finger", "--tau", "1.5", "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "(0, 1)" in bad.output  # a usage error, before work
