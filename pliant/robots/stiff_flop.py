"""The Stiff-Flop pneumatic trunk (thesis §5.1.5, §5.2.4; Cianchetti et al. 2014): two
silicone modules of three fibre-reinforced chamber pairs, one pressure per pair.

Fibre reinforcement: the real chambers are wound with a thread that stops them ballooning, so a
pressurised chamber lengthens its side of the module and bends it away. Here each chamber wall
carries a membrane (:class:`pliant.fem.membrane.Membrane`) of hoop fibres (round the chamber's
axis, stretch stiffness `fibre_stiffness`) on a soft isotropic skin: the fibres take the hoop
stress, the wall stays free to stretch along the chamber. Without them the coarse chambers
balloon sideways and the module bends far less for the same pressure
(30 kPa in one pair of the base module: the tip moves 4.31 mm with the fibres, 1.57 without).

Units: mm, kg, s, so forces in mN and pressures in kPa (mN/mm^2); 1 bar = 100 kPa. Pressure
bounds are given in bar (`max_pressure_bar`) and converted.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from pliant.errors import ModelError
from pliant.fem.membrane import Membrane
from pliant.mesh import shapes
from pliant.model import Model
from pliant.robots.common import cavity, effector, fixed_by_box, landmark
from pliant.robots.parameters import Damping, Density, Gravity, Meshing, Solid
from pliant.robots.scene import builder

KPA_PER_BAR = 100.0


def _hoop_fibres(points: np.ndarray, triangles: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(t, 3) the hoop direction ez x r round the nearest of the pair's chamber axes."""
    centroids = points[triangles].mean(axis=1)
    gaps = centroids[:, None, :2] - axes[None, :, :]
    nearest = np.argmin(np.linalg.norm(gaps, axis=2), axis=1)
    r = gaps[np.arange(len(triangles)), nearest]
    return np.column_stack([-r[:, 1], r[:, 0], np.zeros(len(r))])


@builder(Meshing(8.0), Solid(150.0, 0.45), Density(), Gravity.Z, Damping(1.0, 0.05))
def stiff_flop(
    p,
    *,
    fibre_stiffness: float = 3000.0,
    skin_stiffness: float = 15.0,
    max_pressure_bar: float = 0.6,
    effector_at: Literal["tip", "middle"] = "tip",
) -> Model:
    """The Stiff-Flop standing along +z on its fixed base (z = 0), 100 mm long, 30 mm across.

    Actuators: 'pressure_{i}_{j}', the pressure of chamber pair j (azimuth 120 j degrees from
    +x) of module i (0: base), CavityActuator in force mode, 0 to `max_pressure_bar` bar (kPa
    inside). Effector: on the axis at the tip or between the modules (`effector_at`).

    Args:
        young_modulus, poisson_ratio: the silicone (kPa; Ecoflex-like 150 kPa).
        fibre_stiffness: the hoop threads' stretch stiffness E t on every chamber wall (kPa mm;
            0: no reinforcement).
        skin_stiffness: the wall membrane's isotropic stretch stiffness under the fibres.
    """
    mesh = p.mesh_or(shapes.stiff_flop)
    if not (math.isfinite(max_pressure_bar) and max_pressure_bar > 0):
        raise ModelError(f"max_pressure_bar must be > 0, got {max_pressure_bar!r}")
    if not (math.isfinite(fibre_stiffness) and fibre_stiffness >= 0):
        raise ModelError(f"fibre_stiffness must be >= 0, got {fibre_stiffness!r}")
    if effector_at not in ("tip", "middle"):
        raise ModelError(f"effector_at must be 'tip' or 'middle', got {effector_at!r}")
    bound = max_pressure_bar * KPA_PER_BAR
    pairs = sorted(k[len("cavity_") :] for k in mesh.surfaces if k.startswith("cavity_"))
    membranes = []
    if fibre_stiffness > 0:
        for pair in pairs:
            triangles = mesh.surfaces[f"cavity_{pair}"]
            axes = landmark(mesh, f"chamber_axes_{pair}", np.zeros((2, 2)))
            membranes.append(
                Membrane(
                    mesh.points,
                    triangles,
                    stretch_stiffness=skin_stiffness,
                    poisson_ratio=0.3,
                    fibres=_hoop_fibres(mesh.points, triangles, axes),
                    fibre_stiffness=fibre_stiffness,
                )
            )
    body = p.tet_body(
        mesh, fixed_nodes=fixed_by_box(mesh, mesh.landmarks["fixed_box"]), membranes=membranes
    )
    chambers = [
        cavity(mesh, body, f"cavity_{pair}", name=f"pressure_{pair}", max_pressure=bound)
        for pair in pairs
    ]
    eff = effector(mesh, body, mesh.landmarks[f"effector_{effector_at}"])
    return Model(body, actuators=chambers, effectors=[eff], name="stiff_flop")


def demo_actuation(t: float) -> np.ndarray:
    """Pressure (kPa) in pair 0 of both modules to 0.4 bar over a second, then pair 1 of the
    tip module, then release."""
    p = np.zeros(6)
    p[0] = p[3] = 40.0 * min(t, 1.0)
    p[4] = 40.0 * min(max(t - 1.0, 0.0), 1.0)
    if t > 2.0:
        p *= max(0.0, 3.0 - t)
    return p


def circle(n: int = 20, *, radius: float = 8.0, height: float = 100.5) -> np.ndarray:
    """Goals on a circle round the axis (inverse control): the chambers lengthen the side
    they bend away from, so a bent tip rises (measured ~100.5 mm at 9 mm off the axis, from
    99.7 at rest); goals 3 mm lower were out of reach by ~3.5 mm."""
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(n, height)])


def spiral(
    n: int = 40, *, radius: float = 1.8, turns: float = 2.0, height: float = 99.71
) -> np.ndarray:
    """Goals on a spiral round the axis, out from it to `radius` in `turns` turns, in the
    plane z = `height` (thesis §5.1.5, 40 goals): 0.29 mm below the unloaded tip, where the
    tip sagging under gravity moves when each chamber pair's volume grows by 0-100 mm^3 (its
    reach there is 2-3 mm off the axis, least between the pairs)."""
    t = np.linspace(0.0, 1.0, n)
    a = 2.0 * math.pi * turns * t
    r = radius * (0.1 + 0.9 * t)
    return np.column_stack([r * np.cos(a), r * np.sin(a), np.full(n, height)])
