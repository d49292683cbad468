"""Count SoftRobots' example scenes and SofaGym's environment scenes that Pliant's scene loader
runs unmodified, and what stops the others.

    python experiments/sofa/count_scenes.py --softrobots PATH/SoftRobots --sofagym PATH/SofaGym

Both are checkouts of the public repositories (SofaDefrost/SoftRobots, SofaDefrost/SofaGym;
never copied into this project). Each scene runs in a fresh interpreter with a time limit:

- SoftRobots: every ``examples/**/*.py`` that defines ``createScene`` and imports no serial
  port or ROS; loaded with ``load_scene`` and stepped twice.
- SofaGym: every ``sofagym/envs/*/*Scene*.py``, loaded with its environment's
  ``DEFAULT_CONFIG`` (read from ``<Name>Env.py``; the goal the first of ``goalList``, as
  ``goalPos``), stepped three times, then the scene's ``Reward`` updated and read after two
  more steps when it has one.

Meshes a scene takes from SOFA's own data (``mesh/floor.obj`` of SOFA's ``share`` folder) are
found as SOFA finds them, in ``SOFA_DATA_PATH`` or ``$SOFA_ROOT/share`` (``--sofa-data-path``
sets the first: e.g. a folder holding SOFA's ``share`` files).

A scene "runs" when that ends; otherwise its outcome is the first line of the SceneError (or
the name of another exception: a bare exception, which the loader must never give). Writes
experiments/results/sofa/scene_counts.json.
"""

from __future__ import annotations

import argparse
import ast
import collections
import json
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "sofa" / "scene_counts.json"
HARDWARE = re.compile(r"import serial|from serial|rospy|rclpy|sofaros|SerialPort")


def softrobots_scenes(repo: Path) -> list[Path]:
    scenes = []
    for file in sorted((repo / "examples").rglob("*.py")):
        text = file.read_text(errors="replace")
        if "def createScene" in text and not HARDWARE.search(text):
            scenes.append(file)
    return scenes


def sofagym_scenes(repo: Path) -> list[Path]:
    return sorted((repo / "sofagym" / "envs").glob("*/*Scene*.py"))


def default_config(scene: Path) -> dict | None:
    """The environment's DEFAULT_CONFIG: the class body's assignments up to it, run with the
    names they use (os, sys, the class's own path)."""
    envs = sorted(scene.parent.glob("*Env.py"))
    if not envs:
        return None
    tree = ast.parse(envs[0].read_text())
    for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)):
        body = [n for n in cls.body if isinstance(n, ast.Assign)]
        names = {"os": os, "sys": sys, "__file__": str(envs[0])}
        try:
            for node in body:
                exec(compile(ast.Module([node], []), str(envs[0]), "exec"), names)
        except Exception:
            continue
        if "DEFAULT_CONFIG" in names:
            return names["DEFAULT_CONFIG"]
    return None


WORKER = r"""
import inspect, json, sys, numpy as np
from pliant.sofa import SceneError, load_scene
path, config, gym = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3] == "1"
try:
    scene = load_scene(path, config=config) if config is not None else load_scene(path)
    solver = scene.solver()
    state = scene.model.rest_state()
    for _ in range(3 if gym else 2):
        state = solver.step(state)
    detail = ""
    if gym and scene.root.getObject("Reward") is not None:
        goal = (config or {}).get("goalPos")
        takes = len(inspect.signature(scene.root.Reward.update).parameters)  # SofaGym: either
        scene.root.Reward.update(goal) if goal is not None and takes else scene.root.Reward.update()
        for _ in range(2):
            state = solver.step(state)
        reward = scene.root.Reward.getReward()
        detail = f"reward {reward}"
    assert np.all(np.isfinite(state.positions)), "non-finite positions"
    print(json.dumps({"outcome": "runs", "detail": detail}))
except SceneError as exc:
    print(json.dumps({"outcome": "SceneError", "detail": str(exc).splitlines()[0]}))
except BaseException as exc:
    print(json.dumps({"outcome": type(exc).__name__, "detail": str(exc)[:300]}))
"""


def run_one(scene: Path, config: dict | None, gym: bool, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    args = [sys.executable, "-c", WORKER, str(scene), json.dumps(config), "1" if gym else "0"]
    start = time.perf_counter()
    try:
        done = subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"outcome": "timeout", "detail": f"over {timeout:.0f} s", "seconds": timeout}
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    result = (
        json.loads(lines[-1])
        if lines
        else {"outcome": "crash", "detail": done.stderr.strip().splitlines()[-1:]}
    )
    result["seconds"] = round(time.perf_counter() - start, 1)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--softrobots", type=Path, required=True)
    parser.add_argument("--sofagym", type=Path, required=True)
    parser.add_argument("--timeout", type=float, default=300.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--only",
        help="measure again only the scenes whose path contains this text (or, as"
        " 'outcome:timeout', whose stored outcome is this), keeping the others' results",
    )
    parser.add_argument(
        "--sofa-data-path",
        help="folders where SOFA's own meshes are (SOFA_DATA_PATH for the scenes' interpreters)",
    )
    args = parser.parse_args()
    if args.sofa_data_path:
        os.environ["SOFA_DATA_PATH"] = args.sofa_data_path
    jobs = [
        (s, s.relative_to(args.softrobots), None, False) for s in softrobots_scenes(args.softrobots)
    ]
    for scene in sofagym_scenes(args.sofagym):
        config = default_config(scene)
        if config is not None:
            config = {
                k: v
                for k, v in config.items()
                if isinstance(v, (int, float, str, list, bool, tuple, type(None)))
            }
            if config.get("goalList"):
                config["goalPos"] = config["goalList"][0]
                config["goal_node"] = 0
            if "board_dim" in config:  # BubbleMotion draws its ball and goal on the board
                # Its environment draws the ball's start in [4, board_dim) and the goal in
                # [1, 1 + board_dim) across the board; its reward divides by their initial
                # distance across the board (x, y): the goal two cm off the start each way.
                middle = config["board_dim"] / 2.0
                config.update(
                    init_pos=[middle, middle, 5.0], goalPos=[middle - 2.0, middle + 2.0, 2.0]
                )
            if not re.search(r"def createScene\(\s*\w+\s*,", scene.read_text()):
                config = None  # a scene of the folder that takes no configuration
        jobs.append((scene, scene.relative_to(args.sofagym), config, True))
    report: dict = {"softrobots": {}, "sofagym": {}}
    if args.only:
        stored = json.loads(OUT.read_text())
        report = {corpus: stored[corpus] for corpus in report}
        if args.only.startswith("outcome:"):  # the scenes whose stored outcome is this one
            again = {
                n for c in report.values() for n, r in c.items() if r["outcome"] == args.only[8:]
            }
            jobs = [j for j in jobs if str(j[1]) in again]
        else:
            jobs = [j for j in jobs if args.only in str(j[1])]
    with ThreadPoolExecutor(args.workers) as pool:
        results = list(pool.map(lambda j: run_one(j[0], j[2], j[3], args.timeout), jobs))
    for (_, name, _, gym), result in zip(jobs, results, strict=True):
        report["sofagym" if gym else "softrobots"][str(name)] = result
        print(f"{result['outcome']:10s} {name}: {result['detail']}", flush=True)
    summary = {}
    for corpus in ("softrobots", "sofagym"):
        scenes = report[corpus]
        counts = collections.Counter(r["outcome"] for r in scenes.values())
        summary[corpus] = {"scenes": len(scenes), **counts}
    report["summary"] = summary
    print(json.dumps(summary, indent=1))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(report, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
