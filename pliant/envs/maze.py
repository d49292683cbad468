"""SimpleMaze and Maze (thesis §3.1.2, §3.4.2; SofaGym simple_maze-v0, maze-v0).

A ball rolls in a rigid maze. In SimpleMaze the maze's tilt is the action (a gimbal under a gel
pad); in Maze three servos bend a soft tripod that carries the maze. The reward follows the
shortest path to the goal inside the maze, computed by Dijkstra (thesis §3.1.2) on a grid of
the ball centre's free space (the maze's floor less the walls grown by the ball's radius):
r_t = clip((d_{t-1} - d_t) / d_0, 0, 1), d the geodesic distance from the ball to the goal and
d_0 its value at the start, so rewards lie in [0, 1] (as OPD needs) and add up to at most 1.

Goals: the four corners of the maze (``goal`` option of ``reset``, 0-3, or drawn at random);
the ball starts at the path's start (``start="path"``, SofaGym's) or at the maze's centre
(``start="centre"``, thesis §3.4.2: from the centre to each corner). Terminated when the ball
is within ``goal_radius`` mm of the goal, or has left the maze (fallen: reward 0, info says so).

Observation: SimpleMaze [theta_x, theta_y, ball x, y, z, goal x, y] (tilts in rad divided by
the tilt cap, positions in the maze's frame divided by half its size); Maze adds the three servo
angles divided by their cap. Actions: discrete, one tilt (servo) moved by ``action_scale`` rad
up or down (4 and 6 actions, SofaGym's); continuous, the tilts (servo angles) in [-cap, cap].
"""

from __future__ import annotations

import gymnasium as gym
import networkx as nx
import numpy as np

from pliant.envs.base import ActionType, SoftRobotEnv, discrete_increments, scaled_box
from pliant.model import Model, State
from pliant.robots import simple_maze as _maze
from pliant.robots import tripod as _tripod


class GeodesicDistance:
    """Shortest-path distance to a goal inside a maze, from Dijkstra on a grid graph.

    Cells of `spacing` mm whose centres lie in the free space of the ball's centre (inside the
    floor, at least `clearance` away from every wall box) are nodes; 8-neighbours are joined by
    edges weighted by their distance. The distance at a point is its nearest node's plus the
    straight distance to that node.
    """

    def __init__(self, walls: list, half_size: float, clearance: float, spacing: float = 1.0):
        ticks = np.arange(-half_size + spacing / 2, half_size, spacing)
        gx, gy = np.meshgrid(ticks, ticks, indexing="ij")
        centres = np.column_stack([gx.ravel(), gy.ravel()])
        free = np.ones(len(centres), dtype=bool)
        for box in walls:
            lo = np.asarray(box.position)[:2] - np.asarray(box.half_extents)[:2] - clearance
            hi = np.asarray(box.position)[:2] + np.asarray(box.half_extents)[:2] + clearance
            free &= ~np.all((centres >= lo) & (centres <= hi), axis=1)
        n = len(ticks)
        graph = nx.Graph()
        index = np.full(n * n, -1)
        index[free] = np.arange(free.sum())
        self.nodes = centres[free]
        ij = np.argwhere(free.reshape(n, n))
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
            w = spacing * float(np.hypot(di, dj))
            for i, j in ij:
                a, b = i + di, j + dj
                if 0 <= a < n and 0 <= b < n and free[a * n + b]:
                    graph.add_edge(int(index[i * n + j]), int(index[a * n + b]), weight=w)
        self.graph = graph
        self.spacing = spacing

    def field(self, goal: np.ndarray) -> np.ndarray:
        """Distances of every node to the node nearest `goal` (x, y)."""
        source = int(np.argmin(np.linalg.norm(self.nodes - goal, axis=1)))
        lengths = nx.single_source_dijkstra_path_length(self.graph, source, weight="weight")
        dist = np.full(len(self.nodes), np.inf)
        dist[list(lengths)] = list(lengths.values())
        return dist

    def at(self, field: np.ndarray, point: np.ndarray) -> float:
        gap = np.linalg.norm(self.nodes - point[:2], axis=1)
        k = int(np.argmin(gap))
        return float(field[k] + gap[k])


class _MazeTask(SoftRobotEnv):
    """What SimpleMaze and Maze share: the ball, the goals, the geodesic reward."""

    def _setup_task(self, start: str, goal_radius: float, goals_corner: list) -> None:
        kw = self.maze_kwargs
        self.half_size = kw.get("maze_size", 60.0) / 2
        size = 2 * self.half_size
        corridors = kw.get("corridors", 3)
        wall = kw.get("wall_thickness", 2.0)
        boxes = _maze.maze_boxes(size=size, corridors=corridors, wall_thickness=wall)
        radius = kw.get("ball_radius", 4.0)
        self.geodesic = GeodesicDistance(boxes[1:], self.half_size, clearance=radius + 0.5)
        path = _maze.maze_path(size, corridors, wall)
        self.corners = np.array(goals_corner if goals_corner else path[[0, 1, -2, -1]])
        self._fields = [self.geodesic.field(c) for c in self.corners]
        self.goal_radius = float(goal_radius)
        if start not in ("path", "centre"):
            raise ValueError(f"start must be 'path' or 'centre', got {start!r}")
        self.start = start

    def ball(self) -> np.ndarray:
        return _maze.ball_in_maze(self.model, self.state)

    def _start_state(self, state: State) -> State:
        if self.start == "centre":
            offset = state.rigid_positions[_maze.BALL] - _maze.ball_in_maze(self.model, state)
            state.rigid_positions[_maze.BALL] = np.array([0.0, 0.0, self.ball()[2]]) + offset
        return state

    def _reset_task(self, rng, options) -> None:
        self.state = self._start_state(self.state)
        goal = (options or {}).get("goal")
        k = int(rng.integers(len(self.corners))) if goal is None else int(goal)
        if not 0 <= k < len(self.corners):
            raise ValueError(f"goal must be a corner index in [0, {len(self.corners)}), got {goal}")
        self.task["corner"] = k
        self.task["goal"] = self.corners[k].copy()
        d = self.geodesic.at(self._fields[k], self.ball())
        self.task["d0"] = max(d, 1e-9)
        self.task["distance"] = d

    def _maze_reward(self):
        ball = self.ball()
        d = self.geodesic.at(self._fields[self.task["corner"]], ball)
        fallen = bool(np.any(np.abs(ball[:2]) > self.half_size) or ball[2] < -5.0)
        r = 0.0 if fallen else float(np.clip((self.task["distance"] - d) / self.task["d0"], 0, 1))
        self.task["distance"] = d
        self.task["fallen"] = fallen
        return r, fallen or d <= self.goal_radius, {"path_progress": r}

    def _info(self):
        d = self.task["distance"]
        return {
            "distance": d,
            "fallen": self.task.get("fallen", False),
            "is_success": d <= self.goal_radius,
        }

    def _render_goal(self):
        # The goal in the world: from the ball, by the goal's offset in the maze's frame.
        ball = self.ball()
        offset = np.array([*(self.task["goal"] - ball[:2]), 0.0])
        rotation = self.state.rigid_rotations[_maze.MAZE]
        return self.state.rigid_positions[_maze.BALL] + rotation @ offset


class SimpleMazeEnv(_MazeTask):
    name = "SimpleMaze"
    version = 1
    view = (45.0, -70.0)

    def __init__(
        self,
        *,
        dt: float = 0.01,
        substeps: int = 10,
        action_type: ActionType = "discrete",
        action_scale: float = 0.05,
        max_tilt: float = 0.2,
        start: str = "path",
        goal_radius: float = 5.0,
        render_mode: str | None = None,
        tangent: str = "lagged",
        **maze_kwargs,
    ) -> None:
        self.maze_kwargs = maze_kwargs
        self.max_tilt = float(max_tilt)
        self.action_scale = float(action_scale)
        super().__init__(
            dt=dt,
            substeps=substeps,
            action_type=action_type,
            render_mode=render_mode,
            tangent=tangent,
        )
        self._setup_task(start, goal_radius, [])
        if action_type == "discrete":
            self._table = discrete_increments(2, self.action_scale)
            self.action_space = gym.spaces.Discrete(4)
        else:
            self.action_space = scaled_box(-1.0, 1.0, (2,))
        self.observation_space = scaled_box(-3.0, 3.0, (7,))

    def _build(self) -> Model:
        self.tilt = self.ramp("tilt", [0.0, 0.0])
        return _maze.simple_maze(max_tilt=self.max_tilt, tilt=self.tilt.pair, **self.maze_kwargs)

    def _commands_from_action(self, action) -> None:
        if self.action_type == "discrete":
            target = self.tilt.target + self._table[action]
        else:
            target = self.max_tilt * np.asarray(action, dtype=float)
        target = np.clip(target, -self.max_tilt, self.max_tilt)
        self.tilt.retarget(self.state.time, target, self.step_time)

    def _observe(self) -> np.ndarray:
        tilt = self.tilt.value(self.state.time) / self.max_tilt
        return np.concatenate(
            [tilt, self.ball() / self.half_size, self.task["goal"] / self.half_size]
        )

    def _reward(self):
        return self._maze_reward()


class MazeEnv(_MazeTask):
    name = "Maze"
    version = 1
    view = (35.0, -70.0)

    def __init__(
        self,
        *,
        dt: float = 0.01,
        substeps: int = 5,
        action_type: ActionType = "discrete",
        action_scale: float = 0.1,
        max_servo_angle: float = 1.5,
        start: str = "path",
        goal_radius: float = 5.0,
        mesh_size: float = 5.0,
        render_mode: str | None = None,
        tangent: str = "lagged",
        **maze_kwargs,
    ) -> None:
        self.maze_kwargs = maze_kwargs
        self.max_angle = float(max_servo_angle)
        self.action_scale = float(action_scale)
        self.mesh_size = mesh_size
        super().__init__(
            dt=dt,
            substeps=substeps,
            action_type=action_type,
            render_mode=render_mode,
            tangent=tangent,
        )
        self._setup_task(start, goal_radius, [])
        if action_type == "discrete":
            self._table = discrete_increments(3, self.action_scale)
            self.action_space = gym.spaces.Discrete(6)
        else:
            self.action_space = scaled_box(-1.0, 1.0, (3,))
        self.observation_space = scaled_box(-3.0, 3.0, (10,))

    def _build(self) -> Model:
        self.servos = self.ramp("servos", [0.0, 0.0, 0.0])
        return _tripod.tripod_maze(
            mesh_size=self.mesh_size,
            max_servo_angle=self.max_angle,
            servo_angles=self.servos.value,
            **self.maze_kwargs,
        )

    def maze_tilt(self) -> np.ndarray:
        """(theta_x, theta_y) of the maze: its floor's normal read as Rot(x) Rot(y)."""
        n = self.state.rigid_rotations[_maze.MAZE][:, 2]
        return np.array([-np.arcsin(np.clip(n[1], -1, 1)), np.arctan2(n[0], n[2])])

    def _commands_from_action(self, action) -> None:
        if self.action_type == "discrete":
            target = self.servos.target + self._table[action]
        else:
            target = self.max_angle * np.asarray(action, dtype=float)
        self.servos.retarget(
            self.state.time, np.clip(target, -self.max_angle, self.max_angle), self.step_time
        )

    def _observe(self) -> np.ndarray:
        return np.concatenate(
            [
                self.maze_tilt() / 0.5,
                self.ball() / self.half_size,
                self.task["goal"] / self.half_size,
                self.servos.value(self.state.time) / self.max_angle,
            ]
        )

    def _reward(self):
        return self._maze_reward()
