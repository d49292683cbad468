"""``pliant bench``'s yardsticks (#62 item 5): scenes beside SOFA are timed from rest with a
new solver each run, as SOFA's batch runner times them, and MuJoCo flex (optional) builds the
same cantilever and moves it as Pliant does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pliant.bench import cantilever, sofa_scene, time_steps
from pliant.bench.engine import TRUNK_CABLES
from pliant.bench.mujoco_peer import FlexPeer, flex_xml, race
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.material import Corotational
from pliant.mesh import box_beam
from pliant.solvers import ImplicitEuler


@pytest.fixture(scope="module")
def beam():
    """The bench's smallest cantilever (240 tets)."""
    return cantilever(2)


def test_from_rest_times_the_first_factorisation_of_every_run(beam) -> None:
    """From rest, each run's new solver factorises on its first step; after a warm-up the kept
    factor serves the timed steps (the lagged policy, a beam settling under gravity)."""
    steps = 3

    def timing(from_rest: bool):
        return time_steps(
            lambda: ImplicitEuler(beam, 0.01, tangent="lagged"),
            beam.rest_state(),
            lambda s: None,
            steps,
            2,
            30,
            from_rest=from_rest,
        )

    assert timing(True).factorisations_per_step >= 1.0 / steps
    assert timing(False).factorisations_per_step < 1.0 / steps


MESHES = Path("../shared/meshes")


@pytest.mark.skipif(
    not (MESHES.parent / "sofa-reference" / "trunk_cables.scn").is_file(),
    reason="../shared/sofa-reference (SOFA's scenes) is not beside the checkout",
)
def test_the_trunk_with_cables_pulls_what_sofas_scene_pulls() -> None:
    """The Trunk's "with cables" row is timed beside SOFA's figure on trunk_cables.scn: the
    same commands (one cable, L0 at 10 mm)."""
    loaded = sofa_scene(MESHES, "trunk_cables.scn")
    np.testing.assert_array_equal(loaded.commands(), TRUNK_CABLES)
    assert np.count_nonzero(TRUNK_CABLES) == 1


def test_the_peer_refuses_a_body_it_cannot_build_alike() -> None:
    mesh = box_beam(10.0, 2.0, 2.0, nx=2, ny=1, nz=1)
    lumped = TetBody(mesh, Corotational(1000.0, 0.45), total_mass=0.01, mass="lumped")
    with pytest.raises(ModelError, match="uniform"):
        flex_xml(lumped, 0.01)


def test_mujoco_flex_moves_the_cantilever_as_pliant_does(beam) -> None:
    """Same mesh, material, mass, held nodes, gravity and step: after 1 s the tip of MuJoCo's
    flex (Saint Venant-Kirchhoff, its discrete integrator, solved to its tolerance) is within
    1 % of Pliant's (corotational, linearly implicit Euler), and the race reports both rates."""
    pytest.importorskip("mujoco")
    peer = FlexPeer(beam)
    assert peer.model.nflex == 1 and peer.model.flex_elemnum[0] == beam.body.n_elements
    np.testing.assert_allclose(peer.positions(), beam.body.rest_positions, atol=1e-9)
    result = race(beam, steps=2, repeats=1, warmup=1, settings={"converged": {}})
    mujoco = result["mujoco"]["converged"]
    assert result["pliant_steps_per_s"] > 0.0 and mujoco["steps_per_s"] > 0.0
    assert mujoco["steps_short_of_tolerance"] == 0
    pliant_tip = np.array(result["pliant_tip_displacement_mm"])
    assert pliant_tip[2] < -1.0  # the free end sags about 1.2 mm under gravity
    assert mujoco["tip_difference_percent"] < 1.0
