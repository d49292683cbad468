"""The cube's response to the trunk, FEM against proxy: pushes of the FEM Trunk
(:class:`pliant.envs.trunk_push.TrunkPushEnv`) replayed on its proxy
(:class:`pliant.envs.trunk_push_proxy.TrunkPushProxyEnv`, ``actions="cables"``).

The thesis calibrates the Trunk proxy without the cube and fits the cube's weight afterwards
on one slow push (``pliant proxy calibrate trunk-cube``). A policy learnt on the proxy meets
the cube in fast strikes, where what the cube does depends on how the trunk hits it: its
effective mass and damping, the contact's geometry and friction. Here the reference is a set
of whole episodes of the task on the FEM, under the actions a learner takes, and the proxy is
fitted on what the cube does in them.

Each FEM step's replay is its cables' shortening at the step's end (a pulled cable's target
once reached, a slack one's as the trunk's bending shortens its path; as absolute targets in
the FEM's action space, which the proxy environment maps to its bendings, as the calibration's
reference does) and the base target the FEM was given: the proxy replays the FEM's actuation,
not the FEM's requests, which its cable rate limit may not have met. The matched point is the
cube's centre at each step's end.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.envs.trunk_push import TrunkPushEnv
from pliant.envs.trunk_push_proxy import CABLE_COURSES, TrunkPushProxyEnv
from pliant.errors import ModelError
from pliant.files import load_npz, save_npz
from pliant.learn.evaluate import load_policy
from pliant.transfer.fem_rl import FEM_KWARGS
from pliant.transfer.fem_rl import OUT as FEM_VS_PROXY

#: What chooses an action on the FEM: (observation, episode's rng) -> action (Box(9)).
Policy = Callable[[np.ndarray, np.random.Generator], np.ndarray]


@dataclass(frozen=True)
class Pushes:
    """Episodes of the FEM Trunk pushing the cube: the proxy environment's actions that
    replay them (E, T, 9) and the FEM cube's centre at the start and after each step (E, T +
    1, 3), with the episodes' kinds (E,) (which policy made each, e.g. "random" or a
    policy's name)."""

    actions: np.ndarray
    cubes: np.ndarray
    kinds: np.ndarray

    def __post_init__(self) -> None:
        e, t = self.actions.shape[:2]
        if (
            self.cubes.shape != (e, t + 1, 3)
            or self.actions.shape[2:] != (9,)
            or len(self.kinds) != e
        ):
            raise ModelError(
                f"pushes need actions (E, T, 9), cubes (E, T + 1, 3) and E kinds, got "
                f"{self.actions.shape}, {self.cubes.shape}, {len(self.kinds)}"
            )

    def save(self, path) -> None:
        save_npz(path, compressed=True, actions=self.actions, cubes=self.cubes, kinds=self.kinds)

    @classmethod
    def load(cls, path) -> Pushes:
        """Raises CorruptFileError for a damaged file, FileNotFoundError for none."""
        data = load_npz(path, "a set of proxy pushes")
        return cls(data["actions"], data["cubes"], data["kinds"].astype(str))

    def __add__(self, other: Pushes) -> Pushes:
        return Pushes(
            np.concatenate([self.actions, other.actions]),
            np.concatenate([self.cubes, other.cubes]),
            np.concatenate([self.kinds, other.kinds]),
        )


def random_policy(std: float = 0.37) -> Policy:
    """Actions drawn around the middle of the FEM's box with standard deviation `std`, clipped
    to it: what an untrained PPO policy of that initial std (log_std_init -1) explores."""

    def choose(obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.clip(rng.normal(0.0, std, 9), -1.0, 1.0)

    return choose


def fem_pushes(
    policy: Policy,
    episodes: int,
    *,
    kind: str = "policy",
    steps: int = 10,
    seed: int = 0,
    env_kwargs: Mapping | None = None,
) -> Pushes:
    """`episodes` episodes of `steps` steps of the FEM Trunk (``TrunkPushEnv(**env_kwargs)``)
    under `policy`, episode k reset with seed `seed` + k (its goal; the cube starts where it
    always does) and run its `steps` steps whether or not the goal is reached. ModelError if
    the FEM diverges: a reference must be a physical trajectory."""
    if episodes < 1 or steps < 1:
        raise ModelError(f"pushes need at least one episode of one step, got {episodes}, {steps}")
    kwargs = dict(env_kwargs or {})
    courses = np.array([kwargs.get("max_long_displacement", 70.0)] * 4
                       + [kwargs.get("max_short_displacement", 40.0)] * 4)  # fmt: skip
    # The proxy's cable actions are fractions of its courses times its bend_limit: the same
    # cables only where the FEM's courses are CABLE_COURSES times that limit.
    if not np.allclose(courses / CABLE_COURSES, courses[0] / CABLE_COURSES[0]):
        raise ModelError(f"the FEM's courses {courses[[0, 4]]} are not one fraction of 70/40 mm")
    env = TrunkPushEnv(**kwargs)
    if env.action_space.shape != (9,):
        raise ModelError("pushes replay the FEM Trunk's Box(9) actions (continuous, all cables)")
    actions, cubes = np.zeros((episodes, steps, 9)), np.zeros((episodes, steps + 1, 3))
    for e in range(episodes):
        obs, _ = env.reset(seed=seed + e)
        cubes[e, 0] = env.cube()
        rng = np.random.default_rng(seed + e)
        for k in range(steps):
            action = np.asarray(policy(obs, rng), dtype=float)
            obs, _, _, truncated, info = env.step(action)
            if truncated and "diverged" in info:
                raise ModelError(f"the FEM diverged in episode {e}, step {k}: {info['diverged']}")
            reached = env.state.displacement
            actions[e, k, :8] = np.clip(2.0 * reached / courses - 1.0, -1.0, 1.0)
            actions[e, k, 8] = action[8]
            cubes[e, k + 1] = env.cube()
    env.close()
    return Pushes(actions, cubes, np.array([kind] * episodes))


def proxy_pushes(pushes: Pushes, env_kwargs: Mapping | None = None) -> np.ndarray:
    """(E, T + 1, 3) the proxy's cube at the start and after each step of `pushes` replayed on
    ``TrunkPushProxyEnv(actions="cables", **env_kwargs)`` (its bend_limit must be the FEM's
    courses over 70/40 mm, 0.2 for 14/8 mm). ModelError if the proxy diverges."""
    env = TrunkPushProxyEnv(**{**dict(env_kwargs or {}), "actions": "cables"})
    cubes = np.zeros(pushes.cubes.shape)
    for e, episode in enumerate(pushes.actions):
        env.reset(seed=0)
        cubes[e, 0] = env.cube()
        for k, action in enumerate(episode):
            _, _, _, truncated, info = env.step(action)
            if truncated and "diverged" in info:
                raise ModelError(f"the proxy diverged in episode {e}, step {k}: {info['diverged']}")
            cubes[e, k + 1] = env.cube()
    env.close()
    return cubes


def cube_travel(cubes: np.ndarray) -> np.ndarray:
    """(E,) how far each episode's cube (E, T + 1, 3) ended from where it started, in the
    floor's plane (mm)."""
    return np.hypot(*(cubes[:, -1, [0, 2]] - cubes[:, 0, [0, 2]]).T)


#: The FEM policies whose greedy episodes the push calibration fits the proxy's cube on (PPO on
#: the FEM, seeds 0-4, experiments/proxy/vs_fem_rl.py's runs in fem_vs_proxy/).
PUSH_POLICIES = ["std1"] + [f"std1_seed{s}" for s in range(1, 5)]


def reference_pushes(
    per_policy: int, random_episodes: int, moved: float, policies: Path = FEM_VS_PROXY
) -> Pushes:
    """The FEM's pushes: each of :data:`PUSH_POLICIES`' (in `policies`) `per_policy` greedy
    episodes, then `random_episodes` of random actions at each of two spreads, kept where they
    moved the cube at least `moved` mm."""
    pushes = []
    for k, name in enumerate(PUSH_POLICIES):
        saved = load_policy(Path(policies) / name)

        def greedy(obs, rng, saved=saved):
            return saved.model.predict(saved.normalize_obs(obs), deterministic=True)[0]

        pushes.append(
            fem_pushes(greedy, per_policy, kind=name, seed=3000 + 100 * k, env_kwargs=FEM_KWARGS)
        )
    for std, seed in ((1.0, 5000), (0.37, 6000)):
        drawn = fem_pushes(
            random_policy(std),
            random_episodes,
            kind=f"random{std:g}",
            seed=seed,
            env_kwargs=FEM_KWARGS,
        )
        keep = cube_travel(drawn.cubes) >= moved
        pushes.append(Pushes(drawn.actions[keep], drawn.cubes[keep], drawn.kinds[keep]))
    out = pushes[0]
    for p in pushes[1:]:
        out = out + p
    return out
