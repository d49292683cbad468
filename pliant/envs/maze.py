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

from typing import ClassVar

import networkx as nx
import numpy as np

from pliant.envs.actions import RampTarget, discrete_increments, scaled_box
from pliant.envs.base import SoftRobotEnv
from pliant.envs.config import SimulationConfig, check_choice
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
    """What SimpleMaze and Maze share: the ball, the goals, the geodesic reward, and the action:
    a kinematic input (the tilt, the servo angles) moved by ``action_scale`` rad (discrete) or
    to its target in [-cap, cap] (continuous)."""

    #: the kinematic input the action moves (a ramp's name) and its size
    moved: ClassVar[tuple[str, int]] = ("", 0)
    n_observations: ClassVar[int] = 0

    def __init__(
        self,
        *,
        action_scale: float,
        cap: float,
        start: str = "path",
        goal_radius: float = 5.0,
        **kwargs,
    ) -> None:
        check_choice("start", start, ("path", "centre"))
        self.start = start
        self.goal_radius = float(goal_radius)
        self.action_scale = float(action_scale)
        self.cap = float(cap)
        super().__init__(**kwargs)
        kw = self.robot_kwargs
        self.half_size = kw.get("maze_size", 60.0) / 2
        size = 2 * self.half_size
        corridors = kw.get("corridors", 3)
        wall = kw.get("wall_thickness", 2.0)
        boxes = _maze.maze_boxes(size=size, corridors=corridors, wall_thickness=wall)
        radius = kw.get("ball_radius", 4.0)
        self.geodesic = GeodesicDistance(boxes[1:], self.half_size, clearance=radius + 0.5)
        path = _maze.maze_path(size, corridors, wall)
        self.corners = np.array(path[[0, 1, -2, -1]])
        self._fields = [self.geodesic.field(c) for c in self.corners]
        ramp, n = self.moved
        steps = discrete_increments(n, self.action_scale)
        self.use_actions(RampTarget(ramp, -self.cap, self.cap, steps=steps, size=n))
        self.observation_space = scaled_box(-3.0, 3.0, (self.n_observations,))

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

    def _reward(self):
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
    view = (45.0, -70.0)
    default_config = SimulationConfig(substeps=10)
    moved = ("tilt", 2)
    n_observations = 7

    def __init__(self, *, action_scale: float = 0.05, max_tilt: float = 0.2, **kwargs) -> None:
        self.max_tilt = float(max_tilt)
        super().__init__(action_scale=action_scale, cap=max_tilt, **kwargs)

    def _build(self) -> Model:
        self.tilt = self.ramp("tilt", [0.0, 0.0])
        return _maze.simple_maze(max_tilt=self.max_tilt, tilt=self.tilt.pair, **self.robot_kwargs)

    def _observe(self) -> np.ndarray:
        tilt = self.tilt.value(self.state.time) / self.max_tilt
        return np.concatenate(
            [tilt, self.ball() / self.half_size, self.task["goal"] / self.half_size]
        )


class MazeEnv(_MazeTask):
    name = "Maze"
    view = (35.0, -70.0)
    moved = ("servos", 3)
    n_observations = 10
    robot_defaults = {"mesh_size": 5.0}

    def __init__(
        self, *, action_scale: float = 0.1, max_servo_angle: float = 1.5, **kwargs
    ) -> None:
        self.max_angle = float(max_servo_angle)
        super().__init__(action_scale=action_scale, cap=max_servo_angle, **kwargs)

    def _build(self) -> Model:
        self.servos = self.ramp("servos", [0.0, 0.0, 0.0])
        return _tripod.tripod_maze(
            max_servo_angle=self.max_angle, servo_angles=self.servos.value, **self.robot_kwargs
        )

    def maze_tilt(self) -> np.ndarray:
        """(theta_x, theta_y) of the maze: its floor's normal read as Rot(x) Rot(y)."""
        n = self.state.rigid_rotations[_maze.MAZE][:, 2]
        return np.array([-np.arcsin(np.clip(n[1], -1, 1)), np.arctan2(n[0], n[2])])

    def _observe(self) -> np.ndarray:
        return np.concatenate(
            [
                self.maze_tilt() / 0.5,
                self.ball() / self.half_size,
                self.task["goal"] / self.half_size,
                self.servos.value(self.state.time) / self.max_angle,
            ]
        )
