"""Interactive 3-D viewer in the browser (``pliant view``), on viser (a three.js viewer driven
from Python).

Three sources:

* a robot or scene (:class:`SimulationViewer`): the simulation runs live; a slider per actuator
  sets its command (cable displacement or force, cavity pressure or volume: the actuator's own
  mode and bounds), and a goal the user drags in the scene drives the inverse QP (the runSofa +
  SoftRobots.Inverse experience); play, pause, step and reset;
* an environment (:class:`EnvironmentViewer`): an episode with random actions or a trained
  Stable-Baselines3 policy; play, pause, step and reset;
* a saved run: the ParaView series ``pliant run`` writes (a folder with a ``.pvd``,
  :class:`PlaybackViewer`), or a series of saved states (``State.save`` files, which
  ``pliant run --states`` writes, :class:`StatePlaybackViewer`: drawn with the model, so cables,
  effectors and rigid bodies too), with a time slider and play, step and reset.

Scenes are in mm; the viewer shows them in metres (three.js' camera and grid expect it).
"""

from __future__ import annotations

import json
import socket
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from pliant.constraints.cable import CableActuator
from pliant.constraints.control import InverseControl
from pliant.errors import PliantError, StateError
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model, State
from pliant.viz.shapes import shape_surface

#: mm -> m for display.
SCALE = 1e-3
BODY_RGB = (74, 134, 200)
OBSTACLE_RGB = (176, 176, 176)
RIGID_RGB = (224, 148, 74)


class ViewerError(PliantError, ValueError):
    """The viewer cannot show what it was given (unknown name, unreadable run folder)."""


#: the file beside a series of states that names the robot they belong to.
SERIES_FILE = "series.json"


def free_port(preferred: int, host: str = "127.0.0.1", tries: int = 50) -> int:
    """`preferred` if nothing listens there, else the next free port."""
    for port in range(preferred, preferred + tries):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    raise ViewerError(f"no free port in [{preferred}, {preferred + tries})")


class _Viewer:
    """The server, the scene of one model, and the simulation thread."""

    def __init__(self, model: Model, *, host: str = "127.0.0.1", port: int = 8080) -> None:
        import viser

        self.model = model
        self.port = free_port(port, host)
        self.server = viser.ViserServer(host=host, port=self.port, verbose=False)
        self.lock = threading.Lock()
        self.playing = False
        self.steps = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        rest, tris = model.body.skin(model.body.rest_positions)
        self._triangles = tris
        lo, hi = rest.min(axis=0), rest.max(axis=0)
        self.centre, self.size = 0.5 * (lo + hi), float(np.max(hi - lo))
        camera = self.server.initial_camera
        camera.look_at = tuple(self.centre * SCALE)
        camera.position = tuple((self.centre + np.array([1.2, -1.6, 1.0]) * self.size) * SCALE)
        gravity = np.asarray(getattr(model.body, "gravity", (0.0, 0.0, -1.0)), dtype=float)
        if np.any(gravity):
            camera.up = tuple(-gravity / np.linalg.norm(gravity))
        self._draw_obstacles()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.port}"

    def _draw_obstacles(self) -> None:
        if self.model.contacts is None:
            return
        for k, shape in enumerate(self.model.contacts.shapes):
            pts, tris = shape_surface(shape, extent=0.8 * self.size, centre=self.centre)
            self.server.scene.add_mesh_simple(
                f"/obstacles/{k}", pts * SCALE, tris, color=OBSTACLE_RGB, side="double"
            )

    def show(self, state, goal: np.ndarray | None = None) -> None:
        """Draw the body, cables, effectors, rigid bodies (and the goal marker) at `state`."""
        x = state.positions
        pts, _ = self.model.body.skin(x)
        scene = self.server.scene
        with self.server.atomic():
            scene.add_mesh_simple(
                "/robot/body", pts * SCALE, self._triangles, color=BODY_RGB, side="double"
            )
            for a in self.model.actuators:
                if isinstance(a, CableActuator):
                    line = a.polyline(x) * SCALE
                    segments = np.stack([line[:-1], line[1:]], axis=1)
                    scene.add_line_segments(
                        f"/robot/{a.name}",
                        segments,
                        (240, 140, 40),
                        thickness=2.0,
                        thickness_units="screen",
                    )
            for i, body in enumerate(self.model.rigid_bodies):
                rpts, rtris = shape_surface(
                    body.shape,
                    position=state.rigid_positions[i],
                    rotation=state.rigid_rotations[i],
                )
                scene.add_mesh_simple(f"/rigid/{i}", rpts * SCALE, rtris, color=RIGID_RGB)
            for e in self.model.effectors:
                if hasattr(e, "position"):
                    p = np.atleast_2d(e.position(x)) * SCALE
                    scene.add_point_cloud(
                        f"/robot/{e.name}",
                        p,
                        (220, 40, 40),
                        point_size=0.004,
                        point_shape="circle",
                    )

    def _loop(self) -> None:
        while not self._stop.is_set():
            if self.playing:
                self.advance()
            else:
                time.sleep(0.02)

    def advance(self) -> None:
        raise NotImplementedError

    def start(self) -> None:
        """Run the simulation thread (the server already serves)."""
        self._thread = threading.Thread(target=self._loop, name="pliant-viewer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self.server.stop()

    def _playback_buttons(self) -> None:
        gui = self.server.gui
        play = gui.add_checkbox("Play", initial_value=self.playing)
        step = gui.add_button("Step")
        reset = gui.add_button("Reset")

        @play.on_update
        def _(_event) -> None:
            self.playing = bool(play.value)

        @step.on_click
        def _(_event) -> None:
            self.advance()

        @reset.on_click
        def _(_event) -> None:
            self.reset()

    def reset(self) -> None:
        raise NotImplementedError


class SimulationViewer(_Viewer):
    """A robot simulated live, its actuators on sliders, a draggable goal for inverse control.

    Args:
        model: the robot.
        solver: a solver with ``step(state, control)`` (an ImplicitEuler of the model).
        host, port: where to serve (the next free port if `port` is taken).
        playing: start running at once.
    """

    def __init__(
        self,
        model: Model,
        solver,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        playing: bool = True,
    ) -> None:
        super().__init__(model, host=host, port=port)
        self.solver = solver
        self.state = model.rest_state()
        self.playing = playing
        self.commands = np.zeros(len(model.actuators))
        gui = self.server.gui
        self._playback_buttons()
        self.mode = gui.add_dropdown(
            "Control", ("sliders", "inverse (drag the goal)"), initial_value="sliders"
        )
        self.sliders = []
        with gui.add_folder("Actuators"):
            for i, a in enumerate(model.actuators):
                lo, hi = _slider_range(a)
                slider = gui.add_slider(
                    f"{a.name} ({a.mode})", min=lo, max=hi, step=(hi - lo) / 200, initial_value=0.0
                )
                slider.on_update(self._slider_callback(i))
                self.sliders.append(slider)
        self.goal_control = None
        if model.effectors and hasattr(model.effectors[0], "position"):
            start = np.atleast_2d(model.effectors[0].position(self.state.positions))[0]
            self.goal_control = self.server.scene.add_transform_controls(
                "/goal",
                scale=0.15 * self.size * SCALE,
                disable_rotations=True,
                position=tuple(start * SCALE),
            )
            self.server.scene.add_icosphere(
                "/goal/marker", radius=0.02 * self.size * SCALE, color=(40, 180, 60)
            )
        self.show(self.state)

    def _slider_callback(self, i: int):
        def update(_event) -> None:
            with self.lock:
                self.commands[i] = float(self.sliders[i].value)

        return update

    def goal(self) -> np.ndarray | None:
        if self.goal_control is None:
            return None
        return np.asarray(self.goal_control.position, dtype=float) / SCALE

    def control(self):
        if self.mode.value.startswith("inverse") and self.goal_control is not None:
            return InverseControl(goals=[self.goal()[None, :]])
        with self.lock:
            return self.commands.copy() if len(self.commands) else None

    def advance(self) -> None:
        try:
            self.state = self.solver.step(self.state, self.control())
        except PliantError as exc:  # a diverged step pauses the run and says why
            self.playing = False
            self.server.gui.add_markdown(f"**Stopped:** {exc}")
            return
        self.steps += 1
        self.show(self.state)

    def reset(self) -> None:
        self.state = self.model.rest_state()
        self.show(self.state)


def _slider_range(actuator) -> tuple[float, float]:
    """The command's range: the displacement bounds in displacement mode, the force bounds in
    force mode (finite fallbacks where a bound is infinite)."""
    if actuator.mode == "displacement":
        lo, hi = actuator.min_displacement, actuator.max_displacement
        fallback = 30.0
    else:
        lo, hi = actuator.min_force, actuator.max_force
        fallback = 1000.0
    lo = lo if np.isfinite(lo) else -fallback
    hi = hi if np.isfinite(hi) else fallback
    if lo >= hi:
        hi = lo + 1.0
    return float(max(lo, -fallback) if lo < 0 else lo), float(hi)


class EnvironmentViewer(_Viewer):
    """An environment's episode, with random actions or a policy (``policy(obs) -> action``)."""

    def __init__(
        self,
        env,
        *,
        policy=None,
        host: str = "127.0.0.1",
        port: int = 8080,
        seed: int = 0,
        playing: bool = True,
    ) -> None:
        self.env = env
        self.policy = policy
        self.seed = seed
        self.obs, _ = env.reset(seed=seed)
        super().__init__(env.unwrapped.model, host=host, port=port)
        self.playing = playing
        self.episode_return = 0.0
        self._playback_buttons()
        self.info = self.server.gui.add_markdown("")
        self.show(env.unwrapped.state)

    def advance(self) -> None:
        action = self.env.action_space.sample() if self.policy is None else self.policy(self.obs)
        self.obs, reward, terminated, truncated, info = self.env.step(action)
        self.episode_return += float(reward)
        self.steps += 1
        self.info.content = f"step {self.steps}, return {self.episode_return:.3f}"
        self.show(self.env.unwrapped.state)
        if terminated or truncated:
            self.playing = False
            self.info.content += " — episode over" + (
                f" ({info['diverged']})" if "diverged" in info else ""
            )

    def reset(self) -> None:
        self.obs, _ = self.env.reset()
        self.steps, self.episode_return = 0, 0.0
        self.show(self.env.unwrapped.state)


def read_series(folder: Path) -> tuple[list[float], list[Path]]:
    """Times and files of the ParaView series (.pvd) in `folder`."""
    folder = Path(folder)
    pvds = sorted(folder.glob("*.pvd")) if folder.is_dir() else []
    if not pvds:
        raise ViewerError(
            f"{folder}: no ParaView series (.pvd) here: give a folder `pliant run` wrote"
        )
    try:
        root = ET.parse(pvds[0]).getroot()
    except ET.ParseError as exc:
        raise ViewerError(f"{pvds[0]}: not a readable .pvd file ({exc})") from None
    entries = [(float(d.get("timestep")), folder / d.get("file")) for d in root.iter("DataSet")]
    if not entries:
        raise ViewerError(f"{pvds[0]}: the series holds no frame")
    missing = [str(p) for _, p in entries if not p.is_file()]
    if missing:
        raise ViewerError(f"{pvds[0]}: missing frames {missing[:3]}")
    return [t for t, _ in entries], [p for _, p in entries]


class PlaybackViewer:
    """A saved run (a ``pliant run`` folder) played back with a time slider."""

    def __init__(self, folder: Path, *, host: str = "127.0.0.1", port: int = 8080) -> None:
        import meshio
        import viser

        self.times, files = read_series(folder)
        meshes = [meshio.read(f) for f in files]
        self.frames = [m.points for m in meshes]
        cells = meshes[0].cells_dict
        if "tetra" in cells:
            self.triangles = TetMesh(meshes[0].points, cells["tetra"]).boundary_triangles()
        else:
            raise ViewerError(f"{folder}: the series holds no tetrahedra to draw")
        self.port = free_port(port, host)
        self.server = viser.ViserServer(host=host, port=self.port, verbose=False)
        self.slider = self.server.gui.add_slider(
            "time (s)", min=0, max=len(self.times) - 1, step=1, initial_value=0
        )
        self.slider.on_update(lambda _e: self.show(int(self.slider.value)))
        self.show(0)

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.port}"

    def show(self, k: int) -> None:
        self.server.scene.add_mesh_simple(
            "/robot/body", self.frames[k] * SCALE, self.triangles, color=BODY_RGB, side="double"
        )

    def start(self) -> None:
        pass

    def stop(self) -> None:
        self.server.stop()


def state_files(target: Path) -> list[Path]:
    """The state files of `target`: itself (an ``.npz``), the ``.npz`` files of a folder, or
    those of its ``states/`` folder (a ``pliant run --states`` folder); [] if none."""
    target = Path(target)
    if target.is_file():
        return [target] if target.suffix == ".npz" else []
    for folder in (target / "states", target):
        files = sorted(folder.glob("*.npz")) if folder.is_dir() else []
        if files:
            return files
    return []


def read_states(files: list[Path], model: Model) -> list[State]:
    """The states in `files`, checked against `model`, in the order of their time."""
    try:
        states = [State.load(f, model) for f in files]
    except StateError as exc:
        raise ViewerError(str(exc)) from None
    return sorted(states, key=lambda s: (s.time, s.step))


def series_robot(files: list[Path]) -> str | None:
    """The robot named by the ``series.json`` beside the state files, if there is one."""
    sidecar = files[0].parent / SERIES_FILE
    if not sidecar.is_file():
        return None
    try:
        return str(json.loads(sidecar.read_text())["robot"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ViewerError(f"{sidecar}: not a readable series description ({exc})") from None


class StatePlaybackViewer(_Viewer):
    """A series of saved states of `model`, played back with a time slider (and play, step,
    reset); each frame is drawn as a live one is: body, cables, effectors, rigid bodies."""

    def __init__(
        self, model: Model, states: list[State], *, host: str = "127.0.0.1", port: int = 8080
    ) -> None:
        if not states:
            raise ViewerError("no state to play back")
        super().__init__(model, host=host, port=port)
        self.states = states
        self.times = [s.time for s in states]
        self.frame = 0
        self._playback_buttons()
        self.slider = self.server.gui.add_slider(
            "frame", min=0, max=max(1, len(states) - 1), step=1, initial_value=0
        )
        self.label = self.server.gui.add_markdown("")
        self.slider.on_update(lambda _e: self.show_frame(int(self.slider.value)))
        self.show_frame(0)

    def show_frame(self, k: int) -> None:
        self.frame = min(max(k, 0), len(self.states) - 1)
        state = self.states[self.frame]
        self.label.content = f"t = {state.time:.3f} s (step {state.step})"
        self.show(state)

    def advance(self) -> None:
        """The next frame (a playing series stops at its end)."""
        if self.frame + 1 >= len(self.states):
            self.playing = False
            return
        self.slider.value = self.frame + 1  # its callback draws the frame
        self.steps += 1
        time.sleep(0.05)

    def reset(self) -> None:
        self.slider.value = 0


def load_policy(path: Path):
    """``obs -> action`` of a Stable-Baselines3 model saved by ``model.save`` (any algorithm)."""
    import stable_baselines3 as sb3

    path = Path(path)
    if not path.is_file():
        raise ViewerError(f"{path}: no such policy file")
    for name in ("PPO", "SAC", "TD3", "A2C", "DQN", "DDPG"):
        try:
            model = getattr(sb3, name).load(path, device="cpu")
        except Exception:  # noqa: BLE001 - the wrong algorithm for this file: try the next
            continue
        return lambda obs: model.predict(obs, deterministic=True)[0]
    raise ViewerError(f"{path}: not a Stable-Baselines3 model")
