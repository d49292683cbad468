"""The browser viewer: it starts, draws the robot in a real (headless) Chromium, a slider moved
in the page changes the simulation's actuation, a run folder plays back, bad input is refused
before any server starts, and a taken port moves to the next free one."""

from __future__ import annotations

import shutil
import socket
import time
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from pliant.cli import app, open_viewer
from pliant.viz.viewer import (
    PlaybackViewer,
    StatePlaybackViewer,
    ViewerError,
    free_port,
)

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
playwright = pytest.importorskip("playwright.sync_api", reason="playwright not installed")


@pytest.fixture
def viewer():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        v = open_viewer("diamond", port=free_port(8790), playing=False)
    v.start()
    yield v
    v.stop()


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium not installed (.ci/run installs it)")
def test_robot_drawn_and_slider_moves_the_actuation(viewer):
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=CHROMIUM,
            args=["--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader"],
        )
        try:
            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.goto(viewer.url)
            page.wait_for_selector("canvas", timeout=60000)
            sliders = page.locator("[role=slider]")
            sliders.first.wait_for(timeout=60000)
            assert sliders.count() == len(viewer.model.actuators)
            # The robot's pixels: the body's blue in the middle of the canvas.
            blue = 0
            for _ in range(30):
                time.sleep(0.5)
                shot = page.screenshot()
                image = _decode_png(shot)
                r, g, b = (image[..., k].astype(int) for k in range(3))
                blue = int(np.sum((b > r + 60) & (b > g + 20)))
                if blue > 2000:
                    break
            assert blue > 2000, f"only {blue} robot-coloured pixels"
            # Move cable 0's slider from the page, then step the simulation from the page.
            sliders.first.focus()
            for _ in range(20):
                page.keyboard.press("ArrowRight")
            deadline = time.time() + 10
            while viewer.commands[0] == 0.0 and time.time() < deadline:
                time.sleep(0.1)
            assert viewer.commands[0] > 0.0
            page.get_by_role("button", name="Step").click()
            deadline = time.time() + 20
            while viewer.steps == 0 and time.time() < deadline:
                time.sleep(0.1)
            assert viewer.steps >= 1
            assert viewer.state.displacement[0] > 0.0  # the cable was pulled
        finally:
            browser.close()


def _decode_png(data: bytes) -> np.ndarray:
    import io

    import imageio.v3 as iio

    return np.asarray(iio.imread(io.BytesIO(data)))[..., :3]


def test_unknown_target_is_refused_before_a_server_starts():
    with pytest.raises(ViewerError, match="not a robot"):
        open_viewer("no_such_robot")
    result = CliRunner().invoke(app, ["view", "no_such_robot"])
    assert result.exit_code == 2 and "not a robot" in result.output


def test_taken_port_moves_to_the_next_free_one():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        taken = s.getsockname()[1]
        assert free_port(taken) > taken


def test_playback_of_a_run_folder(tmp_path):
    result = CliRunner().invoke(
        app,
        ["run", "diamond", "--duration", "0.03", "--frames", "3", "--out", str(tmp_path)]
        + ["--states"],
    )
    assert result.exit_code == 0, result.output
    v = PlaybackViewer(tmp_path / "diamond", port=free_port(8830))
    try:
        assert len(v.frames) == 3 and v.times == sorted(v.times)
        v.slider.value = 2
        assert not np.allclose(v.frames[2], v.frames[0])
    finally:
        v.stop()
    with pytest.raises(ViewerError, match="no ParaView series"):
        PlaybackViewer(tmp_path)

    # The saved states play back on the model (named by states/series.json), in time order.
    v = open_viewer(str(tmp_path / "diamond"), port=free_port(8840), playing=False)
    try:
        assert isinstance(v, StatePlaybackViewer) and [s.step for s in v.states] == [1, 2, 3]
        v.slider.value = 2
        assert v.frame == 2 and "step 3" in v.label.content
        v.playing = True
        v.advance()  # the last frame: playing stops there
        assert not v.playing and v.frame == 2
        v.reset()
        assert v.frame == 0
    finally:
        v.stop()
    one = tmp_path / "diamond" / "states" / "state_000002.npz"
    with pytest.raises(ViewerError, match="give --robot"):
        open_viewer(str(one.rename(tmp_path / "one.npz")))
    v = open_viewer(str(tmp_path / "one.npz"), robot="diamond", port=free_port(8850))
    v.stop()
    with pytest.raises(ViewerError, match="does not fit|not fit|nodes"):
        open_viewer(str(tmp_path / "one.npz"), robot="trunk", port=free_port(8850))
