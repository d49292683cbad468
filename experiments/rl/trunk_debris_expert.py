"""TrunkSpaceDebris: is a catch reachable, and from which cube placements? A planner's answer
(issue #16; thesis §3.2.2: PPO catches the cube in 80 % of 400 tests, the cube placed "always
within the grasping capabilities of the Trunk robot"; our PPO: 0.25 %).

    PYTHONPATH=. python experiments/rl/trunk_debris_expert.py [--beam 4] [--macro-steps 5]
        [--sizes 20 30 40] [--heights 110 135 160] [--gaps 5 15] [--hull-penalty 3] [--held 5]

For each cube placement of a grid (size x height z of its centre x gap between its near face and
the trunk's surface, on +x: azimuth 0, a face towards the trunk), a search looks for a
cable program of the environment's 50 steps that ends with the environment's success: the trunk
pressing on >= 2 faces of the cube at the last step (``info["is_success"]``). The environment is
``pliant/TrunkSpaceDebris-v0`` as it is (physics, courses 35/25 mm, cube 10 g, friction 0.5),
with the keyword ``continuous_mode="increment"`` (the PPO experiment's: each action moves a cable
by at most ``action_scale`` = 2 mm) and the placement given through ``reset(options=...)``.

Two phases, each over the whole grid:

1. ``placements/``: beam search over macro actions, receding over the whole horizon.

   * a macro is one increment vector held for ``--macro-steps`` environment steps, from a menu
     of 19 (MACROS: hold; pull one of the 8 cables; release all; pull the long and short cable
     of one side; three S-curves, a long cable with the opposite short one; pull the +x long
     cable with a +-y long one);
   * at each decision, every node of the beam (``--beam`` of them) is restored from its
     snapshot (``get_state``/``set_state``) and extended by every macro; children that lose
     the cube (terminated) or diverge (truncated) are dropped; children with the same cable
     commands and the cube in the same place (2 mm) are merged;
   * score of a node after its last step t:
     ``2 * min(faces_t, 2) + r_t - hull_penalty * [cube on the hull]``, with ``r_t`` the
     environment's own reward (Eq. 3.3, about [-6, 0]: it falls as the cube is pushed away),
     ``faces_t`` its ``info["faces"]``, and the cube "on the hull" when its lowest corner is
     within 1 mm of the hull plane z = 0. Half the beam (rounded up) is kept by this score,
     which steers it to catches in free space (a cube pinned against the spacecraft by the
     trunk satisfies the environment's criterion but is not caught); the other half by the
     same score without the hull term (the environment's criterion alone);
   * at the last decision the child that ends best is kept (success first, then free of the
     hull, then faces, then score) and replayed from ``reset`` to check it.

2. ``sweeps/``: timed sweeps (:func:`sweep_placement`): each macro played from rest for the
   whole horizon; a step t with two faces pressed gives the program "hold H - t steps, then the
   macro", which ends on that contact (replayed to check it).

Per placement: success, whether the cube is free of the hull, faces at the end, the first step
with two faces, how many last steps held two faces, the cube's speed at the end, the budget
(simulated steps) and wall time; the played actions (increments in [-1, 1], 50 x 8) of each
success are the expert trajectories for behaviour cloning. The environment's success only asks
for two faces at the last step; the summary also counts "sustained free catches": free of the
hull, two faces over at least the last ``--held`` steps. One JSON per placement and phase in
experiments/results/rl/trunk_debris_expert/{placements,sweeps}/ (a rerun skips those done and
the summary covers every placement in the folder), then summary.json; each written atomically.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pliant import configure_threads
from pliant.files import write_json, write_results

RESULTS = Path("experiments/results/rl/trunk_debris_expert")
ENV_ID = "pliant/TrunkSpaceDebris-v0"
ENV_KWARGS = {"continuous_mode": "increment", "action_scale": 2.0}

# Cables (pliant.robots.trunk): 0-3 long, 4-7 short, at azimuths +y, -x, -y, +x (i % 4).
LONG = {"+y": 0, "-x": 1, "-y": 2, "+x": 3}
SHORT = {side: i + 4 for side, i in LONG.items()}


def _macro(**pulls: float) -> np.ndarray:
    """An increment vector over the 8 cables from {"c3": 1.0, ...}."""
    action = np.zeros(8)
    for name, value in pulls.items():
        action[int(name[1:])] = value
    return action


def macro_menu() -> dict[str, np.ndarray]:
    """The macros the search chooses from (increments in [-1, 1] x 2 mm a step)."""
    menu = {"hold": np.zeros(8)}
    for side, i in LONG.items():
        menu[f"long{side}"] = _macro(**{f"c{i}": 1.0})
    for side, i in SHORT.items():
        menu[f"short{side}"] = _macro(**{f"c{i}": 1.0})
    menu["release"] = -np.ones(8)
    for side in LONG:
        menu[f"both{side}"] = _macro(**{f"c{LONG[side]}": 1.0, f"c{SHORT[side]}": 1.0})
    opposite = {"+x": "-x", "-x": "+x", "+y": "-y", "-y": "+y"}
    for side in ("+x", "+y", "-y"):
        menu[f"S{side}"] = _macro(**{f"c{LONG[side]}": 1.0, f"c{SHORT[opposite[side]]}": 1.0})
    for side in ("+y", "-y"):
        menu[f"long+x{side}"] = _macro(**{f"c{LONG['+x']}": 1.0, f"c{LONG[side]}": 1.0})
    return menu


MACROS = macro_menu()


def placements(sizes, heights, gaps) -> list[dict]:
    return [
        {"name": f"s{s:g}_z{z:g}_g{g:g}", "cube_size": float(s), "z": float(z), "gap": float(g)}
        for s in sizes
        for z in heights
        for g in gaps
    ]


def on_hull(env) -> bool:
    """The cube's lowest corner within 1 mm of the hull (z = 0)."""
    half = 0.5 * env.cube_size
    rotation = env.state.rigid_rotations[0]
    lowest = env.cube()[2] - half * np.abs(rotation[2]).sum()
    return bool(lowest < 1.0)


@dataclass
class Node:
    """A state of the search: its snapshot, the macros that led there and what was seen."""

    snapshot: object
    macros: list[str]
    faces: int
    reward: float
    hull: bool
    score: float
    first_two_faces: int | None  # first step (1-based) with two faces on this path
    commands: np.ndarray = field(repr=False, default=None)


class BeamSearch:
    """Beam search over macro actions from the environment's reset state (module docstring)."""

    def __init__(self, env, *, beam: int, macro_steps: int, horizon: int, hull_penalty: float):
        if horizon % macro_steps:
            raise ValueError(f"--macro-steps {macro_steps} must divide the horizon {horizon}")
        self.env = env
        self.beam = beam
        self.macro_steps = macro_steps
        self.horizon = horizon
        self.hull_penalty = hull_penalty
        self.steps = 0  # simulated environment steps
        self.successes: list[Node] = []  # every successful node at the last decision

    def score(self, faces: int, reward: float, hull: bool) -> float:
        return 2.0 * min(faces, 2) + reward - self.hull_penalty * hull

    def _extend(self, node: Node, name: str, depth: int) -> Node | None:
        """Restore `node`, play macro `name` for macro_steps steps; None if the cube was lost
        or the step diverged."""
        self.env.set_state(node.snapshot)
        first = node.first_two_faces
        info, reward = {}, 0.0
        for k in range(self.macro_steps):
            _, reward, terminated, truncated, info = self.env.step(MACROS[name])
            self.steps += 1
            if terminated or truncated:
                return None
            if first is None and info["faces"] >= 2:
                first = depth * self.macro_steps + k + 1
        hull = on_hull(self.env)
        return Node(
            snapshot=self.env.get_state(),
            macros=[*node.macros, name],
            faces=int(info["faces"]),
            reward=float(reward),
            hull=hull,
            score=self.score(int(info["faces"]), float(reward), hull),
            first_two_faces=first,
            commands=self.env.commands.copy(),
        )

    def run(self) -> Node | None:
        root = Node(self.env.get_state(), [], 0, 0.0, False, 0.0, None, self.env.commands.copy())
        frontier = [root]
        depths = self.horizon // self.macro_steps
        for depth in range(depths):
            children: dict[tuple, Node] = {}
            for node in frontier:
                for name in MACROS:
                    child = self._extend(node, name, depth)
                    if child is None:
                        continue
                    key = (
                        tuple(np.round(child.commands, 1)),
                        tuple(np.round(self.env.cube() / 2.0).astype(int)),
                    )
                    if key not in children or children[key].score < child.score:
                        children[key] = child
            if not children:
                return None
            ranked = sorted(children.values(), key=lambda n: n.score, reverse=True)
            if depth == depths - 1:
                self.successes = [n for n in ranked if n.faces >= 2]
                return max(ranked, key=lambda n: (n.faces >= 2, not n.hull, n.faces, n.score))
            # Half the beam by the score, half by the same score without the hull term (the
            # environment's own criterion), so that pinned catches are explored too.
            frontier = ranked[: (self.beam + 1) // 2]
            kept = {id(n) for n in frontier}
            plain = sorted(
                (n for n in ranked if id(n) not in kept),
                key=lambda n: n.score + self.hull_penalty * n.hull,
                reverse=True,
            )
            frontier += plain[: self.beam - len(frontier)]
        return None


def play(env, placement: dict, seed: int, program: list[str]) -> dict:
    """Play a program (one macro name a step) from reset; the per-step record and the actions
    (increments in [-1, 1], one row a step)."""
    reset(env, placement, seed)
    actions, faces, rewards = [], [], []
    info, ended = {}, False
    for name in program:
        action = MACROS[name]
        _, reward, terminated, truncated, info = env.step(action)
        actions.append(action.tolist())
        faces.append(int(info.get("faces", 0)))
        rewards.append(float(reward))
        if terminated or truncated:
            ended = True
            break
    held = _held_from(faces)
    return {
        "success": bool(info.get("is_success", False)) and not ended,
        "free_of_hull": not on_hull(env),
        "faces_at_end": faces[-1] if faces else 0,
        "first_two_face_step": next((t + 1 for t, f in enumerate(faces) if f >= 2), None),
        "two_faces_held_from": held,
        "two_faces_held_steps": 0 if held is None else len(faces) - held + 1,
        "return": float(np.sum(rewards)),
        "cube_at_end": env.cube().round(2).tolist(),
        "cube_speed_at_end": float(np.linalg.norm(env.state.rigid_velocities[0])),
        "faces": faces,
        "actions": actions,
    }


def replay(env, placement: dict, seed: int, macros: list[str], macro_steps: int) -> dict:
    """Play a macro program (each macro held for macro_steps steps) from reset."""
    return play(env, placement, seed, [m for m in macros for _ in range(macro_steps)])


def _held_from(faces: list[int]) -> int | None:
    """The step (1-based) from which two faces are held to the end, or None."""
    if not faces or faces[-1] < 2:
        return None
    t = len(faces)
    while t > 1 and faces[t - 2] >= 2:
        t -= 1
    return t


def reset(env, placement: dict, seed: int) -> None:
    from pliant.robots.trunk_debris import beside_trunk

    position = beside_trunk(placement["cube_size"], placement["z"], placement["gap"], 0.0)
    env.reset(seed=seed, options={"cube_size": placement["cube_size"], "cube_position": position})


def search_placement(env, placement: dict, seed: int, args) -> dict:
    reset(env, placement, seed)
    search = BeamSearch(
        env,
        beam=args.beam,
        macro_steps=args.macro_steps,
        horizon=env.horizon,
        hull_penalty=args.hull_penalty,
    )
    clock = time.perf_counter()
    best = search.run()
    wall = time.perf_counter() - clock
    record = {
        **placement,
        "seed": seed,
        "beam": args.beam,
        "macro_steps": args.macro_steps,
        "hull_penalty": args.hull_penalty,
        "budget_steps": search.steps,
        "wall_seconds": wall,
        "steps_per_second": search.steps / wall if wall else None,
        "successful_children_at_last_decision": len(search.successes),
        "free_successful_children": sum(not n.hull for n in search.successes),
    }
    if best is None:
        return {**record, "success": False, "best": None}
    played = replay(env, placement, seed, best.macros, args.macro_steps)
    record.update(success=played["success"], free_catch=played["success"] and not best.hull)
    record["best"] = {"macros": best.macros, "score": best.score, **played}
    if not played["success"]:
        record["best"].pop("actions")  # keep the expert sequences only
    # A pinned and a free catch may both exist: keep one of each kind as expert data.
    other = next((n for n in search.successes if n.hull != best.hull), None)
    if other is not None:
        record["other_kind"] = {"macros": other.macros, "score": other.score}
        record["other_kind"].update(replay(env, placement, seed, other.macros, args.macro_steps))
    return record


def sweep_placement(env, placement: dict, seed: int) -> dict:
    """Timed sweeps: each macro (but hold and release, which do nothing from rest) played from
    reset for the whole horizon. A step t where the trunk presses two faces gives the program
    "hold for H - t steps, then the macro for t steps", which presses them at the last step:
    from rest, in zero gravity, holding changes nothing, so the sweep is only delayed (checked
    by replaying it). The candidate kept: free of the hull first, then the most steps with two
    faces up to t, then the slowest cube."""
    horizon = env.horizon
    clock, steps = time.perf_counter(), 0
    sweeps, candidates = {}, []
    for name in MACROS:
        if name in ("hold", "release"):
            continue
        reset(env, placement, seed)
        faces, run = [], 0
        for t in range(1, horizon + 1):
            _, _, terminated, truncated, info = env.step(MACROS[name])
            steps += 1
            if terminated or truncated:
                break
            faces.append(int(info["faces"]))
            run = run + 1 if faces[-1] >= 2 else 0
            if run:
                speed = float(np.linalg.norm(env.state.rigid_velocities[0]))
                candidates.append((not on_hull(env), run, -speed, name, t))
        sweeps[name] = {
            "max_faces": max(faces, default=0),
            "two_face_steps": sum(f >= 2 for f in faces),
            "faces_at_end": faces[-1] if len(faces) == horizon else None,
        }
    record = {
        **placement,
        "seed": seed,
        "sweeps": sweeps,
        "candidates": len(candidates),
        "free_candidates": sum(c[0] for c in candidates),
    }
    if candidates:
        _, _, _, name, t = max(candidates)
        program = ["hold"] * (horizon - t) + [name] * t
        played = play(env, placement, seed, program)
        steps += horizon
        record["best"] = {"macro": name, "hold_steps": horizon - t, **played}
        record["success"] = played["success"]
        record["free_catch"] = played["success"] and played["free_of_hull"]
    else:
        record.update(best=None, success=False, free_catch=False)
    record["budget_steps"] = steps
    record["wall_seconds"] = time.perf_counter() - clock
    return record


def _held_steps(best: dict) -> int:
    """How many last steps of the played program pressed two faces."""
    held = _held_from(best.get("faces", [])) if best else None
    return 0 if held is None else len(best["faces"]) - held + 1


def _row(r: dict, held: int = 5) -> dict:
    """A placement's line in the summary. A catch is "sustained" when the cube is free of the
    hull and two faces are pressed over at least the last `held` steps: the environment's
    success only asks for two faces at the last step, which a sweep through the cube (the cube
    flying off) or a cube pinned on the hull also gives."""
    best = r.get("best") or {}
    return {
        "name": r["name"],
        "success": r["success"],
        "free_catch": bool(r.get("free_catch")),
        "faces_at_end": best.get("faces_at_end"),
        "first_two_face_step": best.get("first_two_face_step"),
        "two_faces_held_steps": _held_steps(best),
        "sustained_free_catch": bool(r.get("free_catch")) and _held_steps(best) >= held,
        "cube_speed_at_end": best.get("cube_speed_at_end"),
        "budget_steps": r["budget_steps"],
        "wall_seconds": round(r["wall_seconds"], 1),
    }


def _json_object(text: str) -> dict:
    """``--env-kwargs``: a JSON object (argparse reports anything else in one line)."""
    value = json.loads(text)
    if not isinstance(value, dict):
        raise ValueError("not a JSON object")
    return value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beam", type=int, default=4)
    parser.add_argument("--macro-steps", type=int, default=5)
    parser.add_argument("--sizes", type=float, nargs="+", default=[20.0, 30.0, 40.0])
    parser.add_argument("--heights", type=float, nargs="+", default=[110.0, 135.0, 160.0])
    parser.add_argument("--gaps", type=float, nargs="+", default=[5.0, 15.0])
    parser.add_argument("--hull-penalty", type=float, default=3.0)
    parser.add_argument("--seed", type=int, default=0, help="reset seed of every placement")
    parser.add_argument(
        "--held", type=int, default=5, help="last steps with two faces for a sustained catch"
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument(
        "--env-kwargs", type=_json_object, default={},
        help='JSON of environment keywords over ENV_KWARGS, e.g. \'{"material": ...}\'',
    )  # fmt: skip
    parser.add_argument(
        "--phases", nargs="+", choices=["placements", "sweeps"], default=["placements", "sweeps"],
        help="the searches to run (sweeps alone: a cheap map of where catches are)",
    )  # fmt: skip
    args = parser.parse_args()

    import gymnasium as gym

    import pliant.envs  # noqa: F401  (registers the environments)

    configure_threads(torch_threads=1)
    env_kwargs = {**ENV_KWARGS, **args.env_kwargs}
    env = gym.make(ENV_ID, **env_kwargs).unwrapped
    unknown = set(args.sizes) - set(env.cube_sizes)
    if unknown:
        parser.error(f"cube sizes {sorted(unknown)} are not the environment's {env.cube_sizes}")
    grid = placements(args.sizes, args.heights, args.gaps)
    phases = {
        "placements": lambda p: search_placement(env, p, args.seed, args),
        "sweeps": lambda p: sweep_placement(env, p, args.seed),
    }
    phases = {phase: run for phase, run in phases.items() if phase in args.phases}
    summary = {
        "env_id": ENV_ID,
        "env_kwargs": env_kwargs,
        "seed": args.seed,
        "macros": {k: v.tolist() for k, v in MACROS.items()},
        "command": " ".join(
            ["PYTHONPATH=. python experiments/rl/trunk_debris_expert.py", *sys.argv[1:]]
        ),
    }
    for phase, run in phases.items():
        records = []
        for placement in grid:
            path = args.out / phase / f"{placement['name']}.json"
            if path.exists():
                records.append(json.loads(path.read_text()))
                continue
            record = run(placement)
            write_results(path, record)
            records.append(record)
            row = _row(record)
            print(f"{phase} {' '.join(f'{k}={v}' for k, v in row.items())}", flush=True)
        # The summary covers every placement searched into this folder (earlier grids too).
        done = {r["name"] for r in records}
        for path in sorted((args.out / phase).glob("*.json")):
            if path.stem not in done:
                records.append(json.loads(path.read_text()))
        steps = sum(r["budget_steps"] for r in records)
        wall = sum(r["wall_seconds"] for r in records)
        summary[phase] = {
            "placements": len(records),
            "successes": sum(r["success"] for r in records),
            "free_catches": sum(bool(r.get("free_catch")) for r in records),
            "pinned_catches": sum(r["success"] and not r.get("free_catch") for r in records),
            "sustained_free_catches": sum(
                _row(r, args.held)["sustained_free_catch"] for r in records
            ),
            "held_steps_for_sustained": args.held,
            "simulated_steps": steps,
            "wall_seconds": wall,
            "steps_per_second": steps / wall if wall else None,
            "table": [_row(r, args.held) for r in records],
        }
    if "placements" in summary:
        summary["placements"]["search"] = {
            "kind": "beam search over macro actions",
            "beam": args.beam,
            "macro_steps": args.macro_steps,
            "score": "2 * min(faces, 2) + r_t(Eq. 3.3) - hull_penalty * [cube on the hull]",
            "hull_penalty": args.hull_penalty,
        }
    if "sweeps" in summary:
        summary["sweeps"]["search"] = "one macro from rest, delayed so a two-face step is the last"
    write_json(args.out / "summary.json", summary)
    for phase in phases:
        print(phase, {k: v for k, v in summary[phase].items() if k != "table"})


if __name__ == "__main__":
    main()
