"""MuJoCo flex as a peer in ``pliant bench`` (issue #62, item 5): the bench's bare bodies (the
SPEC §5 cantilevers) built as MuJoCo flex bodies and timed in the same process, interleaved with
Pliant, so that the ratio does not depend on the host or on the day.

The two models share the mesh, Young's modulus, Poisson's ratio, the mass (the same on every
node: MuJoCo's flexcomp gives each point ``mass / points``, SOFA's UniformMass), the held nodes
(pinned points), gravity and the time step. They differ in what is discretised and how it is
integrated, which is why the bench reports the tip's motion after 1 s beside the ratio:

* Pliant: corotational linear elasticity (rotation of each element by polar decomposition),
  linearly implicit Euler with a sparse Cholesky factor (the default policy keeps it while
  the element frames change little).
* MuJoCo: Saint Venant-Kirchhoff elasticity (Green strain, linear stress) on the same linear
  tetrahedra, the ``discrete`` integrator (implicit in position and velocity, stiffness
  linearised at the start of the step: MuJoCo's only integrator stable for stiff flex at this
  step), whose effective metric M + h^2 K is solved matrix-free by a block-preconditioned
  conjugate gradient to MuJoCo's ``tolerance``.

MuJoCo is an optional dependency (``pip install 'pliant[peers]'``): without it the bench prints
one line and goes on.
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from contextlib import contextmanager

import numba
import numpy as np

from pliant.bench.timing import POLICY_OPTIONS
from pliant.errors import MissingDependencyError, ModelError
from pliant.fem.body import TetBody
from pliant.model import Model
from pliant.solvers import ImplicitEuler

# The bench's units are mm, kg and s (stress in kPa); MuJoCo is given SI units.
METRES_PER_MM = 1e-3
# Conjugate-gradient iterations MuJoCo may spend on the effective-metric solve of one step: at
# MuJoCo's default (100) the first step of the 240-tet cantilever stops at a relative residual of
# 0.4 and warns; this cap lets it reach its tolerance at every size the bench times.
ITERATIONS = 10000
TOLERANCE = 1e-8
# The settings raced: MuJoCo's tolerance reached at every step, and MuJoCo's defaults (an
# iteration cap of 100, short of the tolerance on many steps here: counted and reported).
SETTINGS = {"converged": {"iterations": ITERATIONS}, "default": {"iterations": 100}}


def mujoco_available() -> bool:
    """Whether the ``mujoco`` package can be imported."""
    return importlib.util.find_spec("mujoco") is not None


def _mujoco():
    if not mujoco_available():
        raise MissingDependencyError(
            "MuJoCo is not installed: the MuJoCo flex peer needs it (pip install 'pliant[peers]')"
        )
    import mujoco

    return mujoco


def flex_xml(
    body: TetBody,
    dt: float,
    *,
    iterations: int = ITERATIONS,
    tolerance: float = TOLERANCE,
) -> str:
    """MJCF of `body` as one MuJoCo flex (dim 3, one moving point per free node, the held
    nodes pinned), in SI units, without contact: ModelError for what a flex cannot carry the
    same way (a mass other than uniform, mass-proportional damping, partly held nodes,
    membranes, loads, projections)."""
    if not isinstance(body, TetBody):
        raise ModelError(f"the MuJoCo peer builds tetrahedral bodies, got {type(body).__name__}")
    unsupported = {
        "a mass other than uniform (flexcomp spreads it evenly over the points)": body.mass_type
        != "uniform",
        "mass-proportional Rayleigh damping": body.rayleigh_mass != 0.0,
        "Rayleigh damping by part of the body": body.rayleigh_dofs() is not None,
        "nodes held in some components only": body.free_dofs.size
        != 3 * body.n_nodes - 3 * body.fixed_nodes.size,
        "membranes, loads or projections": bool(body.membranes or body.loads or body.projections),
    }
    missing = [what for what, present in unsupported.items() if present]
    if missing:
        raise ModelError(f"the MuJoCo peer cannot build a body with {', '.join(missing)}")
    material = body.material
    young = getattr(material, "young_modulus", None)
    poisson = getattr(material, "poisson_ratio", None)
    if young is None or poisson is None:
        raise ModelError(
            "the MuJoCo peer needs an isotropic material with young_modulus and poisson_ratio,"
            f" got {type(material).__name__}"
        )
    points = " ".join(f"{x:.9g}" for x in (body.rest_positions * METRES_PER_MM).ravel())
    elements = " ".join(str(i) for i in body.tets.ravel())
    gravity = " ".join(f"{g:.9g}" for g in body.gravity * METRES_PER_MM)
    pins = " ".join(str(i) for i in body.fixed_nodes)
    pin = f'<pin id="{pins}"/>' if pins else ""
    # kPa (kg mm^-1 s^-2) to Pa; Rayleigh's stiffness coefficient is a time in both.
    return f"""<mujoco model="pliant-peer">
  <option timestep="{dt!r}" gravity="{gravity}" integrator="discrete" solver="Newton"
          iterations="{int(iterations)}" tolerance="{tolerance!r}">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <flexcomp name="body" type="direct" dim="3" mass="{body.total_mass!r}" radius="1e-4"
              point="{points}" element="{elements}">
      <contact contype="0" conaffinity="0" selfcollide="none"/>
      <elasticity young="{young / METRES_PER_MM!r}" poisson="{poisson!r}"
                  damping="{body.rayleigh_stiffness!r}"/>
      {pin}
    </flexcomp>
  </worldbody>
</mujoco>"""


class FlexPeer:
    """`model`'s body as a MuJoCo flex (:func:`flex_xml`), stepped by :meth:`step`; node
    positions in the bench's millimetres, in the body's node order. MuJoCo's warnings are kept
    in :attr:`messages` (the first few) rather than printed."""

    MAX_MESSAGES = 10

    def __init__(self, model: Model, dt: float = 0.01, **options) -> None:
        if model.rigid_bodies or model.contacts is not None or model.actuators:
            raise ModelError(
                "the MuJoCo peer builds bare bodies (no rigid bodies, contact or actuators)"
            )
        mujoco = _mujoco()
        self._mj = mujoco
        self.body = model.body
        self.messages: list[str] = []
        with self._warnings_kept():
            self.model = mujoco.MjModel.from_xml_string(flex_xml(model.body, dt, **options))
        self.data = mujoco.MjData(self.model)
        # flexcomp numbers its vertices as the points were given: the body's node order.
        if self.model.flex_vertnum[0] != self.body.n_nodes:
            raise ModelError(
                f"MuJoCo's flex has {self.model.flex_vertnum[0]} vertices for"
                f" {self.body.n_nodes} nodes"
            )
        self.reset()

    @contextmanager
    def _warnings_kept(self):
        """MuJoCo's warning handler (one for the process) pointed at :attr:`messages`."""
        previous = self._mj.get_mju_user_warning()
        self._mj.set_mju_user_warning(self._keep)
        try:
            yield
        finally:
            self._mj.set_mju_user_warning(previous)

    def _keep(self, message: str) -> None:
        if len(self.messages) < self.MAX_MESSAGES:
            self.messages.append(message)

    def reset(self) -> None:
        """Back to rest, zero velocity, time 0."""
        with self._warnings_kept():
            self._mj.mj_resetData(self.model, self.data)
            self._mj.mj_forward(self.model, self.data)

    def step(self, n: int = 1) -> None:
        mj_step, m, d = self._mj.mj_step, self.model, self.data
        with self._warnings_kept():
            for _ in range(n):
                mj_step(m, d)

    def positions(self) -> np.ndarray:
        """(n, 3) node positions in mm (after :meth:`step`, as MuJoCo computed them)."""
        with self._warnings_kept():
            self._mj.mj_kinematics(self.model, self.data)
            self._mj.mj_flex(self.model, self.data)
        return np.array(self.data.flexvert_xpos) / METRES_PER_MM

    def save(self) -> tuple:
        return self.data.qpos.copy(), self.data.qvel.copy(), self.data.time

    def restore(self, saved: tuple) -> None:
        self.data.qpos[:], self.data.qvel[:], self.data.time = saved[0], saved[1], saved[2]
        with self._warnings_kept():
            self._mj.mj_forward(self.model, self.data)

    def warnings(self) -> int:
        """MuJoCo's warnings since the last reset (an unconverged solve raises one)."""
        return int(sum(w.number for w in self.data.warning))


def race(
    model: Model,
    *,
    steps: int,
    repeats: int,
    warmup: int,
    policy: str = "lagged",
    dt: float = 0.01,
    motion_steps: int = 100,
    settings: dict[str, dict] | None = None,
) -> dict:
    """Pliant (`policy`) and the MuJoCo flex peer under each of `settings` (name: options of
    :func:`flex_xml`; default :data:`SETTINGS`) on the same body in this process: each engine
    from the state after `warmup` steps from rest, `repeats` rounds of `steps` steps, the
    engines taken in turn within a round so that all see the same load; medians of steps/s.
    Then the tip's motion (the mean of the nodes at the largest x) after `motion_steps` steps
    from rest in each, and the steps of that run on which MuJoCo warned (a solve that stopped
    at its iteration cap short of its tolerance). Pliant runs twice a round: with its compiled
    kernels' threads (numba's count) and on one thread, as MuJoCo steps."""
    settings = SETTINGS if settings is None else settings
    body = model.body
    peers = {name: FlexPeer(model, dt, **options) for name, options in settings.items()}
    solver = ImplicitEuler(model, dt, **POLICY_OPTIONS[policy])
    state = model.rest_state()
    for _ in range(warmup):
        state = solver.step(state, None)
    saved = {}
    for name, peer in peers.items():
        peer.step(warmup)
        saved[name] = peer.save()
    threads = numba.get_num_threads()
    rates: dict[str, list[float]] = {"pliant": [], "pliant_one_thread": []}
    rates |= {name: [] for name in peers}
    for _ in range(repeats):
        for key, count in (("pliant", threads), ("pliant_one_thread", 1)):
            numba.set_num_threads(count)
            try:
                s = state.copy()
                t0 = time.perf_counter()
                for _ in range(steps):
                    s = solver.step(s, None)
                rates[key].append(steps / (time.perf_counter() - t0))
            finally:
                numba.set_num_threads(threads)
        for name, peer in peers.items():
            peer.restore(saved[name])
            t0 = time.perf_counter()
            peer.step(steps)
            rates[name].append(steps / (time.perf_counter() - t0))
    rest = body.rest_positions
    tip = np.flatnonzero(rest[:, 0] >= rest[:, 0].max() - 1e-9)
    s = model.rest_state()
    solver = ImplicitEuler(model, dt, **POLICY_OPTIONS[policy])
    for _ in range(motion_steps):
        s = solver.step(s, None)
    pliant_tip = (s.positions[tip] - rest[tip]).mean(axis=0)
    pliant_rate = statistics.median(rates["pliant"])
    one_thread = statistics.median(rates["pliant_one_thread"])
    out = {
        "tets": body.n_elements,
        "policy": policy,
        "pliant_threads": threads,
        "pliant_steps_per_s": pliant_rate,
        "pliant_repeats": rates["pliant"],
        "pliant_one_thread_steps_per_s": one_thread,
        "pliant_one_thread_repeats": rates["pliant_one_thread"],
        "pliant_tip_displacement_mm": pliant_tip.tolist(),
        "seconds_simulated": motion_steps * dt,
        "mujoco_version": next(iter(peers.values()))._mj.__version__ if peers else None,
        "mujoco": {},
    }
    for name, peer in peers.items():
        peer.reset()
        warned = 0
        for _ in range(motion_steps):
            before = peer.warnings()
            peer.step()
            warned += peer.warnings() > before
        tip_motion = (peer.positions()[tip] - rest[tip]).mean(axis=0)
        rate = statistics.median(rates[name])
        out["mujoco"][name] = {
            "iterations_cap": int(peer.model.opt.iterations),
            "tolerance": float(peer.model.opt.tolerance),
            "steps_per_s": rate,
            "repeats": rates[name],
            "ratio": pliant_rate / rate,
            "ratio_one_thread": one_thread / rate,
            "tip_displacement_mm": tip_motion.tolist(),
            "tip_difference_percent": float(
                100.0 * np.linalg.norm(tip_motion - pliant_tip) / np.linalg.norm(pliant_tip)
            ),
            "steps_short_of_tolerance": int(warned),
            "mujoco_messages": list(dict.fromkeys(m.split("\n")[0] for m in peer.messages)),
        }
    return out
