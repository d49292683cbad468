"""Multigait locomotion on the reduced model (thesis §3.1.2, §3.4.1; SofaGym's
multigaitrobot-v0, whose scene runs the reduced Multigait).

The task is :class:`pliant.envs.multigait.MultigaitEnv`'s (symmetric discrete actions: centre,
front pair, rear pair inflated or deflated over a step; 6 steps of 60 x 0.01 s), stepped by
:class:`pliant.reduction.ReducedImplicitEuler`. Observation: the `n_observed` leading reduced
coordinates (the 3 translations, then the deformation modes by decreasing energy) divided by
the norm of all of them, as SofaGym's (32 of its 63); zeros past the basis' size. Reward:
SofaGym's max(0, dx) of the centre of mass by default (Table 3.2 sums it; wave2_facts.md A.4).

The reduced model is given as a file (`reduced_model`, from ``pliant reduce multigait``) or
built on first use from the full model's training load cases
(:func:`pliant.reduction.multigait_cases` with `training`) and cached
(:func:`pliant.reduction.pipeline.cache_folder`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pliant.envs.actions import scaled_box
from pliant.envs.multigait import FORWARD, MultigaitEnv
from pliant.model import Model
from pliant.reduction import ReducedImplicitEuler, ReducedModel
from pliant.reduction.pipeline import cached, multigait_cases

#: training of a reduced model built on demand (multigait_cases' arguments and build's). 20
#: random action sequences beside the gait and the groups alone: with 3, PPO's gait (worth
#: 10 mm on that reduced model) walked 2.2 mm on the full one, where the hand gait walks 6.4;
#: with 20 the learned gait walks 10.6 mm on the full FEM (docs/reduction.md, Table 3.2).
#: Built once (about 2 min here) and cached.
TRAINING = {"sequences": 20, "cycles": 1, "phase": 0.6, "pod_tolerance": 1e-3, "tau": 3e-3}


class ReducedMultigaitEnv(MultigaitEnv):
    name = "ReducedMultigait"
    rewards = ("sofagym", "thesis")

    def __init__(
        self,
        *,
        amplitude: tuple[float, float] = (4900.0, 3300.0),
        n_observed: int = 32,
        reduced_model: str | Path | None = None,
        training: dict | None = None,
        **kwargs,
    ) -> None:
        self.reduced_model = reduced_model
        self.training = {**TRAINING, **(training or {})}
        self._amplitude = tuple(amplitude)
        self.n_observed = int(n_observed)
        super().__init__(amplitude=amplitude, **kwargs)
        self.sim = self._reduced
        self.observation_space = scaled_box(-1.0, 1.0, (self.n_observed,))

    def _build(self) -> Model:
        model = super()._build()
        if self.reduced_model is not None:
            reduced = ReducedModel.load(self.reduced_model, model)
        else:
            t = self.training
            cases = multigait_cases(
                amplitude=self._amplitude,
                phase=t["phase"],
                sequences=t["sequences"],
                cycles=t["cycles"],
            )
            settings = {"mesh_size": self.robot_kwargs["mesh_size"], "amplitude": self._amplitude}
            reduced = cached(
                model,
                cases,
                {**settings, **self.robot_kwargs, **t},
                dt=self.dt,
                pod_tolerance=t["pod_tolerance"],
                tau=t["tau"],
                tau_membrane=t["tau"],
            )
        self.reduced = reduced
        self._reduced = ReducedImplicitEuler(model, reduced.basis, reduced.domain, self.dt)
        masses = model.body.node_masses
        # Centre of mass along the forward axis: x_c0 + c . alpha.
        modes = reduced.basis.modes
        self._forward = np.einsum("n,nir,i->r", masses, modes, FORWARD) / masses.sum()
        self._forward0 = float(masses @ model.body.rest_positions @ FORWARD / masses.sum())
        return model

    def _initial_state(self):
        return self._reduced.rest_state()

    def progress(self) -> float:
        """Forward position of the centre of mass (mm)."""
        return self._forward0 + float(self._forward @ self.state.coordinates)

    def _observe(self) -> np.ndarray:
        alpha = self.state.coordinates
        norm = float(np.linalg.norm(alpha))
        obs = np.zeros(self.n_observed)
        k = min(self.n_observed, alpha.size)
        if norm > 0.0:
            obs[:k] = alpha[:k] / norm
        return obs

    def set_state(self, snapshot) -> None:
        super().set_state(snapshot)
        self.state = self.sim.attach(self.state)  # an unpickled state has no basis
