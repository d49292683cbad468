"""The small scene the gradients are verified on (tests/diff) and the calibration study
calibrates (experiments/diff/calibration.py): a coarse beam with two cables and a tip load."""

from __future__ import annotations

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.contact import Contacts
from pliant.fem.body import TetBody
from pliant.fem.loads import NodalForces
from pliant.fem.material import Corotational, NeoHookean
from pliant.geometry.collision import Plane
from pliant.mesh.shapes import box_beam
from pliant.model import Model


def cable_beam(
    *,
    young_modulus=200.0,
    poisson_ratio=0.3,
    density=1e-6,
    rayleigh_mass=0.5,
    rayleigh_stiffness=0.01,
    law="polar",
    points=None,
    tip_force=(0.0, 0.0, -1.0),
    modes=("displacement", "force"),
):
    """A 60 x 10 x 10 mm beam of 30 tetrahedra held at x = 0, a cable along its top edge and
    one along a bottom edge (through nodes, so that moving the rest nodes keeps the cables'
    embedding), a tip load."""
    mesh = box_beam(60.0, 10.0, 10.0, 5, 1, 1)
    if points is not None:
        mesh = type(mesh)(points, mesh.tets)
    rest = box_beam(60.0, 10.0, 10.0, 5, 1, 1).points
    near = np.isclose
    fixed = np.flatnonzero(near(rest[:, 0], 0.0))
    top = np.flatnonzero(near(rest[:, 2], 10.0) & near(rest[:, 1], 0.0) & ~near(rest[:, 0], 0.0))
    bottom = np.flatnonzero(near(rest[:, 2], 0.0) & near(rest[:, 1], 10.0) & ~near(rest[:, 0], 0.0))
    tip = np.flatnonzero(near(rest[:, 0], 60.0))
    material = (
        NeoHookean(young_modulus, poisson_ratio)
        if law == "neo-hookean"
        else Corotational(young_modulus, poisson_ratio, rotation=law)
    )
    body = TetBody(
        mesh,
        material,
        density=density,
        fixed_nodes=fixed,
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=rayleigh_mass,
        rayleigh_stiffness=rayleigh_stiffness,
        loads=[NodalForces(tip, np.asarray(tip_force) / tip.size)],
    )
    cables = [
        CableActuator(
            EmbeddedPoints.at_nodes(nodes[np.argsort(rest[nodes, 0])]),
            body.rest_positions,
            pull_point=np.array(pull),
            name=name,
            mode=mode,
            max_force=1e3,
        )
        for name, nodes, pull, mode in (
            ("top", top, [-10.0, 0.0, 10.0], modes[0]),
            ("bottom", bottom, [-10.0, 10.0, 0.0], modes[1]),
        )
    ]
    return Model(body, actuators=cables, name="beam")


def routing_finger(finger: Model, *, pull=8.0):
    """The Soft Finger `finger` (:func:`pliant.robots.finger.soft_finger` at its default
    dimensions, displacement-mode cables) with its closing cable only, and the box each of
    that cable's six routing points may move in, in x and z (y held at the mid-plane): the
    half of its phalanx (40 mm long, 20 mm high, phalanges every 52 mm) it starts in, less
    1 mm. Returns (model, commands,
    free, lower, upper) for :class:`pliant.diff.design.RoutingDesign` on the cable "cable_0"
    pulled by `pull` mm.
    """
    model = Model(
        finger.body, actuators=finger.actuators[:1], effectors=finger.effectors, name="finger"
    )
    half = np.repeat(np.arange(3), 2) * 52.0 + np.tile([0.0, 20.0], 3)
    free = np.tile([True, False, True], (6, 1))
    lower = np.column_stack([half + 1.0, np.ones(6)]).ravel()
    upper = np.column_stack([half + 19.0, np.full(6, 19.0)]).ravel()
    return model, np.array([pull]), free, lower, upper


def beam_on_floor(*, friction=0.3, floor=-0.6, **beam):
    """:func:`cable_beam` over a floor (a plane `floor` mm below its underside) that its tip
    sags onto within a step, Coulomb friction `friction`, the contact solver's tolerance
    tight (1e-13 mm) so that finite differences of the steps resolve its forces."""
    model = cable_beam(**beam)
    contacts = Contacts([Plane(point=(0.0, 0.0, floor))], friction=friction, tolerance=1e-13)
    return Model(model.body, actuators=model.actuators, contacts=contacts, name="beam on floor")
