"""Every registered environment (quick variant), in each of its action spaces and option
variants, replays a recorded rollout: 10 seeded random actions from ``reset(seed=0)`` give the
observations, rewards, end flags and commands recorded in ``data/env_rollouts.npz``.

The recording was made before the environments' constructors and action maps were refactored
(one simulation config, composable action maps), so that the refactor is held to the
behaviour it replaced. It is bit-exact on the machine that recorded it; the tolerance absorbs
another CPU's rounding of the compiled kernels. CI runs each environment's default action
space and a few option variants (about 20 of the 51); the rest are marked slow. Regenerate
(only when a behaviour change is intended) with ``python tests/envs/test_env_rollouts.py``.
"""

from __future__ import annotations

import importlib
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.envs import ENVS

DATA = Path(__file__).parent / "data" / "env_rollouts.npz"
STEPS = 10

#: (variant name, environment, keyword arguments over the quick variant's).
EXTRA = [
    ("Diamond-increment", "Diamond", {"action_type": "continuous", "continuous_mode": "increment"}),
    ("Diamond-sofagym", "Diamond", {"reward": "sofagym"}),
    ("Trunk-sofagym", "Trunk", {"reward": "sofagym"}),
    ("TrunkCup-sofagym", "TrunkCup", {"reward": "sofagym"}),
    ("TrunkPush-planar", "TrunkPush", {"planar": True}),
    ("TrunkPush-planar-discrete", "TrunkPush", {"planar": True, "action_type": "discrete"}),
    ("TrunkPush-increment", "TrunkPush", {"continuous_mode": "increment", "reward": "sofagym"}),
    ("TrunkPushProxy-planar", "TrunkPushProxy", {"planar": True}),
    ("TrunkPushProxy-cables", "TrunkPushProxy", {"actions": "cables"}),
    ("Multigait-asymmetric", "Multigait", {"action_type": "continuous", "symmetric": False}),
    ("Gripper-sofagym", "Gripper", {"observation": "sofagym", "reward": "sofagym"}),
    ("Gripper-push", "Gripper", {"action_type": "continuous", "cube_push_down": True}),
    ("CartStemContact-sofagym", "CartStemContact", {"observation": "sofagym", "reward": "sofagym"}),
    ("RodManipulator-sofagym", "RodManipulator", {"reward": "sofagym"}),
    ("TrunkSpaceDebris-increment", "TrunkSpaceDebris", {"continuous_mode": "increment"}),
]


#: Variants CI runs (``-m "not slow"``): each environment in its default action space (but the
#: two FEM Multigaits, whose chamber groups MultigaitProxy runs through the same action map)
#: and the option variants whose action maps take other paths; the rest are marked slow.
FAST_EXTRA = {"TrunkPush-planar-discrete", "TrunkPush-increment", "TrunkPushProxy-cables"}
SLOW_ENVS = {"Multigait", "ReducedMultigait"}


def variants() -> list[tuple[str, str, dict]]:
    out = []
    for name in sorted(ENVS):
        for kind in ("discrete", "continuous"):
            out.append((f"{name}-{kind}", name, {"action_type": kind}))
    return out + EXTRA


def _fast(variant: str, name: str) -> bool:
    if variant in FAST_EXTRA or variant == "Gripper-push":
        return True
    default = gym.spec(f"pliant/{name}-v0").entry_point
    module, cls = default.split(":")
    kind = getattr(importlib.import_module(module), cls).default_config.action_type
    return name not in SLOW_ENVS and variant == f"{name}-{kind}"


def rollout(name: str, kwargs: dict) -> dict[str, np.ndarray]:
    """Observations (reset's first), rewards, terminated/truncated and the unwrapped
    environment's commands after each of STEPS seeded random actions (a new episode, seeded
    on, after one that ends)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make(f"pliant/{name}-v0", **{**ENVS[name].quick, **kwargs})
        obs, _ = env.reset(seed=0)
        env.action_space.seed(0)
        observations, rewards, ends, commands = [obs], [], [], []
        for _ in range(STEPS):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            observations.append(obs)
            rewards.append(reward)
            ends.append((terminated, truncated))
            commands.append(np.array(env.unwrapped.commands, dtype=float).ravel())
            if terminated or truncated:
                obs, _ = env.reset()
        env.close()
    return {
        "obs": np.asarray(observations),
        "reward": np.asarray(rewards, dtype=float),
        "ends": np.asarray(ends, dtype=bool),
        "commands": np.asarray(commands),
    }


def _ids() -> list:
    slow = pytest.mark.slow
    return [
        pytest.param(v, n, k, id=v, marks=() if _fast(v, n) else slow) for v, n, k in variants()
    ]


@pytest.fixture(scope="module")
def recorded():
    if not DATA.exists():
        pytest.fail(f"{DATA} is missing: run python {Path(__file__).name} to record it")
    with np.load(DATA) as data:
        return {key: data[key] for key in data.files}


@pytest.mark.parametrize(("variant", "name", "kwargs"), _ids())
def test_rollout_replays_the_recorded_one(recorded, variant, name, kwargs):
    got = rollout(name, kwargs)
    for key, value in got.items():
        expected = recorded[f"{variant}/{key}"]
        assert value.shape == expected.shape, f"{variant}: {key} shape"
        if value.dtype == bool:
            np.testing.assert_array_equal(value, expected, err_msg=f"{variant}: {key}")
        else:
            np.testing.assert_allclose(
                value, expected, rtol=1e-6, atol=1e-9, err_msg=f"{variant}: {key}"
            )


def test_every_registered_environment_is_recorded(recorded):
    names = {key.split("/")[0].rsplit("-", 1)[0] for key in recorded if key.endswith("/obs")}
    assert set(ENVS) <= names


if __name__ == "__main__":
    arrays = {}
    for variant, name, kwargs in variants():
        for key, value in rollout(name, kwargs).items():
            arrays[f"{variant}/{key}"] = value
        print(variant, flush=True)
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, **arrays)
    print(f"wrote {DATA} ({DATA.stat().st_size} bytes)")
