"""Transfer of a proxy's strategy to the FEM Trunk pushing its cube (pliant.transfer.proxy,
thesis §4.1.1): the ``pliant proxy transfer`` command and its refusals, a trained policy as
the proxy's, a transfer that stops when its task ends, and a proxy coarser in time than the
FEM (the Multigait's transfer: test_proxy_transfer.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pliant.errors import ModelError


def test_the_transfer_command_writes_both_trajectories_and_refuses_bad_actions(tmp_path) -> None:
    """`pliant proxy transfer trunk` on two steps bending onto the cube: JSON and PNG written,
    the FEM's cube pushed along +x as the proxy's, by the QP and by the sensitivity inverse;
    a Multigait action outside Discrete(6), an unknown inverse model and a prior the robot
    cannot take are refused before any work."""
    import json

    from typer.testing import CliRunner

    from pliant.cli import app

    runner = CliRunner()
    actions = "0,0.05,0,0.05,0;0,0.1,0,0.1,0"
    args = ["proxy", "transfer", "trunk", "--actions", actions, "--out", str(tmp_path)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "trunk_transfer.json").read_text())
    assert (tmp_path / "trunk_transfer.png").stat().st_size > 0
    assert len(report["steps"]) == 2 and report["failed_inverse_steps"] == 0
    assert report["proxsuite_build"] == "proxsuite_pywrap"  # the reproducible build
    start = report["start"]
    proxy, fem = report["steps"][-1]["proxy_position"], report["steps"][-1]["fem_position"]
    assert proxy[0] > start[0] + 5.0 and fem[0] > start[0] + 5.0
    bad = runner.invoke(app, ["proxy", "transfer", "multigait", "--actions", "4,7"])
    assert bad.exit_code == 2
    # The sensitivity inverse on the Trunk's cables and base: the cube pushed the same way.
    sens = tmp_path / "sensitivity"
    result = runner.invoke(app, [*args[:-1], str(sens), "--inverse-model", "sensitivity"])
    assert result.exit_code == 0, result.output
    report = json.loads((sens / "trunk_transfer.json").read_text())
    assert report["gains"]["inverse_model"] == "sensitivity"
    assert report["failed_inverse_steps"] == 0
    assert report["steps"][-1]["fem_position"][0] > start[0] + 5.0
    refused = runner.invoke(app, [*args, "--inverse-model", "newton"])
    assert refused.exit_code == 1 and "one of qp, twin, sensitivity" in refused.output
    refused = runner.invoke(app, [*args, "--inverse-model", "twin"])  # the base's clock
    assert refused.exit_code == 1 and "moving base" in refused.output
    refused = runner.invoke(app, [*args, "--prior-weight", "1"])  # no map from its commands
    assert refused.exit_code == 1 and "no feedforward map" in refused.output
    refused = runner.invoke(app, ["proxy", "transfer", "multigait", "--prior-weight", "-1"])
    assert refused.exit_code == 1 and "prior's weight" in refused.output
    for robot, matched in (("trunk", "underside"), ("multigait", "middle")):
        refused = runner.invoke(app, ["proxy", "transfer", robot, "--matched", matched])
        assert refused.exit_code == 2 and "--matched" in refused.output
    # --proxy: a calibration report's proxy, here the defaults touching through the surface.
    from pliant.proxy.builders import TRUNK_PARAMETERS

    fitted = tmp_path / "fitted.json"
    fitted.write_text(json.dumps({"parameters": TRUNK_PARAMETERS, "contact": "surface"}))
    out = tmp_path / "surface"
    result = runner.invoke(app, [*args[:-1], str(out), "--proxy", str(fitted)])
    assert result.exit_code == 0, result.output
    skinned = json.loads((out / "trunk_transfer.json").read_text())
    pushed = skinned["steps"][-1]["proxy_position"]
    assert pushed[0] > start[0] + 5.0 and abs(pushed[0] - proxy[0]) > 1e-3  # another proxy
    both = runner.invoke(app, [*args, "--proxy", str(fitted), "--policy", str(fitted)])
    assert both.exit_code == 2 and "brings the proxy" in both.output
    (tmp_path / "bad.json").write_text(json.dumps({"parameters": {"cube_mass": "heavy"}}))
    bad = runner.invoke(app, [*args, "--proxy", str(tmp_path / "bad.json")])
    assert bad.exit_code == 2 and "not a calibration report" in bad.output


def test_the_transfer_command_runs_a_trained_policy_with_its_normaliser(tmp_path) -> None:
    """`--policy` takes a folder saved by the training stack (model, VecNormalize, the
    environment's keywords): one step of an untrained PPO on the Trunk proxy with
    bend_limit 0.2 towards --goal; --goal is refused for the Multigait (exit 2)."""
    import json

    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize
    from typer.testing import CliRunner

    import pliant.envs  # noqa: F401  (registers the environments)
    from pliant.cli import app
    from pliant.learn.evaluate import save_policy

    kwargs = {"bend_limit": 0.2}
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("pliant/TrunkPushProxy-v0", **kwargs)]))
    model = PPO("MlpPolicy", venv, n_steps=16, seed=0)
    save_policy(model, tmp_path / "policy", "PPO", "pliant/TrunkPushProxy-v0", kwargs, venv)
    runner = CliRunner()
    args = ["proxy", "transfer", "trunk", "--policy", str(tmp_path / "policy"), "--steps", "1"]
    result = runner.invoke(app, [*args, "--goal=10,5", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "trunk_transfer.json").read_text())
    assert len(report["steps"]) == 1 and report["failed_inverse_steps"] == 0
    multigait = ["proxy", "transfer", "multigait", "--goal=10,5"]
    assert runner.invoke(app, multigait).exit_code == 2


def test_a_transfer_stops_at_the_first_step_its_until_holds() -> None:
    """`until`: the run ends after the first step at which it holds (an episode its task
    ends early), the steps before it all recorded; without it every step is taken."""
    from pliant.transfer.proxy import trunk_transfer

    push = [(0.0, 0.05, 0.0, 0.05, 0.0)] * 3
    asked = []

    def second_time() -> bool:
        asked.append(True)
        return len(asked) == 2

    assert len(trunk_transfer().run(push, until=second_time).steps) == 2 and len(asked) == 2
    assert len(trunk_transfer().run(push).steps) == 3


def test_a_coarser_proxy_is_followed_by_the_fem_in_its_own_steps() -> None:
    """A proxy stepping 0.03 s (10 sub-steps to the Trunk's 0.3 s step) drives the FEM at its
    0.01 s, three FEM steps per proxy sub-step towards the proxy's points interpolated between
    them: the same simulated time, and the FEM follows as closely as under a proxy at the
    FEM's step; a proxy step that is no whole number of the FEM's, or not positive, is
    refused."""
    from pliant.transfer.proxy import TRUNK_GAINS, proxy_timing, trunk_transfer

    push = [(0.0, 0.05, 0.0, 0.05, 0.0)] * 2
    loops = {
        0.01: trunk_transfer(),
        0.02: trunk_transfer(env_kwargs={"dt": 0.02, "substeps": 15}),
        0.03: trunk_transfer(env_kwargs={"dt": 0.03, "substeps": 10}),
    }
    coarse = loops[0.03]
    assert (coarse.gains.scale, coarse.gains.fem_substeps) == (10, 3)
    assert coarse.solver.dt == pytest.approx(0.01) and coarse.env.dt == pytest.approx(0.03)
    start = coarse.state.time
    results = {dt: loop.run(push) for dt, loop in loops.items()}
    assert len(results[0.03].times) == 20  # one record a proxy sub-step
    assert coarse.state.time - start == pytest.approx(0.6)
    assert coarse.env.state.time == pytest.approx(coarse.state.time)
    errors = {dt: max(s.tracking_error for s in r.steps) for dt, r in results.items()}
    # measured: tracking 1.93 / 1.93 / 1.94 mm. Where the cube ends is not compared across
    # steps: a strike is chaotic (the inverse solve's roundoff, 1e-13, decides between two
    # outcomes 3 mm apart at dt 0.02 between runs); each FEM's cube is pushed along +x and
    # ends near its own proxy's (measured 0.3-2.9 mm)
    assert max(errors.values()) < errors[0.01] + 0.5, errors
    for result in results.values():
        fem, proxy = np.array(result.fem_trajectory[-1]), np.array(result.proxy_trajectory[-1])
        assert fem[0] - result.start[0] > 5.0
        assert np.linalg.norm(fem - proxy) < 4.0, (fem, proxy)
    with pytest.raises(ModelError, match="whole number"):
        proxy_timing({"dt": 0.025}, TRUNK_GAINS, 0.01)
    for bad in (0.0, -0.03, float("nan")):
        with pytest.raises(ModelError, match="finite and > 0"):
            proxy_timing({"dt": bad}, TRUNK_GAINS, 0.01)
    with pytest.raises(ModelError, match="fem_substeps"):
        dataclasses.replace(TRUNK_GAINS, fem_substeps=0)
