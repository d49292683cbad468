"""Tutorial 3: a Gymnasium environment, saved and restored exactly, and a random rollout."""

import gymnasium as gym
import numpy as np
from _common import QUICK, out

import pliant.envs  # registers pliant/<Name>-v0
from pliant.viz import save_gif

env = gym.make("pliant/CartStemContact-v0", render_mode="rgb_array")
obs, info = env.reset(seed=0)
snapshot = pliant.envs.get_state(env)  # the whole simulation, picklable

frames, rewards = [env.render()], []
for _ in range(3 if QUICK else 20):
    obs, reward, terminated, truncated, info = env.step(np.array([-1.0], dtype=np.float32))
    rewards.append(reward)
    frames.append(env.render())
    if terminated or truncated:
        break

pliant.envs.set_state(env, snapshot)  # back to the start: the same actions replay exactly
again = [env.step(np.array([-1.0], dtype=np.float32))[1] for _ in rewards]
assert again == rewards
print(f"{len(rewards)} steps, return {sum(rewards):.3f}, tip-goal {info['distance']:.1f} mm")
save_gif(frames, out("cartstem_env.gif"), fps=4)
