"""A Gymnasium environment around a SofaGym scene loaded by Pliant: SofaGym users keep their
scene (``<Name>Scene.py``), its toolbox (``<Name>Toolbox.py``) and their configuration.

The loop is SofaGym's (its ``AbstractEnv``): ``reset`` builds the scene anew with the
configuration (the goal drawn from ``goalList`` when ``goal`` is set), then calls the scene's
``GoalSetter.update(goalPos)`` and ``Reward.update(goalPos)``; ``step(action)`` starts the
toolbox's command, ``startCmd(root, action, dt * (scale_factor - 1))``, runs ``scale_factor``
simulation steps with the scene's controllers around each, and returns the toolbox's
``getState(root)`` and ``getReward(root)`` (``done, reward``); the episode is truncated after
``timer_limit`` steps. Only the simulation is Pliant's: the physics of the scene, read by
:func:`pliant.sofa.load_scene`.

The scene's controllers keep Python state of their own, so these environments offer no exact
snapshots (``get_state`` / ``set_state``) as Pliant's own environments do.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

from pliant.envs.base import ActionError
from pliant.errors import DivergenceError
from pliant.sofa import SceneError, load_scene
from pliant.sofa.script import scene_error


class SofaGymEnv(gym.Env):
    """SofaGym's environment loop on a SofaGym scene simulated by Pliant.

    Args:
        scene: the scene script, ``createScene(rootNode, config)``.
        config: the environment's configuration (SofaGym's ``DEFAULT_CONFIG`` with the
            user's changes): ``dt``, ``scale_factor`` (simulation steps per environment step)
            and ``timer_limit`` (environment steps per episode) are read here; ``goal`` and
            ``goalList`` choose the goal; the rest is the scene's.
        action_space: the actions the toolbox's ``startCmd`` takes.
        observation_space: the states its ``getState`` gives; by default unbounded, of
            ``config["dim_state"]`` values (a number or a shape).
        toolbox: the name of the scene's toolbox module (imported by the scene from its
            folder); by default the scene's name with ``Scene`` made ``Toolbox``.
        mesh_dirs: folders where mesh files not found beside the scene are looked for.
    """

    metadata = {"render_modes": []}  # noqa: RUF012 (Gymnasium's class attribute)

    def __init__(
        self,
        scene: str | Path,
        config: Mapping,
        *,
        action_space: gym.Space,
        observation_space: gym.Space | None = None,
        toolbox: str | None = None,
        mesh_dirs: Sequence[str | Path] = (),
    ) -> None:
        self.scene_path = Path(scene)
        missing = [k for k in ("dt", "scale_factor", "timer_limit") if k not in config]
        if missing:
            raise ValueError(f"the configuration lacks {', '.join(missing)}")
        self.config = copy.deepcopy(dict(config))
        self.toolbox_name = toolbox or self.scene_path.stem.replace("Scene", "Toolbox")
        self.mesh_dirs = list(mesh_dirs)
        self.action_space = action_space
        if observation_space is None:
            if "dim_state" not in config:
                raise ValueError("give observation_space, or dim_state in the configuration")
            shape = tuple(int(n) for n in np.atleast_1d(config["dim_state"]))
            observation_space = gym.spaces.Box(-np.inf, np.inf, shape, dtype=np.float32)
        self.observation_space = observation_space
        self.scene = None  # the episode's scene (pliant.sofa.SofaScene), built by reset
        self.episode_config: dict | None = None  # the configuration it was built with
        self.toolbox = None
        self.solver = None
        self.state = None
        self.timer = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        config = copy.deepcopy(self.config)
        goals = config.get("goalList")
        if config.get("goal") and goals:
            chosen = int(self.np_random.integers(len(goals)))
            config.update(goal_node=chosen, goalPos=goals[chosen])
        self.scene = load_scene(self.scene_path, config=config, mesh_dirs=self.mesh_dirs)
        self.toolbox = self.scene.root.modules.get(self.toolbox_name)
        if self.toolbox is None:
            raise SceneError(
                f"{self.scene_path.name} imports no module {self.toolbox_name!r} from its folder"
                " (the toolbox with startCmd, getState and getReward; name it with toolbox=)"
            )
        self.solver = self.scene.solver()
        self.state = self.scene.model.rest_state()
        self.timer = 0
        root = self.scene.root
        if config.get("goal") and root.getObject("GoalSetter") is not None:
            root.GoalSetter.update(config["goalPos"])
        if root.getObject("Reward") is not None:
            goal = config.get("goalPos")
            root.Reward.update(goal) if goal is not None else root.Reward.update()
        self.episode_config = config
        return self._observe(), {"goal": config.get("goalPos")}

    def step(self, action):
        if self.scene is None:
            raise RuntimeError("call reset() before step()")
        if not self.action_space.contains(action):
            raise ActionError(f"{action!r} is not in {self.action_space}")
        dt, substeps = float(self.config["dt"]), int(self.config["scale_factor"])
        self._toolbox("startCmd", action, dt * (substeps - 1))
        info = {}
        try:
            for _ in range(substeps):
                self.state = self.solver.step(self.state)
        except DivergenceError as exc:  # as Pliant's environments: the episode ends, named
            info["diverged"] = str(exc)
            return self._observe(), 0.0, False, True, info
        done, reward = self._toolbox("getReward")
        self.timer += 1
        truncated = self.timer >= int(self.config["timer_limit"])
        return self._observe(), float(reward), bool(done), truncated, info

    def _observe(self) -> np.ndarray:
        return np.asarray(self._toolbox("getState"), dtype=np.float32)

    def _toolbox(self, function: str, *args):
        """The toolbox's `function` on the scene's root; what fails in it is the scene's
        error, at its line."""
        call = getattr(self.toolbox, function, None)
        if call is None:
            raise SceneError(f"the toolbox {self.toolbox_name!r} has no {function}()")
        try:
            return call(self.scene.root, *args)
        except SceneError:
            raise
        except Exception as exc:
            raise scene_error(self.scene_path, exc, f"{self.toolbox_name}.{function}") from exc
