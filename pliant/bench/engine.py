"""``pliant bench``: steps per second beside SOFA's figures measured on this kind of machine.

Scenes follow SPEC §5 ("SOFA measured on this machine"): same meshes (the reference SOFA meshes,
read from ``--meshes``), same materials, dt = 0.01, implicit Euler, fixed base; "cables" adds the
constraint solve with the cables in displacement mode. Every figure is the median over
``repeats`` timed runs measured in this one process, one scene after the other. A scene timed
beside a SOFA figure is timed as SOFA's batch runner timed it: each run from rest with a new
solver, its first factorisation included (a few untimed steps of another solver first warm the
process: compilation); the other scenes are timed from the state after their warm-up. The
MuJoCo flex peer (:mod:`pliant.bench.mujoco_peer`, optional) races the cantilevers in the same
run, interleaved with Pliant.
"""

from __future__ import annotations

import json
import os
import platform
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from pliant import __version__, robots
from pliant.bench.host import host
from pliant.bench.mujoco_peer import mujoco_available, race
from pliant.bench.profile import PARTS, batch_throughput, default_error, step_breakdown
from pliant.bench.sofa_scenes import SOFA_SCENES, TRUNK_CUBE_WARMUP, sofa_scene, trunk_cables_cube
from pliant.bench.timing import POLICY_OPTIONS, Measurement, time_steps
from pliant.constraints.control import InverseControl
from pliant.fem.body import TetBody, nodes_in_box
from pliant.fem.material import Corotational
from pliant.mesh import box_beam, load_mesh
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model
from pliant.solvers import ImplicitEuler, StaticSolver

# SOFA master (Aug 2026) + SoftRobots, Release -O3, single-threaded batch runner, re-measured on
# this machine kind on 2026-11-25 (SPEC §5; a build about 2x faster than the first figures).
# The Trunk pushing a cube is SOFA's sofa-reference/trunk_cables_cube.scn, which Pliant runs
# through its scene loader.
SOFA_STEPS_PER_S = {
    "diamond": 87.9,
    "diamond+cables": 85.8,
    "trunk": 243.8,
    "trunk+cables": 211.7,
    "multigait": 1.22,
    "cantilever-240": 2432.0,
    "cantilever-1920": 158.7,
    "cantilever-15360": 3.97,
    "cantilever-51840": 0.24,
    "trunk+cables+cube": 16.2,
}
# SOFA's trunk_cables.scn, the scene of the Trunk's "with cables" figure: cable L0 pulled 10 mm.
TRUNK_CABLES = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
# The cantilevers the MuJoCo flex peer races (240, 1 920 and 15 360 tets; quick: the first).
PEER_SIZES = (2, 4, 8)
# Thesis Fig. 5.5 / Table 5.2 (SOFA, the thesis' machine), frames/s of the Soft Finger.
THESIS_FINGER_FPS = {"coarse": 32.6, "fine": 4.8, "superfine": 1.8}


def _default_meshes() -> Path | None:
    for cand in (os.environ.get("PLIANT_REFERENCE_MESHES"), "../shared/meshes", "shared/meshes"):
        if cand and Path(cand, "Diamond_siliconeV0.vtu").is_file():
            return Path(cand)
    return None


def _placed(mesh: TetMesh, rotation: np.ndarray, shift: tuple[float, float, float]) -> TetMesh:
    return TetMesh(mesh.points @ rotation.T + np.asarray(shift), mesh.tets)


def reference_diamond(meshes: Path) -> TetMesh:
    """The SoftRobots Diamond mesh as its scene places it: 90 degrees about x, +35 mm in z."""
    rot = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return _placed(load_mesh(meshes / "Diamond_siliconeV0.vtu"), rot, (0.0, 0.0, 35.0))


def cantilever(n: int) -> Model:
    """SPEC §5 cantilever: 100 x 20 x 20 mm, 5n x n x n cubes of 6 tets, E=1000, nu=0.45."""
    mesh = box_beam(100.0, 20.0, 20.0, nx=5 * n, ny=n, nz=n)
    fixed = np.flatnonzero(mesh.points[:, 0] <= 1e-9)
    return _corotational(mesh, 1000.0, 0.04, fixed, f"cantilever-{mesh.n_tets}")


def multigait(meshes: Path) -> Model:
    """SPEC §5 Multigait body: E=70, nu=0.45, 0.035 kg, centre fixed, gravity."""
    mesh = load_mesh(meshes / "MultiGaitRobot_full_quadriped_fine.vtk")
    c = mesh.points.mean(axis=0)
    fixed = nodes_in_box(mesh.points, [c - [10.0, 10.0, 50.0], c + [10.0, 10.0, 50.0]])
    return _corotational(mesh, 70.0, 0.035, fixed, "multigait")


def _corotational(mesh: TetMesh, young: float, mass: float, fixed, name: str) -> Model:
    """SPEC §5's bare bodies: corotational, nu = 0.45, uniform mass, gravity along -z."""
    body = TetBody(
        mesh,
        Corotational(young, 0.45),
        total_mass=mass,
        mass="uniform",
        fixed_nodes=fixed,
        gravity=(0.0, 0.0, -9810.0),
    )
    return Model(body, name=name)


def multigait_on_floor(meshes: Path) -> Model:
    """The Multigait scene: reference mesh, its five chambers (walls found from the scene's
    cavity surfaces), the floor touched by the scene's collision-surface vertices."""
    import warnings

    import meshio

    from pliant.mesh.multigait import reference_cavity_surfaces
    from pliant.robots.multigait import multigait as multigait_robot

    stems = {
        "centre": "Center",
        "front_left": "Front-Left",
        "front_right": "Front-Right",
        "rear_left": "Rear-Left",
        "rear_right": "Rear-Right",
    }
    mesh = load_mesh(meshes / "MultiGaitRobot_full_quadriped_fine.vtk")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # meshio's binary-STL size check overflows
        surfaces = {
            name: meshio.read(meshes / f"MultiGaitRobot_quadriped_{stem}-cavity_finer.stl")
            for name, stem in stems.items()
        }
        collision = meshio.read(meshes / "MultiGaitRobot_quadriped_collision.stl").points
    walls = reference_cavity_surfaces(
        mesh, {k: (v.points, v.cells_dict["triangle"]) for k, v in surfaces.items()}
    )
    mesh = TetMesh(mesh.points, mesh.tets, surfaces={f"cavity_{k}": v for k, v in walls.items()})
    # The material of SPEC §5's bare-body figure (corotational, E = 70, nu = 0.45), so that
    # the two Multigait rows differ only by the chambers and the floor.
    return multigait_robot(
        mesh=mesh,
        collision_points=collision,
        material="corotational",
        young_modulus=70.0,
        poisson_ratio=0.45,
        cavity_mode="pressure",
    )


def multigait_reference(meshes: Path) -> Model:
    """The SOFA reference mesh, its chambers' walls and collision points as
    :func:`multigait_on_floor` reads them, with the Multigait builder's defaults (SofaGym's
    scene: Neo-Hookean E 70 kPa, nu 0.05, volume-controlled chambers, paper membrane): the
    reduction and proxy studies' full model (experiments/reduction/, experiments/proxy/speed.py)."""
    from pliant.robots.multigait import multigait as multigait_robot

    bench = multigait_on_floor(meshes)
    points = bench.contacts.points.positions(bench.body.rest_positions)
    return multigait_robot(mesh=bench.body.mesh, collision_points=points)


def run_benchmarks(
    *,
    meshes: Path | None,
    repeats: int,
    steps: int,
    quick: bool,
    out: Path,
    console: Console,
    profile: bool = True,
    batch: tuple[int, ...] = (1, 8, 32),
) -> list[Measurement]:
    """Time every scene (see the module docstring); with `profile`, each SPEC §5 scene also
    gets the default step's error against the exact one and its time per part."""
    meshes = meshes or _default_meshes()
    results: list[Measurement] = []
    host_before = host()

    def measure(
        scene: str,
        model: Model,
        *,
        cables: np.ndarray | None = None,
        control=None,
        policies=("pcg", "lagged", "fresh"),
        n_steps: int = steps,
        warmup: int = 10,
        sofa: float | None = None,
        exact: str | None = "fresh",
        from_rest: bool | None = None,
        **extra,
    ) -> None:
        """Time `model` under each policy; with `profile`, also the default's error against
        the `exact` policy over 1 s from rest and the time per step of each part (lagged and
        exact), :mod:`pliant.bench.profile`. Timed from rest (each run with a new solver, as
        SOFA's runs) where `from_rest`, by default where a SOFA figure is given."""
        from_rest = sofa is not None if from_rest is None else from_rest
        step_control = control if callable(control) else (lambda s: control)
        analysis = {}
        if profile and exact is not None:
            if cables is not None:
                model.set_actuation(cables, mode="displacement")
            analysis["default_error"] = default_error(model, step_control, exact=exact)
            for policy in dict.fromkeys(("lagged", exact)):
                analysis[f"breakdown_{policy}"] = step_breakdown(
                    lambda p=policy: ImplicitEuler(model, 0.01, **POLICY_OPTIONS[p]),
                    model.rest_state(),
                    step_control,
                    max(n_steps, 20) if model.body.n_elements < 20000 else n_steps,
                    warmup,
                )
            err = analysis["default_error"]
            console.print(
                f"  {scene:<22} default vs {exact}: {err['error_end_mm']:.4f} mm after 1 s"
                f" ({err['error_end_percent_of_motion']:.3f} % of the"
                f" {err['motion_max_mm']:.1f} mm motion; {err['error_max_mm']:.4f} mm at most)"
            )
            for policy in dict.fromkeys(("lagged", exact)):
                b = analysis[f"breakdown_{policy}"]
                console.print(
                    f"  {'':<22} {policy:<6} ms/step: "
                    + ", ".join(f"{k} {b[k]:.3f}" for k in (*PARTS, "rest", "total"))
                    + f" ({b['factorisations_per_step']:.2f} factorisations/step)"
                )
        for policy in policies:
            if cables is not None:
                model.set_actuation(cables, mode="displacement")
            timing = time_steps(
                lambda p=policy: ImplicitEuler(model, 0.01, **POLICY_OPTIONS[p]),
                model.rest_state(),
                control if callable(control) else (lambda s: control),
                n_steps,
                repeats,
                warmup,
                from_rest=from_rest,
            )
            details = dict(extra) | analysis | {"timed_from_rest": from_rest}
            contact = ""
            if model.contacts is not None:
                details["contact_sweeps_per_step"] = timing.sweeps_per_step
                details["contact_newton_steps_per_step"] = timing.newton_steps_per_step
                details["contacts_per_step"] = timing.contacts_per_step
                details["body_contacts_per_step"] = timing.body_contacts_per_step
                details["solved_contacts_per_step"] = timing.solved_contacts_per_step
                details["contact_solves_per_step"] = timing.contact_rounds_per_step
                contact = (
                    f", {timing.sweeps_per_step:.1f} contact sweeps"
                    f" + {timing.newton_steps_per_step:.1f} Newton steps/step,"
                    f" {timing.contacts_per_step:.1f} contacts/step"
                    f" ({timing.body_contacts_per_step:.1f} on rigid bodies,"
                    f" {timing.solved_contacts_per_step:.1f} solved in"
                    f" {timing.contact_rounds_per_step:.2f} solves)"
                )
            m = Measurement(
                scene,
                model.body.n_elements,
                policy,
                statistics.median(timing.rates),
                timing.rates,
                timing.factorisations_per_step,
                None if policy == "sofa-algorithm" else sofa,
                details,
            )
            results.append(m)
            ratio = f"{m.speedup:.1f}x SOFA" if m.speedup else ""
            if "sofa_scene" in details:
                ratio += f" ({details['sofa_scene']})"
            console.print(
                f"  {scene:<22} {policy:<6} {m.steps_per_s:9.2f} steps/s"
                f"  ({timing.factorisations_per_step:.3f} factorisations/step{contact}) {ratio}"
            )

    console.print(f"[bold]pliant bench[/bold] {__version__}; reference meshes: {meshes}")
    if meshes is not None:
        dia = robots.diamond(mesh=reference_diamond(meshes))
        measure("diamond", Model(dia.body, name="diamond"), sofa=SOFA_STEPS_PER_S["diamond"])
        measure(
            "diamond+cables", dia, cables=np.full(4, 10.0), sofa=SOFA_STEPS_PER_S["diamond+cables"]
        )
        tr = robots.trunk(mesh=load_mesh(meshes / "Trunk_trunk.vtk"))
        measure("trunk", Model(tr.body, name="trunk"), sofa=SOFA_STEPS_PER_S["trunk"])
        measure(
            "trunk+cables",
            tr,
            cables=TRUNK_CABLES,
            sofa=SOFA_STEPS_PER_S["trunk+cables"],
        )
    else:
        console.print(
            "[yellow]reference meshes not found: SOFA-comparison scenes skipped"
            " (pass --meshes ../shared/meshes)[/yellow]"
        )
    sizes = (2, 4) if quick else (2, 4, 8, 12)
    for n in sizes:
        model = cantilever(n)
        big = model.body.mesh.n_tets > 20000
        measure(
            model.name,
            model,
            sofa=SOFA_STEPS_PER_S.get(model.name),
            policies=("pcg", "lagged")
            if model.body.mesh.n_tets > 5000
            else ("pcg", "lagged", "fresh"),
            n_steps=max(5, steps // (20 if big else 1)) if not big else 5,
            warmup=3 if big else 10,
            exact="pcg" if model.body.mesh.n_tets > 5000 else "fresh",
        )
    peer = mujoco_peer(PEER_SIZES[:1] if quick else PEER_SIZES, steps, repeats, console)
    for name, key in SOFA_SCENES.items() if meshes is not None else ():
        loaded = sofa_scene(meshes, name)
        if loaded is None:
            continue
        commands = loaded.commands()
        measure(
            name,
            loaded.model,
            control=lambda s, c=commands: c,
            policies=("lagged", "fresh"),
            warmup=1,  # compilation; each timed run then starts from rest with a new solver
            sofa=SOFA_STEPS_PER_S[key],
            exact=None,  # the same model's default error is reported on its SPEC row
            sofa_scene=f"SOFA's {name}, loaded, {steps} steps from rest",
        )
    if meshes is not None and not quick:
        measure(
            "multigait",
            multigait(meshes),
            sofa=SOFA_STEPS_PER_S["multigait"],
            policies=("pcg", "lagged"),
            n_steps=5,
            warmup=3,
            exact="pcg",
        )
    if meshes is not None and not quick:
        import warnings

        from pliant.errors import ContactConvergenceWarning

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactConvergenceWarning)
            scene = multigait_on_floor(meshes)
            measure(
                "multigait+cavities+floor",
                scene,
                control=np.array([0.0, 0.0, 0.0, 3.0, 3.0]),  # rear legs at 3 kPa
                sofa=SOFA_STEPS_PER_S["multigait"],
                policies=("lagged",),
                n_steps=3,
                warmup=2,
                contact_points=len(scene.contacts.points),
            )
    if not quick:
        import warnings

        from pliant.errors import ContactConvergenceWarning

        # Contact scenes under their scripted actuation, timed once contact is made.
        for name, label, warmup in (
            ("gripper", "gripper", 80),
            ("multigait", "multigait-coarse+gait", 20),
            ("cartstem_contact", "cartstem_contact", 100),
            ("trunk_cube", "trunk_cube", 100),
        ):
            entry = robots.entry(name)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ContactConvergenceWarning)
                measure(
                    label,
                    entry.build(),
                    control=lambda s, e=entry: e.demo_actuation(s.time),
                    policies=("lagged",),
                    n_steps=max(10, steps // 5),
                    warmup=warmup,
                    exact=None,  # not SPEC §5 scenes
                )
        cube_scene = trunk_cables_cube(meshes) if meshes is not None else None
        if cube_scene is not None:
            commands = cube_scene.commands()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ContactConvergenceWarning)
                measure(
                    "trunk+cables+cube",
                    cube_scene.model,
                    control=lambda s: commands,
                    policies=("lagged", "sofa-algorithm"),
                    n_steps=max(10, steps // 5),
                    warmup=TRUNK_CUBE_WARMUP,
                    from_rest=False,  # timed once the trunk pushes the cube
                    sofa=SOFA_STEPS_PER_S["trunk+cables+cube"],
                    sofa_scene="the same scene: SOFA's trunk_cables_cube.scn, loaded",
                )
    for res in ("coarse",) if quick else ("coarse", "fine", "superfine"):
        finger = robots.soft_finger(resolution=res)
        measure(
            f"finger-{res}",
            finger,
            cables=np.array([5.0, 0.0]),
            policies=("pcg", "lagged"),
            n_steps=steps if res == "coarse" else max(10, steps // 5),
            exact=None,
            thesis_sofa_fps=THESIS_FINGER_FPS[res],
        )

    # Batched stepping (N copies, one call a step) against N single solvers in a loop.
    batches = {}
    if batch:
        cases = [("cantilever-240", cantilever(2), None)]
        if meshes is not None:
            trunk = robots.trunk(mesh=load_mesh(meshes / "Trunk_trunk.vtk"))
            cases.append(("trunk+cables", trunk, TRUNK_CABLES))
        for name, model, commands in cases:
            if commands is not None:
                model.set_actuation(np.zeros_like(commands), mode="displacement")
            rows = batch_throughput(model, commands, batch, steps=max(10, steps // 4))
            batches[name] = rows
            for r in rows:
                console.print(
                    f"  batched {name:<15} N={r['copies']:<3} ({r['threads']} threads):"
                    f" {r['batched']:8.1f} copy-steps/s, N single solvers {r['single_loop']:8.1f}"
                    f" ({r['gain']:.2f}x)"
                )

    # Static solve and inverse control step on the Diamond (Pliant's mesh in quick mode).
    dia = robots.diamond(mesh=reference_diamond(meshes)) if meshes is not None else robots.diamond()
    dia.set_actuation(np.full(4, 10.0), mode="displacement")
    static_times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        st = StaticSolver(dia).step(dia.rest_state())
        static_times.append(time.perf_counter() - t0)
    console.print(
        f"  static solve (diamond, 4 cables at 10 mm):"
        f" {statistics.median(static_times) * 1e3:.1f} ms"
    )
    goal = dia.effectors[0].position(st.positions) + np.array([[5.0, 0.0, 0.0]])
    timing = time_steps(
        lambda: ImplicitEuler(dia, 0.01),
        dia.rest_state(),
        lambda s: InverseControl(goals=[goal]),
        steps,
        repeats,
        10,
    )
    inverse_ms = 1e3 / statistics.median(timing.rates)
    console.print(f"  inverse QP control step (diamond): {inverse_ms:.2f} ms")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    _print_table(results, console)
    payload = {
        "pliant_version": __version__,
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "host_before": host_before,
        "host_after": host(),
        "dt": 0.01,
        "repeats": repeats,
        "reference_meshes": str(meshes) if meshes else None,
        "scenes": [m.__dict__ | {"speedup_vs_sofa": m.speedup} for m in results],
        "static_solve_ms": statistics.median(static_times) * 1e3,
        "inverse_step_ms": inverse_ms,
        "batched": batches,
        "mujoco_flex_peer": peer,
        "peak_memory_mb": peak_mb,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".json")
    with os.fdopen(fd, "w") as fh:
        json.dump(payload, fh, indent=1)
    os.replace(tmp, out)
    _plot(results, out.with_suffix(".png"))
    console.print(
        f"host: {host_before['cpu_model']}, load {host_before['load_average_1_5_15_min'][0]}"
        f" before, {payload['host_after']['load_average_1_5_15_min'][0]} after (1 min average)"
    )
    console.print(f"peak memory {peak_mb:.0f} MB; wrote {out} and {out.with_suffix('.png')}")
    return results


def mujoco_peer(sizes, steps: int, repeats: int, console: Console) -> dict:
    """The cantilevers of `sizes` raced against MuJoCo flex in this process
    (:func:`pliant.bench.mujoco_peer.race`), or a note where MuJoCo is not installed."""
    if not mujoco_available():
        note = "MuJoCo not installed: the MuJoCo flex peer skipped (pip install 'pliant[peers]')"
        console.print(f"[yellow]{note}[/yellow]")
        return {"skipped": note}
    rows = []
    for n in sizes:
        model = cantilever(n)
        small = model.body.n_elements < 5000
        row = race(
            model,
            steps=steps if small else max(5, steps // 10),
            repeats=repeats,
            warmup=10 if small else 3,
        )
        rows.append({"scene": model.name} | row)
        tip = row["pliant_tip_displacement_mm"][2]
        for name, peer in row["mujoco"].items():
            console.print(
                f"  {model.name:<22} MuJoCo flex ({name}, cap {peer['iterations_cap']}):"
                f" {peer['steps_per_s']:8.1f} steps/s, Pliant lagged"
                f" {row['pliant_steps_per_s']:8.1f} ({peer['ratio']:.1f}x; one thread"
                f" {row['pliant_one_thread_steps_per_s']:.1f}, {peer['ratio_one_thread']:.1f}x);"
                f" tip z after {row['seconds_simulated']:g} s {peer['tip_displacement_mm'][2]:.3f}"
                f" vs {tip:.3f} mm ({peer['tip_difference_percent']:.2f} % apart);"
                f" {peer['steps_short_of_tolerance']} of"
                f" {round(row['seconds_simulated'] / 0.01)} steps short of MuJoCo's tolerance"
            )
    return {
        "method": "same process, engines interleaved within each repeat, median steps/s;"
        " Pliant's default policy (lagged) with its threads and on one, MuJoCo on one",
        "differences": "Pliant: corotational elasticity, linearly implicit Euler, sparse"
        " Cholesky; MuJoCo: Saint Venant-Kirchhoff elasticity, 'discrete' integrator (implicit"
        " in position, stiffness linearised at the step's start), matrix-free preconditioned"
        " CG to its tolerance",
        "rows": rows,
    }


def _print_table(results: list[Measurement], console: Console) -> None:
    table = Table(title="median steps/s at dt = 0.01 (Pliant vs SOFA on this machine kind)")
    policies = ("pcg", "lagged", "fresh", "sofa-algorithm")
    for col in ("scene", "tets", "SOFA", "pcg (exact)", "lagged", "fresh", "SOFA's algorithm"):
        table.add_column(col, justify="right")
    for col in ("default / SOFA", "exact / SOFA", "default error after 1 s"):
        table.add_column(col, justify="right")
    scenes = dict.fromkeys(m.scene for m in results)
    for scene in scenes:
        ms = {m.policy: m for m in results if m.scene == scene}
        any_m = next(iter(ms.values()))
        cells = [f"{ms[p].steps_per_s:.1f}" if p in ms else "-" for p in policies]
        sofa = any_m.sofa
        exact = max((ms[p].steps_per_s for p in ("pcg", "fresh") if p in ms), default=None)
        error = next(
            (m.extra["default_error"] for m in ms.values() if "default_error" in m.extra), None
        )
        table.add_row(
            scene,
            str(any_m.tets),
            f"{sofa}" if sofa else "-",
            *cells,
            f"{ms['lagged'].steps_per_s / sofa:.1f}x" if sofa and "lagged" in ms else "-",
            f"{exact / sofa:.1f}x" if sofa and exact else "-",
            f"{error['error_end_mm']:.3g} mm ({error['error_end_percent_of_motion']:.2g} %)"
            if error
            else "-",
        )
    console.print(table)
    for scene in scenes:
        note = next(m for m in results if m.scene == scene).extra.get("sofa_scene")
        if note:
            console.print(f"  {scene}: {note}")


def _plot(results: list[Measurement], path: Path) -> None:
    from pliant.viz import plot_loglog

    series = {}
    for policy in ("pcg", "lagged"):
        pts = sorted(
            (m.tets, m.steps_per_s)
            for m in results
            if m.policy == policy and m.scene.startswith("cantilever")
        )
        if pts:
            series[f"Pliant ({policy})"] = (
                np.array([p[0] for p in pts]),
                np.array([p[1] for p in pts]),
            )
    sofa = sorted(
        (int(k.split("-")[1]), v) for k, v in SOFA_STEPS_PER_S.items() if k.startswith("cantilever")
    )
    series["SOFA (SparseLDL)"] = (np.array([p[0] for p in sofa]), np.array([p[1] for p in sofa]))
    plot_loglog(
        series,
        path,
        xlabel="tetrahedra",
        ylabel="steps / s (dt = 0.01)",
        title="Cantilever: steps/s vs element count",
    )
