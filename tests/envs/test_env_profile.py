"""`pliant bench --env-profile` (pliant.bench.envs.profile_env): the shares of an environment
step add up to one, the parts that run do show, and the timing leaves the code as it was;
vector_throughput times each way of stepping copies in turn."""

from __future__ import annotations

import pytest

from pliant.bench.envs import ENV_PARTS, profile_env, vector_throughput
from pliant.constraints import contact
from pliant.envs import ENVS
from pliant.geometry import collision
from pliant.solvers.system import LinearisedSystem


@pytest.fixture(scope="module")
def diamond():
    kwargs = {k: v for k, v in ENVS["Diamond"].quick.items() if k != "substeps"}
    return profile_env("Diamond", env_steps=2, **kwargs)


def test_shares_add_up_to_the_step(diamond):
    shares = diamond["fractions"]
    assert set(shares) == {*ENV_PARTS, "solver_other", "observation", "reward", "glue"}
    assert all(v >= 0.0 for v in shares.values()), shares
    assert sum(shares.values()) == pytest.approx(1.0, abs=1e-9)
    # The Diamond's step computes its forces and solves; it has no contact to detect.
    assert shares["forces"] > 0.0 and shares["solves"] > 0.0
    assert shares["collision"] == 0.0
    assert diamond["env_steps"] == 2 and diamond["real_time_factor"] > 0.0


def test_the_functions_timed_are_put_back(diamond):
    assert not hasattr(LinearisedSystem._assemble, "__wrapped__")
    assert not hasattr(collision.detect, "__wrapped__")
    assert not hasattr(contact.detect, "__wrapped__")


def test_vector_throughput_times_every_mode_in_turn():
    out = vector_throughput(
        "CartStem", 2, steps=1, repeats=2, modes=("sequential", "threads"), **ENVS["CartStem"].quick
    )
    assert set(out["env_steps_per_s"]) == {"sequential", "threads"}
    assert all(len(v) == 2 and min(v) > 0.0 for v in out["runs"].values())
