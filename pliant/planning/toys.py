"""Small deterministic environments whose best plans are known, to try and test the planners.

Both keep their whole state in one tuple that ``get_state``/``set_state`` hand over, have
rewards in [0, 1] and draw an RGB image. Importing this module registers them with Gymnasium,
so ``gymnasium.make("pliant.planning.toys:PliantChain-v0")`` (or ``pliant plan`` with that id)
finds them.
"""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

_CELL = 16  # pixels per cell in the images


class ChainEnv(gym.Env):
    """A chain of n states where the patient plan beats the greedy one (after Strens 2000).

    The agent starts at state 0. Action 0 ("back") returns to state 0 and pays
    ``back_reward`` at once; action 1 ("forward") moves one state right and pays 1 only at the
    last state (and for staying there). When γ^(n-2) > back_reward, reaching the end (worth
    γ^(n-2)/(1-γ)) beats going back forever (back_reward/(1-γ)) and the optimal sequence is
    forward at every step; a planner that looks fewer than n-1 steps ahead goes back.

    Args:
        n: number of states (>= 2).
        back_reward: the immediate reward of going back, in [0, 1].
        render_mode: None or "rgb_array".
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self, n: int = 5, back_reward: float = 0.2, render_mode: str | None = None
    ) -> None:
        if n < 2:
            raise ValueError(f"the chain needs at least 2 states, got {n}")
        if not 0.0 <= back_reward <= 1.0:
            raise ValueError(f"back_reward must lie in [0, 1], got {back_reward}")
        self.n, self.back_reward, self.render_mode = n, back_reward, render_mode
        self.observation_space = spaces.Discrete(n)
        self.action_space = spaces.Discrete(2)
        self.position = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.position = 0
        return self.position, {}

    def step(self, action: int):
        if not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        if action == 0:
            self.position, reward = 0, self.back_reward
        else:
            self.position = min(self.position + 1, self.n - 1)
            reward = 1.0 if self.position == self.n - 1 else 0.0
        return self.position, reward, False, False, {}

    def get_state(self) -> tuple[int]:
        return (self.position,)

    def set_state(self, state: tuple[int]) -> None:
        (self.position,) = state

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        cells = np.full((1, self.n, 3), 235, np.uint8)
        cells[0, -1] = (90, 190, 90)  # the rewarding end
        cells[0, self.position] = (220, 60, 50)
        return _upscale(cells)


class GridWorldEnv(gym.Env):
    """A maze on a grid: reach the goal cell, paid 1 on arrival, which ends the episode.

    The layout is a list of rows: ``S`` the start, ``G`` the goal, ``#`` a wall, ``.`` free.
    Actions 0..3 move up, right, down, left; a move into a wall or off the grid stays put.
    Every step but the last pays 0, so with discount γ a plan reaching the goal in k moves is
    worth γ^(k-1): the best plans are the shortest paths, whose length ``shortest_path`` gives.

    Args:
        layout: the maze rows (default: ``GridWorldEnv.LAYOUT``, 6 moves from S to G).
        render_mode: None or "rgb_array".
    """

    LAYOUT = (
        "S..#",
        "##.#",
        "G...",
        "###.",
    )
    MOVES = ((-1, 0), (0, 1), (1, 0), (0, -1))
    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, layout: Sequence[str] = LAYOUT, render_mode: str | None = None) -> None:
        grid = np.array([list(row) for row in layout])
        if grid.ndim != 2 or (grid == "S").sum() != 1 or (grid == "G").sum() != 1:
            raise ValueError("the layout must be equal rows with one S and one G")
        self.walls = grid == "#"
        self.start = tuple(int(i) for i in np.argwhere(grid == "S")[0])
        self.goal = tuple(int(i) for i in np.argwhere(grid == "G")[0])
        self.render_mode = render_mode
        self.observation_space = spaces.MultiDiscrete(grid.shape)
        self.action_space = spaces.Discrete(4)
        self.cell = self.start

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.cell = self.start
        return np.array(self.cell), {}

    def step(self, action: int):
        if not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        self.cell = self._move(self.cell, int(action))
        reached = self.cell == self.goal
        return np.array(self.cell), float(reached), reached, False, {}

    def _move(self, cell: tuple[int, int], action: int) -> tuple[int, int]:
        row, col = cell[0] + self.MOVES[action][0], cell[1] + self.MOVES[action][1]
        rows, cols = self.walls.shape
        if 0 <= row < rows and 0 <= col < cols and not self.walls[row, col]:
            return row, col
        return cell

    def shortest_path(self) -> int:
        """The fewest moves from the start to the goal (breadth-first search)."""
        distance, frontier = {self.start: 0}, [self.start]
        while frontier:
            cell = frontier.pop(0)
            if cell == self.goal:
                return distance[cell]
            for action in range(4):
                nxt = self._move(cell, action)
                if nxt not in distance:
                    distance[nxt] = distance[cell] + 1
                    frontier.append(nxt)
        raise ValueError("the goal cannot be reached from the start")

    def get_state(self) -> tuple[int, int]:
        return self.cell

    def set_state(self, state: tuple[int, int]) -> None:
        self.cell = tuple(state)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        cells = np.full((*self.walls.shape, 3), 235, np.uint8)
        cells[self.walls] = (60, 60, 70)
        cells[self.goal] = (90, 190, 90)
        cells[self.cell] = (220, 60, 50)
        return _upscale(cells)


def _upscale(cells: np.ndarray) -> np.ndarray:
    return np.repeat(np.repeat(cells, _CELL, axis=0), _CELL, axis=1)


gym.register("PliantChain-v0", entry_point=ChainEnv, max_episode_steps=20)
gym.register("PliantGridWorld-v0", entry_point=GridWorldEnv, max_episode_steps=20)
