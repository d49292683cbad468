"""Table 3.2: the hand-defined gait against a gait learned by PPO on the reduced Multigait, each
replayed on the reduced model and on the full FEM (default mesh, SofaGym's reward max(0, dx)).

    # 1. train (resumable: add --resume to go on after an interruption), about 20 min here
    python -m pliant.cli train pliant/ReducedMultigait-v0 --algo PPO \
        --config pliant/learn/configs/Multigait.yaml --out runs/table_3_2_ppo --seed 0 \
        --env-kwarg 'training={"sequences": 20}'
    # (20 is now the environment's default; the committed run with the former default of 3,
    # table_3_2_sequences3.json, was made with 'training={"sequences": 3}'.)
    # 2. replay the gaits on both models, write the table, keep the policies (small .npz)
    python experiments/reduction/table_3_2.py --run runs/table_3_2_ppo \
        --keep experiments/results/reduction/table_3_2_policies
    # re-evaluate the kept policies from the repository alone (pliant reproduce table-3.2
    # --evaluate): the same replays, into another folder
    python experiments/reduction/table_3_2.py \
        --evaluate experiments/results/reduction/table_3_2_policies --out /tmp/t32

The learned gait is the deterministic episode, from the environment's reset, of the run's best
evaluated policy (the task has no randomness: every episode starts at rest, so an evaluation
is this very episode: the selection and the figure are one episode); the final policy's gait,
chosen by nothing, is replayed beside it (``final``). Writes
experiments/results/reduction/table_3_2.json and .png with the learning curve (mean return of
the run's evaluations against environment steps) and the thesis' figures beside ours.
The thesis' figures are on SofaGym's reference mesh and its command sizes, in cm; ours on
Pliant's default Multigait mesh, in mm: compare the ordering (learned against hand, reduced
against full), not the values.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np

import pliant.envs  # noqa: F401  (registers the environments)
from pliant.files import write_results
from pliant.viz import save_figure

HAND = [4, 0, 2, 5, 1, 3]  # rear, centre, front inflated; then deflated in that order
# Thesis Table 3.2 (cm): cumulative reward on the reduced model, final x on the reduced and on
# the complete model.
THESIS = {
    "hand": {"reduced_reward_cm": 5.38, "reduced_x_cm": 3.24, "full_x_cm": 3.56},
    "learned": {"reduced_reward_cm": 6.33, "reduced_x_cm": 4.51, "full_x_cm": 6.21},
}


def replay(env_id: str, actions: list[int], **kwargs) -> dict:
    """The action sequence on `env_id`: rewards, cumulative reward and final travel (mm)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rewards, info = [], {}
    began = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for action in actions:
            _, reward, terminated, truncated, info = env.step(int(action))
            rewards.append(float(reward))
            if terminated or truncated:
                break
    env.close()
    return {
        "rewards_mm": rewards,
        "cumulative_reward_mm": float(sum(rewards)),
        "final_travel_mm": info.get("travelled"),
        "wall_s": time.perf_counter() - began,
    }


def run_env_kwargs(run: Path) -> dict:
    """The environment arguments the run trained with (its config.yaml): the same reduced
    model (e.g. its training load cases) for the replays."""
    import yaml

    return yaml.safe_load((run / "config.yaml").read_text()).get("env_kwargs") or {}


def policy_actions(source: Path, env_kwargs: dict) -> list[int]:
    """The deterministic actions over one episode of the reduced model of the policy in
    `source` (a run's best/ or final/, or a kept policy .npz)."""
    from pliant.learn.evaluate import load_policy

    policy = load_policy(source)
    env = gym.make("pliant/ReducedMultigait-v0", **env_kwargs)
    obs, _ = env.reset(seed=0)
    actions, done = [], False
    normalize = policy.normalize_obs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        while not done:
            x = normalize(obs) if normalize is not None else obs
            action, _ = policy.model.predict(x, deterministic=True)
            actions.append(int(action))
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    env.close()
    return actions


def run_policies(run: Path) -> dict[str, Path]:
    """The run's best evaluated policy (evaluations are this deterministic episode; the last
    one where the run saved no best) and its final one."""
    best = run / "best" if (run / "best" / "model.zip").exists() else run / "final"
    return {"learned": best, "final": run / "final"}


def kept_policies(folder: Path) -> tuple[dict[str, Path], dict]:
    """The kept policies (policy_learned.npz, policy_final.npz) and the reduced model's
    arguments they were trained with (their provenance)."""
    from pliant.learn.kept import load_policy

    paths = {name: folder / f"policy_{name}.npz" for name in ("learned", "final")}
    for path in paths.values():
        if not path.is_file():
            raise SystemExit(f"{path}: no kept policy (make them with --run RUN --keep DIR)")
    env_kwargs = load_policy(paths["learned"]).meta["provenance"].get("env_kwargs") or {}
    return paths, env_kwargs


def learning_curve(run: Path) -> dict:
    """(steps, mean return) of the run's evaluations (its evaluations.json)."""
    path = run / "evaluations.json"
    entries = json.loads(path.read_text()) if path.exists() else []
    return {
        "steps": [e["step"] for e in entries],
        "mean_return": [e["mean_return"] for e in entries],
    }


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    labels = ["reward (reduced)", "final x (reduced)", "final x (full)"]
    gaits = (("hand", "tab:blue"), ("learned", "tab:orange"), ("final", "tab:green"))
    gaits = [(name, colour) for name, colour in gaits if name in results]
    width = 0.8 / len(gaits)
    for k, (name, colour) in enumerate(gaits):
        r = results[name]
        values = [
            r["reduced"]["cumulative_reward_mm"],
            r["reduced"]["final_travel_mm"],
            r["full"]["final_travel_mm"],
        ]
        a.bar(np.arange(3) + width * k, values, width, label=f"{name} {r['actions']}", color=colour)
    a.set_xticks(np.arange(3) + 0.4 - width / 2, labels)
    a.set_ylabel("mm")
    a.set_title("Table 3.2 on Pliant's default Multigait")
    a.legend(fontsize=8)
    curve = results["learning_curve"]
    if curve["steps"]:
        b.plot(curve["steps"], curve["mean_return"], "o-")
    b.axhline(
        results["hand"]["reduced"]["cumulative_reward_mm"],
        color="tab:blue",
        ls="--",
        label="hand gait",
    )
    b.set_xlabel("environment steps")
    b.set_ylabel("mean evaluation return (mm)")
    b.set_title("PPO on ReducedMultigait-v0")
    b.legend()
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--run", type=Path, default=Path("runs/table_3_2_ppo"))
    source.add_argument(
        "--evaluate", type=Path, help="a folder of kept policies (made by --keep): replay them"
    )
    parser.add_argument(
        "--keep", type=Path, help="keep the run's best and final policies here (.npz, small)"
    )
    parser.add_argument("--out", type=Path, default=Path("experiments/results/reduction"))
    parser.add_argument("--name", default="table_3_2", help="stem of the JSON and PNG written")
    args = parser.parse_args()
    if args.evaluate is not None:
        policies, env_kwargs = kept_policies(args.evaluate)
        results = {"policies": str(args.evaluate), "reduced_env_kwargs": env_kwargs}
    else:
        policies, env_kwargs = run_policies(args.run), run_env_kwargs(args.run)
        if args.keep is not None:
            from pliant.learn.evaluate import export_run

            for name, folder in policies.items():
                export_run(folder, args.keep / f"policy_{name}.npz")
            policies = {name: args.keep / f"policy_{name}.npz" for name in policies}
        results = {
            "run": str(args.run),
            "reduced_env_kwargs": env_kwargs,
            "learning_curve": learning_curve(args.run),
        }
    results["thesis_cm"] = THESIS
    gaits = {"hand": HAND} | {n: policy_actions(p, env_kwargs) for n, p in policies.items()}
    for name, actions in gaits.items():
        results[name] = {
            "actions": actions,
            "reduced": replay("pliant/ReducedMultigait-v0", actions, **env_kwargs),
            "full": replay("pliant/Multigait-v0", actions, reward="sofagym"),
        }
    if args.evaluate is None:
        summary = args.run / "summary.json"
        results["training"] = json.loads(summary.read_text()) if summary.exists() else {}
    results["learned_beats_hand_on_full"] = (
        results["learned"]["full"]["final_travel_mm"] > results["hand"]["full"]["final_travel_mm"]
    )
    args.out.mkdir(parents=True, exist_ok=True)
    write_results(args.out / f"{args.name}.json", results)
    if "learning_curve" in results:
        plot(results, args.out / f"{args.name}.png")
    for name in gaits:
        r = results[name]
        print(
            f"{name:<8} {r['actions']}: reduced reward {r['reduced']['cumulative_reward_mm']:.2f}"
            f" mm, x {r['reduced']['final_travel_mm']:.2f} mm; full x"
            f" {r['full']['final_travel_mm']:.2f} mm"
        )


if __name__ == "__main__":
    main()
