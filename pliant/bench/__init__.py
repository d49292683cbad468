"""``pliant bench``: how fast Pliant runs, beside SOFA's figures measured on this kind of machine.

One module per thing timed: :mod:`~pliant.bench.engine` (the engine's scenes: SPEC §5's
Diamond, Trunk, cantilevers and Multigait, the contact scenes, the Soft Finger, batched
stepping, a static solve and an inverse-control step), :mod:`~pliant.bench.sofa_scenes` (SOFA's
own scenes read by the scene loader), :mod:`~pliant.bench.mujoco_peer` (MuJoCo flex on the same
cantilevers, raced in the same run; optional), :mod:`~pliant.bench.profile` (where a step's
time goes, and the default step's error against the exact one), :mod:`~pliant.bench.envs` (the
environments' speed, ``--envs``), :mod:`~pliant.bench.learner` (the learner's cost per training
step, ``--learner``), :mod:`~pliant.bench.gradient` (a rollout gradient against its rollout,
``--gradient``), with :mod:`~pliant.bench.timing` (timed runs of a scene under each solver
policy) and :mod:`~pliant.bench.host` (the host a timing was taken on) beneath them.

The environments' and the learner's modules import Gymnasium (and PyTorch), so they are not
imported here.
"""

from pliant.bench.engine import (
    SOFA_STEPS_PER_S,
    THESIS_FINGER_FPS,
    cantilever,
    multigait,
    multigait_on_floor,
    multigait_reference,
    reference_diamond,
    run_benchmarks,
)
from pliant.bench.gradient import report_gradient
from pliant.bench.host import host
from pliant.bench.sofa_scenes import SOFA_SCENES, TRUNK_CUBE_WARMUP, sofa_scene, trunk_cables_cube
from pliant.bench.timing import POLICY_OPTIONS, Measurement, Timing, time_steps

__all__ = [
    "POLICY_OPTIONS",
    "SOFA_SCENES",
    "SOFA_STEPS_PER_S",
    "THESIS_FINGER_FPS",
    "TRUNK_CUBE_WARMUP",
    "Measurement",
    "Timing",
    "cantilever",
    "host",
    "multigait",
    "multigait_on_floor",
    "multigait_reference",
    "reference_diamond",
    "report_gradient",
    "run_benchmarks",
    "sofa_scene",
    "time_steps",
    "trunk_cables_cube",
]
