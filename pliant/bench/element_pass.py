"""The element pass against its roofline (#62): ``pliant bench --element-pass``.

Times the polar corotational force pass (and with K_s v) one element at a time
(:func:`pliant.fem.kernels.internal_forces`) and vectorised across elements
(:func:`pliant.fem.soa_kernels.corotational_forces`), interleaved in one process on one thread,
in nanoseconds of CPU per tetrahedron, on the Trunk and the Diamond after 0.3 s swinging from
rest and on a bent 15 360-tet cantilever. Beside them: the floating-point operations per
element of the vectorised loops, counted in their LLVM IR; the bytes an element reads and
writes; and two ceilings measured in the same process, a vectorised multiply-add loop (the
arithmetic peak) and a triad a = b + s c (memory bandwidth, arrays in L2 and in memory). Then
the default (lagged) step of the Diamond and the Trunk with either pass, interleaved.
"""

from __future__ import annotations

import json
import re
import statistics
import time
from pathlib import Path

import numba
import numpy as np
from rich.console import Console

from pliant import robots
from pliant.bench.engine import _default_meshes, cantilever, reference_diamond
from pliant.bench.host import host
from pliant.fem import kernels, soa_kernels
from pliant.fem.body import TetBody
from pliant.mesh import load_mesh
from pliant.model import Model
from pliant.solvers import ImplicitEuler

# Bytes an element moves, by array (8-byte floats and indices): read the node indices (4),
# gradients (12), volume, mu, lambda (3) and the 4 x 3 node positions (an upper bound: a node
# is shared by about six elements, so most of its reads hit the cache); write 12 forces, the
# 3 x 3 rotation, det F, the energy and the last polar step, the last two read back.
BYTES_FORCES = 8 * (4 + 12 + 3 + 12) + 8 * (12 + 9 + 1 + 2) + 8 * 2
# With K_s v: the 4 x 3 node velocities read and 12 entries of K_s v written.
BYTES_KV = 8 * 12 + 8 * 12
_FP_OPS = re.compile(r"=\s+(fadd|fsub|fmul|fdiv|fneg)\s+(?:\w+\s+)*<(\d+) x double>")


def vector_flops(llvm_ir: str) -> dict[str, float]:
    """Floating-point operations per element of the vectorised loops (``vector.body``) of
    :func:`pliant.fem.soa_kernels._blocks` in its LLVM IR: the lanes of their vector fadd,
    fsub, fmul, fdiv and fneg over the elements an iteration takes (its induction step). The
    loops are told apart by what they do: the first polar steps (their three divisions), one
    more step (one division), K_s v (it reads `v`) and the stresses and forces."""
    out: dict[str, float] = {}
    for body in re.split(r"\n(?=[\w.]+:)", llvm_ir):
        step = re.search(
            r"%index\.next\d*\s*=\s*add\s+(?:nuw\s+)?(?:nsw\s+)?i64\s+%index\d*,\s*(\d+)", body
        )
        if not body.startswith("vector.body") or step is None:
            continue
        ops = [(m.group(1), int(m.group(2))) for m in _FP_OPS.finditer(body)]
        flops = sum(lanes for _, lanes in ops) / int(step.group(1))
        divisions = sum(lanes for op, lanes in ops if op == "fdiv") / int(step.group(1))
        if flops == 0.0:
            continue
        label = (
            "polar_steps"
            if divisions == 3
            else "one_more_polar_step"
            if divisions == 1
            else "kv"
            if "%arg.v." in body
            else "stress_and_forces"
        )
        out[label] = flops
    return out


@numba.njit(nogil=True)
def _multiply_add(x, y, a, b):
    """y[i] = x[i] after 16 dependent multiply-adds (vectorised across i; the chains of
    neighbouring i overlap): 32 flops per entry."""
    for i in range(x.shape[0]):
        v = x[i]
        for _ in range(16):
            v = v * a + b
        y[i] = v


@numba.njit(nogil=True)
def _triad(a, b, c, s):
    for i in range(a.shape[0]):
        a[i] = b[i] + s * c[i]


def _median_rate(fn, work: float, repeats: int) -> float:
    """work / (median CPU seconds of fn())."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return work / statistics.median(times)


def ceilings(repeats: int = 7) -> dict:
    """GFLOP/s of the multiply-add loop and GB/s of the triad, arrays in L2 and in memory."""
    x = np.random.default_rng(0).uniform(0.5, 1.0, 4096)  # 32 kB, in L1
    y = np.empty_like(x)
    sweeps = 2000

    def peak():
        for _ in range(sweeps):
            _multiply_add(x, y, 0.999, 0.001)

    out = {"fp_gflops": _median_rate(peak, 32.0 * x.size * sweeps, repeats) / 1e9}
    for name, n, times in (("l2", 8192, 400), ("memory", 4_000_000, 3)):
        a, b, c = np.zeros(n), np.ones(n), np.ones(n)

        def stream(a=a, b=b, c=c, times=times):
            for _ in range(times):
                _triad(a, b, c, 0.5)

        out[f"triad_{name}_gb_s"] = _median_rate(stream, 24.0 * n * times, repeats) / 1e9
    out["triad_l2_array_kb"] = 3 * 8192 * 8 / 1024
    out["triad_memory_array_mb"] = 3 * 4_000_000 * 8 / 2**20
    return out


def _swung(model: Model, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (n, 3) after `steps` default steps from rest under gravity."""
    solver = ImplicitEuler(model, 0.01)
    state = model.rest_state()
    for _ in range(steps):
        state = solver.step(state, None)
    n = model.body.n_nodes
    return state.positions.reshape(n, 3).copy(), state.velocities.reshape(n, 3).copy()


def _bent(body: TetBody) -> tuple[np.ndarray, np.ndarray]:
    """The cantilever bent along x to a quarter circle, and a random velocity."""
    p = body.rest_positions
    length = p[:, 0].max()
    radius = 2.0 * length / np.pi
    angle = p[:, 0] / radius
    x = np.stack(
        [
            (radius - p[:, 2]) * np.sin(angle),
            p[:, 1],
            radius - (radius - p[:, 2]) * np.cos(angle),
        ],
        axis=1,
    )
    return x, np.random.default_rng(1).normal(size=p.shape)


def _blocks_args(body: TetBody, x: np.ndarray, v: np.ndarray, hi: int | None = None) -> tuple:
    """Arguments of :func:`pliant.fem.soa_kernels._blocks` over the body's elements up to `hi`
    (all by default), forces alone; the last one is the last polar step of each element."""
    m = body.n_elements
    nodes, g = soa_kernels.soa_layout(body.tets, body.grads)
    f = np.empty((m, 4, 3))
    out = (np.empty((m, 3, 3)), np.empty(m), np.empty(m), np.empty(m))
    return (
        0,
        m if hi is None else hi,
        x,
        v[:0],
        nodes,
        g,
        body.volumes,
        body.mu,
        body.lam,
        f,
        f[:0],
        *out,
    )


def _pass_times(body: TetBody, x: np.ndarray, v: np.ndarray, repeats: int) -> dict:
    """CPU ns per element of each pass, forces alone and with K_s v (interleaved medians)."""
    m = body.n_elements
    nodes, g = soa_kernels.soa_layout(body.tets, body.grads)
    common = (body.tets, body.grads, body.volumes, body.mu, body.lam)
    frames, dets = np.empty((m, 3, 3)), np.empty(m)
    results = {}
    for label, vel in (("forces", np.empty((0, 3))), ("forces_and_kv", v)):
        elem = np.empty((m, 4, 6 if vel.shape[0] else 3))
        kv = elem[:, :, 3:] if vel.shape[0] else np.empty((0, 4, 3))
        f = elem[:, :, :3]

        def old(vel=vel, f=f, kv=kv):
            kernels.internal_forces(
                x, vel, *common, 0, body.frame_nodes, body.rest_frames, f, kv, frames, dets
            )

        def new(vel=vel, f=f, kv=kv):
            soa_kernels.corotational_forces(x, vel, *common, nodes, g, f, kv, frames, dets)

        calls = max(1, int(2e6 / (200.0 * m)))  # about 2 ms of the old pass per sample
        samples = {"element": [], "vectorised": []}
        for _ in range(repeats):
            for name, fn in (("element", old), ("vectorised", new)):
                t0 = time.process_time()
                for _ in range(calls):
                    fn()
                samples[name].append((time.process_time() - t0) / calls / m * 1e9)
        results[label] = {k: statistics.median(s) for k, s in samples.items()}
        results[label]["speed_up"] = results[label]["element"] / results[label]["vectorised"]
    # Elements the vectorised pass computed again one at a time at this configuration.
    args = _blocks_args(body, x, v)
    soa_kernels._blocks(*args)
    results["recomputed_fraction"] = float(np.mean(~(args[-1] < kernels._POLAR_TOL)))
    return results


def _step_times(model: Model, repeats: int, steps: int) -> dict:
    """CPU ms per default step with either pass (each repeat a new solver from the same state
    after 10 steps, the two passes interleaved)."""
    body = model.body
    solver = ImplicitEuler(model, 0.01)
    start = model.rest_state()
    for _ in range(10):
        start = solver.step(start, None)
    samples = {False: [], True: []}
    for _ in range(repeats):
        for flag in (False, True):
            body.vectorised_element_pass = flag
            solver = ImplicitEuler(model, 0.01)
            s = solver.step(start.copy(), None)  # compile and factorise outside the timing
            t0 = time.process_time()
            for _ in range(steps):
                s = solver.step(s, None)
            samples[flag].append((time.process_time() - t0) / steps * 1e3)
    body.vectorised_element_pass = True
    old, new = statistics.median(samples[False]), statistics.median(samples[True])
    return {"element_ms": old, "vectorised_ms": new, "speed_up": old / new}


def report_element_pass(
    *, out: Path, console: Console, repeats: int = 15, meshes: Path | None = None
) -> dict:
    """Measure (see the module docstring) on one numba thread and write `out` (JSON)."""
    meshes = meshes or _default_meshes()
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        scenes: dict[str, tuple[Model, tuple[np.ndarray, np.ndarray]]] = {}
        if meshes is not None:
            trunk = Model(robots.trunk(mesh=load_mesh(meshes / "Trunk_trunk.vtk")).body)
            diamond = Model(robots.diamond(mesh=reference_diamond(meshes)).body)
            scenes["trunk"] = (trunk, _swung(trunk, 30))
            scenes["diamond"] = (diamond, _swung(diamond, 30))
        beam = cantilever(8)
        scenes[f"cantilever-{beam.body.n_elements}"] = (beam, _bent(beam.body))
        compiled = numba.njit(error_model="numpy")(soa_kernels._blocks.py_func)
        compiled(*_blocks_args(beam.body, *scenes[f"cantilever-{beam.body.n_elements}"][1], 8))
        flops = vector_flops(compiled.inspect_llvm(compiled.signatures[0]))
        flops_forces = flops["polar_steps"] + flops["stress_and_forces"]
        flops_kv = flops["kv"]
        ceiling = ceilings()
        result = {
            "host": host(),
            "note": "one numba thread; CPU time (process_time), medians of interleaved repeats;"
            " the host was shared with other jobs",
            "repeats": repeats,
            "ceilings": ceiling,
            "kernel": {
                "lanes_per_block": soa_kernels.LANES,
                "polar_newton_steps": soa_kernels.POLAR_STEPS,
                "vector_loops_flops_per_element": flops,
                "flops_per_element_forces": flops_forces,
                "flops_per_element_kv": flops_kv,
                "bytes_per_element_forces": BYTES_FORCES,
                "bytes_per_element_kv": BYTES_KV,
            },
            "scenes": {},
        }
        for name, (model, (x, v)) in scenes.items():
            times = _pass_times(model.body, x, v, repeats)
            row = {"tets": model.body.n_elements, **times}
            for label, fl, by in (
                ("forces", flops_forces, BYTES_FORCES),
                ("forces_and_kv", flops_forces + flops_kv, BYTES_FORCES + BYTES_KV),
            ):
                ns = times[label]["vectorised"]
                row[label]["gflops"] = fl / ns
                row[label]["gb_s"] = by / ns
                row[label]["roofline_ns"] = max(
                    fl / ceiling["fp_gflops"], by / ceiling["triad_l2_gb_s"]
                )
            if name in ("trunk", "diamond"):
                row["default_step"] = _step_times(model, max(3, repeats // 3), 20)
            result["scenes"][name] = row
            console.print(f"  {name}: {json.dumps(row)}")
    finally:
        numba.set_num_threads(threads)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    console.print(f"element pass: wrote {out}")
    return result
