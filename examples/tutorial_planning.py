"""Tutorial: planning (thesis §2.2.2). OPD searches a tree of saved simulation states to keep
the CartStem's soft stem upright on its cart (the episode ends when the tip strays 15 mm from
the cart or the cart leaves +-100 mm); random actions end it within a few seconds."""

import gymnasium as gym
import numpy as np
from _common import QUICK, save_figure

import pliant.envs  # noqa: F401  registers pliant/<Name>-v0
from pliant.planning import OPD, check_restorable
from pliant.viz.render import offscreen_figure

env = gym.make("pliant/CartStem-v0")  # Discrete(2): accelerate the cart left or right
length = env.unwrapped.length
steps = 20 if QUICK else 80  # the episode's time limit is 80 steps of 0.1 s


def episode(choose, seed: int) -> list[float]:
    """Play `choose(env) -> action` from a seeded reset; the tip's offset from the cart (mm)."""
    obs, _ = env.reset(seed=seed)
    offsets = [obs[2] * length]
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(choose(env))
        offsets.append(obs[2] * length)
        if terminated or truncated:
            break
    return offsets


# The planner restores saved states: the simulation must replay bit for bit.
env.reset(seed=0)
check_restorable(env, [0, 1, 1, 0])

fig = offscreen_figure(7.0, 4.0)
ax = fig.add_subplot(1, 1, 1)
for seed in range(3):
    env.action_space.seed(seed)
    offsets = episode(lambda e: e.action_space.sample(), seed)
    ax.plot(
        0.1 * np.arange(len(offsets)), offsets, color="0.6", label="random" if seed == 0 else None
    )
    print(f"random actions, seed {seed}: {len(offsets) - 1} steps")

# OPD (Hren & Munos 2008): each decision expands budget // 2 leaves of the tree, restoring
# each leaf's saved state, and plays the root child with the best lower bound.
planner = OPD(budget=16, gamma=0.9)


def plan(e):
    action = planner.plan(e)  # the environment is left where it was
    planner.step(action)  # the played child becomes the root: its subtree is kept
    return action


planner.reset()
offsets = episode(plan, seed=0)
print(f"OPD, budget 16: {len(offsets) - 1} steps, last decision {planner.last}")
ax.plot(0.1 * np.arange(len(offsets)), offsets, "C0", label="OPD, budget 16")
for side in (-15.0, 15.0):
    ax.axhline(side, color="k", ls=":")
ax.set_xlabel("time (s)")
ax.set_ylabel("tip - cart (mm)")
ax.set_title("CartStem: 8 s episodes, ended early by random actions")
ax.legend()
ax.grid(alpha=0.3)
save_figure(fig, "planning_cartstem.png")
