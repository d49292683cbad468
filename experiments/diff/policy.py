"""Analytic policy gradients against PPO on Diamond reaching, in environment steps to success.

    python experiments/diff/policy.py [--quick] [--fresh] [--learner apg|ppo] [--report]
        [--apg-steps N] [--ppo-steps N] [--evals K] [--out FILE]
    python experiments/diff/policy.py --evaluate experiments/results/diff/policy_models
        [--out FILE]

The environment is pliant/Diamond-v0 with continuous absolute actions (the four cable
displacements in [0, 20] mm, ramped over 5 solver steps of 0.01 s), the Diamond at mesh size
20 mm, an episode of at most 50 steps, success as the environment defines it: the effector
within ``goal_tolerance`` = 5 mm of the goal (terminated, ``info["is_success"]``).

**Goals where the robot reaches.** The environment's default goals (SofaGym's box, x and y in
[-30, 30] mm) lie mostly outside this Diamond's workspace (its cables move the effector about
15 mm sideways), so both learners get goals the robot can reach by construction: the effector's
position after holding uniform random actions for ``--settle`` environment steps from the
reset state, kept when it lies further than the tolerance from the start. A bank of training
goals (seed 0), validation goals (seed 1) that select each learner's policy, and held-out test
goals (seed 2026) drawn after both have trained, on which the selected policies are reported.

* **APG** (analytic policy gradients): an MLP (the 18 observations of the environment, computed
  from the state in torch, 2 x 64 tanh, 4 tanh outputs mapped to the displacements as the
  environment maps actions) trained by Adam on the exact gradient of one episode's loss, the
  mean effector-goal distance over ``--horizon`` control steps (pliant.diff.policy.closed_loop:
  the same ramps and solver steps, "fresh" tangent; each episode's backward pass is its
  adjoint sweep). One training episode counts ``--horizon`` environment steps.
* **PPO** (stable-baselines3, MlpPolicy, its defaults but n_steps = 128, batch 64) on the
  environment itself, its resets drawing goals from the same training bank.

Each learner is evaluated ``--evals`` times along its budget on the validation goals
(deterministic actions, in the environment, "lagged" tangent as RL runs it): success rate and
mean final distance, the curves of success against environment steps. ``--learner`` trains one
learner (the two can run side by side), checkpointing after each evaluation so that a run cut
short resumes; ``--report`` (or the plain command, after both) picks each learner's policy on
validation, draws the test goals, evaluates, and writes the result file and its figure; the
study's run keeps the two selected policies in experiments/results/diff/policy_models
(``--evaluate`` tests them again on the held-out goals, from the repository alone).
Timings are wall-clock on a shared 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import pliant.envs  # noqa: E402, F401  (registers the environments)
from pliant.diff.policy import closed_loop, embedded_positions  # noqa: E402
from pliant.files import atomic_path, write_results  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.viz import save_figure

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "diff" / "policy.json"
ENV_ID = "pliant/Diamond-v0"
ENV_KWARGS = {"action_type": "continuous", "continuous_mode": "absolute", "mesh_size": 20.0}
SEEDS = {"train": 0, "validation": 1, "test": 2026}
LEARNERS = ("apg", "ppo")
# The selected policies, kept (small) for `--evaluate`: the APG network's state and the SB3 zip.
KEPT = ROOT / "experiments" / "results" / "diff" / "policy_models"
KEPT_FILES = {"apg": "apg.pt", "ppo": "ppo.zip"}


class MLP(torch.nn.Module):
    def __init__(self, n_in: int, n_out: int, width: int = 64) -> None:
        super().__init__()
        self.net = torch.nn.Sequential(
            torch.nn.Linear(n_in, width),
            torch.nn.Tanh(),
            torch.nn.Linear(width, width),
            torch.nn.Tanh(),
            torch.nn.Linear(width, n_out),
            torch.nn.Tanh(),
        ).double()

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.net(obs)


class GoalBank(gym.Wrapper):
    """Resets draw their goal from a bank (PPO's training goals)."""

    def __init__(self, env, goals: np.ndarray, seed: int) -> None:
        super().__init__(env)
        self.goals = goals
        self.rng = np.random.default_rng(seed)

    def reset(self, *, seed=None, options=None):
        goal = self.goals[self.rng.integers(len(self.goals))]
        return self.env.reset(seed=seed, options={**(options or {}), "goal": goal})


def make_env():
    return gym.make(ENV_ID, **ENV_KWARGS)


def reachable_goals(env, n: int, seed: int, settle: int) -> np.ndarray:
    """(n, 3) effector positions after holding uniform random actions for `settle` steps from
    the reset state, each further than the tolerance from the start."""
    inner = env.unwrapped
    rng = np.random.default_rng(seed)
    goals = []
    while len(goals) < n:
        env.reset(seed=0)
        start = inner.effector_position().copy()
        action = rng.uniform(-1.0, 1.0, env.action_space.shape)
        for _ in range(settle):
            env.step(action)
        point = inner.effector_position().copy()
        if np.linalg.norm(point - start) > inner.goal_tolerance:
            goals.append(point)
    return np.array(goals)


def goal_set(folder: Path, env, name: str, n: int, settle: int) -> np.ndarray:
    """The named goals, drawn once and kept in `folder`."""
    path = folder / f"goals_{name}.npy"
    if path.exists():
        goals = np.load(path)
        if len(goals) >= n:  # the same draw's first n
            return goals[:n]
    goals = reachable_goals(env, n, SEEDS[name], settle)
    with atomic_path(path) as tmp, open(tmp, "wb") as stream:
        np.save(stream, goals)
    return goals


def observation(env, q: torch.Tensor, goal: torch.Tensor) -> torch.Tensor:
    """The environment's observation (DiamondEnv._observe) from positions, in torch."""
    model = env.model
    points = [embedded_positions(model.effectors[0].points, q)[0]]
    points += [embedded_positions(a.points, q)[0] for a in model.actuators]
    return torch.cat([*points, goal]) / env.length_scale


def evaluate(env, act, goals: np.ndarray) -> dict:
    """Success rate and mean final distance of the deterministic policy `act(obs)` over the
    goals, in the environment."""
    successes, finals = [], []
    for goal in goals:
        obs, _ = env.reset(seed=0, options={"goal": goal})
        info = {"is_success": False}
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(act(obs))
            done = terminated or truncated
        successes.append(bool(info.get("is_success", False)))
        finals.append(float(env.unwrapped.distance()))
    return {"success_rate": float(np.mean(successes)), "final_distance_mm": float(np.mean(finals))}


def apg_actor(policy):
    def act(obs):
        with torch.no_grad():
            return policy(torch.as_tensor(obs, dtype=torch.float64)).numpy()

    return act


def new_policy(env) -> MLP:
    torch.manual_seed(0)
    return MLP(18, env.unwrapped.model.n_actuators)


def train_apg(args, folder: Path, record: dict, goals: dict):
    env, eval_env = make_env(), make_env()
    inner = env.unwrapped
    model = inner.model
    solver = ImplicitEuler(model, inner.dt, tangent="fresh")
    env.reset(seed=0)
    start = inner.state.copy()
    policy = new_policy(env)
    optimiser = torch.optim.Adam(policy.parameters(), lr=args.apg_lr)
    rng = np.random.default_rng(SEEDS["train"])
    checkpoint = folder / "apg.pt"
    if checkpoint.exists() and record["steps"]:
        saved = torch.load(checkpoint, weights_only=False)
        policy.load_state_dict(saved["policy"])
        optimiser.load_state_dict(saved["optimiser"])
        rng.bit_generator.state = saved["rng"]
    max_commands = torch.as_tensor(inner.max_commands)
    effector = model.effectors[0].points
    every = args.apg_steps // args.evals
    while record["steps"] < args.apg_steps:
        clock = time.perf_counter()
        goal = torch.as_tensor(goals["train"][rng.integers(len(goals["train"]))])

        def command(q, v, n, goal=goal):
            return 0.5 * (policy(observation(inner, q, goal)) + 1.0) * max_commands

        episode = closed_loop(model, solver, start, command, args.horizon, substeps=inner.substeps)
        reached = torch.stack([embedded_positions(effector, q)[0] for q, _ in episode[1:]])
        loss = torch.linalg.norm(reached - goal, dim=1).mean() / 10.0
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        record["steps"] += args.horizon
        record["episodes"] += 1
        record["seconds"] += time.perf_counter() - clock
        record["losses"].append(float(loss.detach()) * 10.0)
        if record["steps"] % every < args.horizon or record["steps"] >= args.apg_steps:
            name = f"apg_{record['steps']}.pt"
            torch.save(policy.state_dict(), folder / name)
            point = {"env_steps": record["steps"], "train_seconds": record["seconds"]}
            point.update(evaluate(eval_env, apg_actor(policy), goals["validation"]))
            point["checkpoint"] = name
            record["curve"].append(point)
            state = {"policy": policy.state_dict(), "optimiser": optimiser.state_dict()}
            torch.save({**state, "rng": rng.bit_generator.state}, checkpoint)
            print("APG", point, flush=True)
            yield


def train_ppo(args, folder: Path, record: dict, goals: dict):
    from stable_baselines3 import PPO

    env = GoalBank(make_env(), goals["train"], SEEDS["train"])
    eval_env = make_env()
    checkpoint = folder / "ppo.zip"
    if checkpoint.exists() and record["steps"]:
        agent = PPO.load(checkpoint, env=env)
    else:
        rollout = min(128, args.ppo_steps)
        agent = PPO("MlpPolicy", env, n_steps=rollout, batch_size=min(64, rollout), seed=0)
    every = max(args.ppo_steps // args.evals, 1)
    while record["steps"] < args.ppo_steps:
        clock = time.perf_counter()
        chunk = min(every, args.ppo_steps - record["steps"])
        agent.learn(chunk, reset_num_timesteps=False)
        record["steps"] = int(agent.num_timesteps)
        record["seconds"] += time.perf_counter() - clock
        name = f"ppo_{record['steps']}.zip"
        agent.save(folder / name)
        agent.save(checkpoint)
        point = {"env_steps": record["steps"], "train_seconds": record["seconds"]}
        point.update(evaluate(eval_env, ppo_actor(agent), goals["validation"]))
        point["checkpoint"] = name
        record["curve"].append(point)
        print("PPO", point, flush=True)
        yield


def ppo_actor(agent):
    def act(obs):
        return agent.predict(obs, deterministic=True)[0]

    return act


def load_actor(name: str, folder: Path, checkpoint: str):
    if name == "apg":
        policy = new_policy(make_env())
        policy.load_state_dict(torch.load(folder / checkpoint, weights_only=False))
        return apg_actor(policy)
    from stable_baselines3 import PPO

    return ppo_actor(PPO.load(folder / checkpoint))


def steps_to(curve: list[dict], level: float) -> int | None:
    """The fewest environment steps at which the validation success reached `level`."""
    for point in curve:
        if point["success_rate"] >= level - 1e-12:
            return point["env_steps"]
    return None


def select(curve: list[dict]) -> dict:
    """The evaluation with the best validation success (then the smallest distance)."""
    return max(curve, key=lambda p: (p["success_rate"], -p["final_distance_mm"]))


def run_learner(name: str, args, folder: Path, goals: dict) -> dict:
    """Train (or resume) one learner, then test its policy selected on validation on the
    held-out goals, drawn now that it has trained."""
    path = folder / f"{name}.json"
    blank = {"curve": [], "steps": 0, "seconds": 0.0}
    if name == "apg":
        blank.update(episodes=0, losses=[])
    record = json.loads(path.read_text()) if path.exists() and not args.fresh else blank
    learner = train_apg if name == "apg" else train_ppo
    for _ in learner(args, folder, record, goals):
        record.pop("test", None)
        write_results(path, record)
    best = select(record["curve"])
    if record.get("test", {}).get("checkpoint") != best["checkpoint"]:
        env = make_env()
        # Held-out goals: drawn after training, from their own seed.
        test = goal_set(folder, env, "test", args.test_goals, args.settle)
        record["test"] = evaluate(env, load_actor(name, folder, best["checkpoint"]), test)
        record["test"]["checkpoint"] = best["checkpoint"]
        print(name.upper(), "test", record["test"], flush=True)
    write_results(path, record)
    return record


def keep(folder: Path, records: dict) -> dict:
    """Copy each learner's selected policy to KEPT (what `--evaluate` reads); their paths."""
    KEPT.mkdir(parents=True, exist_ok=True)
    kept = {}
    for name, record in records.items():
        target = KEPT / KEPT_FILES[name]
        with atomic_path(target) as tmp:
            shutil.copyfile(folder / select(record["curve"])["checkpoint"], tmp)
        kept[name] = str(target.relative_to(ROOT))
    return kept


def evaluate_kept(args, models: Path, out: Path) -> None:
    """The kept policies on the held-out test goals (drawn again from their seed, beside the
    result file), as the report evaluates them: the test figures of the result file."""
    env = make_env()
    goals = goal_set(out.parent, env, "test", args.test_goals, args.settle)
    result = {"evaluated": str(models), "test_goals": len(goals)}
    for name in LEARNERS:
        actor = load_actor(name, models, KEPT_FILES[name])
        result[name] = {"test": evaluate(env, actor, goals)}
        print(name.upper(), "test", result[name]["test"], flush=True)
    write_results(out, result)
    print(f"wrote {out}")


def report(args, folder: Path, out: Path, settings: dict) -> None:
    records = {name: json.loads((folder / f"{name}.json").read_text()) for name in LEARNERS}
    result = {"setting": settings}
    if out == OUT:  # the study's own run keeps its selected policies
        result["kept"] = keep(folder, records)
    for name, record in records.items():
        curve = record["curve"]
        best = select(curve)
        held = record["test"]
        summary = {key: record[key] for key in ("steps", "seconds") if key in record}
        summary["episodes"] = record.get("episodes")
        summary["env_steps_per_s"] = record["steps"] / max(record["seconds"], 1e-9)
        summary["curve"] = curve
        summary["best_validation_success_rate"] = best["success_rate"]
        summary["selected"] = {"env_steps": best["env_steps"], "checkpoint": best["checkpoint"]}
        summary["test"] = held
        if name == "apg":
            summary["losses"] = record["losses"]
        result[name] = summary
    common = min(result[name]["best_validation_success_rate"] for name in LEARNERS)
    result["same_success"] = {
        "level": common,
        "env_steps": {
            name: (steps_to(result[name]["curve"], common) if common > 0 else None)
            for name in LEARNERS
        },
    }
    levels = sorted({p["success_rate"] for n in LEARNERS for p in result[n]["curve"]} - {0.0})
    result["steps_to_success"] = [
        {"level": level, **{name: steps_to(result[name]["curve"], level) for name in LEARNERS}}
        for level in levels
    ]
    write_results(out, result)
    plot(result, out.with_suffix(".png"))
    print(f"wrote {out}")


def plot(result: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for name, label in (("apg", "analytic policy gradient"), ("ppo", "PPO")):
        curve = result[name]["curve"]
        steps = [p["env_steps"] for p in curve]
        axes[0].plot(steps, [100 * p["success_rate"] for p in curve], "o-", label=label)
        axes[1].plot(steps, [p["final_distance_mm"] for p in curve], "o-", label=label)
    axes[0].set_ylabel("success on validation goals (%)")
    axes[1].set_ylabel("mean final distance (mm)")
    for ax in axes:
        ax.set_xlabel("environment steps")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle("Diamond reaching (reachable goals, success within 5 mm)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few episodes, 2 goals")
    parser.add_argument("--fresh", action="store_true", help="start the learners again")
    parser.add_argument("--learner", choices=LEARNERS, help="train this one only")
    parser.add_argument("--report", action="store_true", help="only select, test and write")
    parser.add_argument("--apg-steps", type=int, default=2400, help="APG's environment steps")
    parser.add_argument("--ppo-steps", type=int, default=4608, help="PPO's environment steps")
    parser.add_argument("--evals", type=int, default=6, help="validations along each budget")
    parser.add_argument("--train-goals", type=int, default=64)
    parser.add_argument("--validation-goals", type=int, default=5)
    parser.add_argument("--test-goals", type=int, default=10)
    parser.add_argument("--settle", type=int, default=8, help="steps held to make a goal")
    parser.add_argument("--horizon", type=int, default=10, help="APG episode, control steps")
    parser.add_argument("--apg-lr", type=float, default=5e-3)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument(
        "--evaluate",
        type=Path,
        metavar="DIR",
        help="only test the kept policies in DIR (apg.pt, ppo.zip) on the held-out goals",
    )
    args = parser.parse_args()
    if args.quick:
        args.apg_steps, args.ppo_steps, args.evals, args.horizon, args.settle = 8, 16, 1, 4, 3
        args.train_goals, args.validation_goals, args.test_goals = 4, 1, 1
    torch.set_num_threads(1)
    if args.evaluate is not None:
        out = args.out or (ROOT / "out" / "diff" / "policy_evaluated.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        evaluate_kept(args, args.evaluate, out)
        return
    out = args.out or (ROOT / "out" / "diff" / "policy_quick.json" if args.quick else OUT)
    folder = ROOT / "out" / "diff" / ("policy_quick" if args.quick else "policy")
    folder.mkdir(parents=True, exist_ok=True)
    env = make_env()
    inner = env.unwrapped
    settings = {
        "env": ENV_ID,
        "env_kwargs": ENV_KWARGS,
        "success": f"effector within {inner.goal_tolerance} mm of the goal (terminated)",
        "episode_steps": env.spec.max_episode_steps,
        "goals": f"effector after {args.settle} steps holding a uniform random action from"
        f" the reset state, further than {inner.goal_tolerance} mm from the start",
        "goal_seeds": SEEDS,
        "train_goals": args.train_goals,
        "validation_goals": args.validation_goals,
        "test_goals": args.test_goals,
        "budget_env_steps": {"apg": args.apg_steps, "ppo": args.ppo_steps},
        "evaluations": args.evals,
        "apg_horizon": args.horizon,
        "apg_lr": args.apg_lr,
        "ppo": "stable-baselines3 PPO, MlpPolicy, n_steps min(128, budget), batch 64, seed 0",
        "machine": "shared 2-core machine (other sessions' jobs beside it), one torch thread",
        "command": "python experiments/diff/policy.py" + (" --quick" if args.quick else ""),
        "run_as": "--learner apg and --learner ppo side by side under nice, then --report"
        " (the plain command runs them one after the other)",
    }
    goals = {
        name: goal_set(folder, env, name, getattr(args, f"{name}_goals"), args.settle)
        for name in ("train", "validation")
    }
    if not args.report:
        for name in (args.learner,) if args.learner else LEARNERS:
            run_learner(name, args, folder, goals)
    if args.report or not args.learner:
        report(args, folder, out, settings)


if __name__ == "__main__":
    main()
