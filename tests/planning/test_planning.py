"""Tree search over saved states (thesis §2.2.2): OPD and UCT against known optimal plans, OPD's
bounds against exact values, the real state left untouched, and the ``pliant plan`` command."""

from __future__ import annotations

import json
import re
from pathlib import Path

import gymnasium as gym
import imageio.v3 as iio
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env
from typer.testing import CliRunner

from pliant.cli import app
from pliant.errors import PlanningError
from pliant.planning import OPD, UCT, Simulator, check_restorable, run_episode
from pliant.planning.toys import ChainEnv, GridWorldEnv

GAMMA = 0.9
DOCS = Path(__file__).parents[2] / "docs" / "planning.md"


class GambleEnv(gym.Env):
    """Action 0 cashes ``cash`` and ends the episode; action 1 pays ``rent`` and goes on.

    With γ = 0.9, rent 0.4 and cash 0.5, renting forever is worth 0.4/(1-γ) = 4 > 0.5, but one
    step only shows 0.4 < 0.5: the lower bounds favour cashing until the tree is deeper.
    """

    action_space = spaces.Discrete(2)
    observation_space = spaces.Discrete(2)

    def __init__(self, cash: float = 0.5, rent: float = 0.4) -> None:
        self.cash, self.rent, self.ended = cash, rent, False

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.ended = False
        return 0, {}

    def step(self, action):
        self.ended = action == 0
        return int(self.ended), self.cash if self.ended else self.rent, self.ended, False, {}

    def get_state(self):
        return self.ended

    def set_state(self, state) -> None:
        self.ended = state


class LeakyEnv(ChainEnv):
    """A chain whose reward depends on a step counter its snapshot forgets."""

    def reset(self, *, seed=None, options=None):
        self.count = 0
        return super().reset(seed=seed)

    def step(self, action):
        obs, reward, terminated, truncated, info = super().step(action)
        self.count += 1
        return obs, reward / self.count, terminated, truncated, info


class SlideEnv(gym.Env):
    """A continuous-action environment: not for tree search."""

    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
    observation_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        return np.zeros(1, np.float32), 0.0, False, False, {}

    def get_state(self):
        return None

    def set_state(self, state) -> None:
        pass


gym.register("PlanningTestSlide-v0", entry_point=SlideEnv)


def optimal_values(env: gym.Env, gamma: float) -> dict:
    """V*(s) of every state reachable from the current one, by value iteration over the
    snapshots (the toys' snapshots are hashable): V(s) = max_a r(s, a) + γ V(s') (s' terminal:
    0, a terminal_reward of 0)."""
    sim = Simulator(env)
    model, frontier = {}, [sim.save()]
    while frontier:
        state = frontier.pop()
        if state in model:
            continue
        model[state] = []
        for action in sim.actions:
            sim.restore(state)
            transition = sim.step(action)
            following = sim.save()
            model[state].append((transition.reward, transition.done, following))
            if not transition.done:
                frontier.append(following)
    values = dict.fromkeys(model, 0.0)
    for _ in range(2000):  # γ^2000 is far below double precision
        values = {
            s: max(r + (0.0 if done else gamma * values[t]) for r, done, t in moves)
            for s, moves in model.items()
        }
    return values


def replay(env: gym.Env, start: object, actions: list[int]) -> object:
    """The state reached from ``start`` by ``actions``."""
    env.unwrapped.set_state(start)
    for action in actions:
        env.unwrapped.step(action)
    return env.unwrapped.get_state()


def path_to(node) -> list[int]:
    actions = []
    while node.parent is not None:
        actions.append(node.action)
        node = node.parent
    return actions[::-1]


# ----------------------------------------------------------------------------------- toys


@pytest.mark.parametrize("name", ["PliantChain-v0", "PliantGridWorld-v0"])
def test_toys_pass_gymnasium_checks_and_replay_exactly(name) -> None:
    env = gym.make(f"pliant.planning.toys:{name}", render_mode="rgb_array").unwrapped
    check_env(env, skip_render_check=False)
    env.reset(seed=0)
    check_restorable(env, [1, 0, 1, 1, 1, 0, 1])
    assert env.render().shape[2] == 3


def test_check_restorable_names_the_step_a_forgetful_snapshot_breaks() -> None:
    env = LeakyEnv()
    env.reset(seed=0)
    with pytest.raises(PlanningError, match=r"step 2 \(action 0\) gave the reward 0.0333"):
        check_restorable(env, [1, 1, 0])


def test_chain_values_make_forward_optimal() -> None:
    """The trap is real: from state 0, forward forever is worth γ^3/(1-γ) = 7.29, going back
    forever 0.2/(1-γ) = 2."""
    env = ChainEnv()
    env.reset(seed=0)
    values = optimal_values(env, GAMMA)
    assert values[(0,)] == pytest.approx(GAMMA**3 / (1 - GAMMA), rel=1e-12)


# ------------------------------------------------------------------------------------ OPD


def test_opd_plays_the_optimal_chain_sequence() -> None:
    """Budget 40 steps = 20 expansions per decision: forward at every step, total reward 7
    over 10 steps (the end is reached at step 4). A 3-step horizon cannot see the end and
    goes back, as a myopic planner must."""
    env = gym.make("pliant.planning.toys:PliantChain-v0")
    report = run_episode(env, OPD(budget=40, gamma=GAMMA), max_steps=10, seed=0)
    assert report.actions == [1] * 10
    assert report.total_reward == 7.0
    myopic = run_episode(env, OPD(budget=40, gamma=GAMMA, max_depth=3), max_steps=3, seed=0)
    assert myopic.actions == [0, 0, 0]


def test_opd_reaches_the_grid_goal_in_the_fewest_moves() -> None:
    """Sparse reward (1 at the goal): a plan of k moves is worth γ^(k-1), so the shortest path
    (6 moves, breadth-first search) is the only optimum; 1000 expansions see depth 6."""
    env = gym.make("pliant.planning.toys:PliantGridWorld-v0")
    report = run_episode(env, OPD(budget=4000, gamma=GAMMA), max_steps=20, seed=0)
    assert report.terminated
    assert len(report.actions) == env.unwrapped.shortest_path() == 6


def test_opd_bounds_contain_the_exact_value_on_the_explored_tree() -> None:
    """For a node of depth d with path value u: lower <= u + γ^d V*(s) <= upper, for every node
    (Hren & Munos 2008, Lemma 1), V* from value iteration."""
    env = ChainEnv()
    env.reset(seed=0)
    values = optimal_values(env, GAMMA)
    start = env.get_state()
    planner = OPD(budget=60, gamma=GAMMA)
    planner.plan(env)
    nodes = list(planner.root.subtree())
    assert len(nodes) == 1 + 2 * 30
    for node in nodes:
        state = replay(env, start, path_to(node))
        exact = node.path_value + GAMMA**node.depth * values[state]
        assert node.lower <= exact + 1e-12 and exact <= node.upper + 1e-12, path_to(node)
        if not node.children:  # a leaf's bounds: u and u + γ^d/(1-γ)
            assert node.lower == node.path_value
            assert node.upper == pytest.approx(node.path_value + GAMMA**node.depth / (1 - GAMMA))


def test_opd_recommends_the_highest_lower_bound_not_the_highest_upper() -> None:
    """One expansion: cashing has bounds [0.5, 0.5], renting [0.4, 0.4 + γ/(1-γ)]. Sampling
    would follow renting; the conservative recommendation cashes. A deeper tree shows renting
    pays 0.4 + 0.36 + ... > 0.5 and switches."""
    env = GambleEnv()
    env.reset(seed=0)
    shallow = OPD(budget=2, gamma=GAMMA)
    assert shallow.plan(env) == 0
    cash, rent = shallow.root.children[0], shallow.root.children[1]
    assert cash.lower == cash.upper == 0.5
    assert rent.lower == 0.4 and rent.upper == pytest.approx(0.4 + GAMMA / (1 - GAMMA))
    assert shallow._optimistic_leaf() is rent
    assert OPD(budget=4, gamma=GAMMA).plan(env) == 1


def test_opd_keeps_the_subtree_with_values_shifted() -> None:
    """After playing a, the child's subtree is kept: every value v becomes (v - r_a)/γ
    (rl-agents' shift), and the next decision starts from those nodes."""
    env = ChainEnv()
    env.reset(seed=0)
    planner = OPD(budget=40, gamma=GAMMA)
    action = planner.plan(env)
    child = planner.root.children[action]
    before = {id(n): (n.path_value, n.lower, n.upper) for n in child.subtree()}
    env.step(action)
    planner.step(action)
    assert planner.root is child and child.parent is None
    for node in child.subtree():
        old = before[id(node)]
        new = (node.path_value, node.lower, node.upper)
        assert new == pytest.approx([(v - child.reward) / GAMMA for v in old], abs=1e-12)
    kept = len(before)
    planner.plan(env)
    stats = planner.last
    assert stats.reused_nodes == kept - 1 > 0
    assert stats.tree_size == kept + 2 * stats.expansions
    assert stats.simulated_steps == 2 * stats.expansions == 40


def test_opd_stops_once_the_best_sequence_within_the_horizon_is_known() -> None:
    """With D = 3 the b-values are exact at depth 3; the search stops when the leaf to expand
    is closed, at most the 7 inner nodes of the depth-3 tree, far below budget // 2."""
    env = ChainEnv()
    env.reset(seed=0)
    planner = OPD(budget=1000, gamma=GAMMA, max_depth=3)
    assert planner.plan(env) == 0
    assert 1 <= planner.last.expansions <= 7
    assert planner.root.lower == planner.root.upper == pytest.approx(0.2 * (1 + GAMMA + GAMMA**2))


def test_opd_refuses_rewards_outside_the_unit_interval_and_restores_the_state() -> None:
    env = GambleEnv(cash=1.5)
    env.reset(seed=0)
    env.step(1)
    before = env.get_state()
    planner = OPD(budget=10, gamma=GAMMA)
    with pytest.raises(PlanningError, match=r"rewards in \[0, 1\].*1\.5"):
        planner.plan(env)
    assert env.get_state() == before
    assert planner.root is None  # the half-expanded tree is dropped


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gamma": 1.0}, "finite depth"),
        ({"gamma": 0.0}, r"\(0, 1\]"),
        ({"budget": 0}, "budget"),
        ({"max_depth": 0}, "max_depth"),
        ({"terminal_reward": 2.0}, "terminal_reward"),
    ],
)
def test_opd_rejects_bad_settings(kwargs, match) -> None:
    with pytest.raises(PlanningError, match=match):
        OPD(**kwargs)


def test_opd_budget_must_pay_for_one_expansion() -> None:
    env = GridWorldEnv()
    env.reset(seed=0)
    with pytest.raises(PlanningError, match="budget of 3 .* 4 steps"):
        OPD(budget=3).plan(env)


# ------------------------------------------------------------------------------------ UCT


def test_uct_plays_the_optimal_chain_sequence() -> None:
    """500 simulated steps per decision (rollouts included), horizon 10, c = 0.3, seed 0:
    forward at every step. (UCT is slow on chains, Coquelin & Munos 2007: with c = 1 it
    first goes back at this budget.)"""
    env = gym.make("pliant.planning.toys:PliantChain-v0")
    planner = UCT(budget=500, gamma=GAMMA, horizon=10, exploration=0.3, seed=0)
    report = run_episode(env, planner, max_steps=10, seed=0)
    assert report.actions == [1] * 10


def test_uct_reaches_the_grid_goal_in_the_fewest_moves() -> None:
    env = gym.make("pliant.planning.toys:PliantGridWorld-v0")
    planner = UCT(budget=2000, gamma=GAMMA, horizon=8, exploration=0.1, seed=0)
    report = run_episode(env, planner, max_steps=20, seed=0)
    assert report.terminated and len(report.actions) == 6


def test_uct_is_repeatable_and_counts_its_rollouts() -> None:
    env = gym.make("pliant.planning.toys:PliantGridWorld-v0")
    first, second = (
        run_episode(env, UCT(budget=300, gamma=GAMMA, horizon=8, seed=7), max_steps=5, seed=0)
        for _ in range(2)
    )
    assert first.actions == second.actions
    for stats in first.decisions:  # the last iteration may overrun by its rollout
        assert 300 <= stats.simulated_steps < 300 + 8
        assert stats.expansions <= stats.simulated_steps


def test_uct_visit_counts_add_up_and_the_subtree_is_kept() -> None:
    """Each iteration passes the root and adds one node: the root's visits are its
    children's, any other node's are one (its creation) plus its children's."""
    env = ChainEnv()
    env.reset(seed=0)
    planner = UCT(budget=200, gamma=GAMMA, horizon=30, seed=1)
    action = planner.plan(env)
    root = planner.root
    assert root.visits == sum(c.visits for c in root.children.values())
    for node in list(root.subtree())[1:]:
        assert node.visits == 1 + sum(c.visits for c in node.children.values())
    most = max(root.children.values(), key=lambda c: c.visits)
    assert action == most.action
    kept = sum(1 for _ in root.children[action].subtree())
    env.step(action)
    planner.step(action)
    planner.plan(env)
    assert planner.last.reused_nodes == kept - 1 > 0
    assert planner.last.tree_size == kept + planner.last.expansions


def test_uct_rejects_bad_settings() -> None:
    with pytest.raises(PlanningError, match="rollout"):
        UCT(rollout="greedy")
    with pytest.raises(PlanningError, match="horizon"):
        UCT(horizon=0)


# ----------------------------------------------------------------------------- both


@pytest.mark.parametrize(
    "planner",
    [OPD(budget=40, gamma=GAMMA), UCT(budget=100, gamma=GAMMA, seed=0)],
    ids=["opd", "uct"],
)
def test_planning_leaves_the_real_environment_where_it_was(planner) -> None:
    """Plan, then step: same state and same observation as a twin that did not plan."""
    env, twin = ChainEnv(), ChainEnv()
    for e in (env, twin):
        e.reset(seed=0)
        e.step(1)
    before = env.get_state()
    action = planner.plan(gym.wrappers.TimeLimit(env, 50))
    assert env.get_state() == before
    assert env.step(action) == twin.step(action)


def test_planning_needs_discrete_actions_and_snapshots() -> None:
    with pytest.raises(PlanningError, match="Discrete"):
        OPD().plan(SlideEnv())
    with pytest.raises(PlanningError, match="get_state"):
        OPD().plan(gym.make("CartPole-v1"))


@pytest.fixture(scope="module")
def diamond() -> gym.Env:
    """Pliant's Diamond (Discrete(8), Eq. 3.2 reward clipped to [0, 1]), its small variant."""
    envs = pytest.importorskip("pliant.envs")
    return gym.make("pliant/Diamond-v0", **envs.ENVS["Diamond"].quick)


@pytest.mark.parametrize(
    "planner",
    [OPD(budget=8, gamma=GAMMA), UCT(budget=8, gamma=GAMMA, horizon=2, seed=0)],
    ids=["opd", "uct"],
)
def test_a_decision_on_the_diamond_leaves_its_state_and_predicts_the_real_step(
    diamond, planner
) -> None:
    """One decision leaves the simulation where it was, and the reward the tree predicted for
    the played action is the one the real step returns."""
    env = diamond
    env.reset(seed=0)
    env.step(3)
    start = env.unwrapped.get_state()
    action = planner.plan(env)
    _, reward, *_ = env.step(action)
    assert planner.root.children[action].reward == reward
    env.unwrapped.set_state(start)
    assert env.unwrapped.step(action)[1] == reward


# ------------------------------------------------------------------------------------ CLI

runner = CliRunner()


def test_plan_command_writes_actions_report_and_gif(tmp_path) -> None:
    result = runner.invoke(
        app,
        ["plan", "pliant.planning.toys:PliantGridWorld-v0", "--budget", "4000"]
        + ["--steps", "20", "--out", str(tmp_path)],
    )
    assert result.exit_code == 0, result.output
    actions = json.loads((tmp_path / "actions.json").read_text())
    report = json.loads((tmp_path / "report.json").read_text())
    assert len(actions) == 6 and report["actions"] == actions
    assert report["total_reward"] == 1.0 and report["terminated"]
    assert report["expansions"] == 6 * 1000 and report["simulated_steps"] == 6 * 4000
    assert report["discounted_return"] == pytest.approx(GAMMA**5)
    frames = iio.imread(tmp_path / "trajectory.gif", index=None)
    assert frames.shape[0] == len(actions) + 1  # the reset and every real step


def test_plan_command_passes_env_kwargs_and_runs_uct(tmp_path) -> None:
    """With back_reward = 0.9, going back forever (0.9/(1-γ) = 9) beats the end of the chain
    (γ^3/(1-γ) = 7.29): the plan turns round."""
    result = runner.invoke(
        app,
        ["plan", "pliant.planning.toys:PliantChain-v0", "-k", "back_reward=0.9", "--algo", "uct"]
        + ["--depth", "10", "--budget", "500", "--steps", "5", "--no-reuse-tree"]
        + ["--out", str(tmp_path)],
    )
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "actions.json").read_text()) == [0] * 5
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["algo"] == "uct" and report["depth"] == 10 and report["total_reward"] == 4.5
    assert not report["reuse_tree"]
    assert all(d["reused_nodes"] == 0 for d in report["decisions"])


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["NoSuchEnv-v0"], "cannot make 'NoSuchEnv-v0'"),
        (["PlanningTestSlide-v0"], "Discrete action space"),
        (["pliant.planning.toys:PliantChain-v0", "--budget", "1"], "budget of 1"),
        (["pliant.planning.toys:PliantChain-v0", "--algo", "mcts"], "--algo"),
        (["pliant.planning.toys:PliantChain-v0", "-k", "size"], "KEY=VALUE"),
    ],
)
def test_plan_command_rejects_bad_input_in_one_line(tmp_path, args, match) -> None:
    result = runner.invoke(app, ["plan", *args, "--out", str(tmp_path)])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and re.search(match, lines[0])
    assert not (tmp_path / "report.json").exists()


# ----------------------------------------------------------------------------------- docs


EXAMPLES = re.findall(r"```python\n(.*?)```", DOCS.read_text(), re.S)


@pytest.mark.parametrize("code", EXAMPLES, ids=[f"example{i}" for i in range(len(EXAMPLES))])
def test_docs_examples_run(code) -> None:
    exec(compile(code, str(DOCS), "exec"), {})
