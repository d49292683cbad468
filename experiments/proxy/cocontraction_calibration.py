"""The Trunk proxy's axial commands fitted on the FEM (docs/proxy.md, "Cables pulled
together"): the FEM Trunk's opposite cables pulled together shorten it without bending it (all
eight to the environment's 14 / 8 mm: its tip 12 mm nearer the base), which the proxy's
cables -> bendings map cancels. ``trunk_proxy(lower_cocontraction=, upper_cocontraction=)``
gives each beam an axial command (the common pull of its cables,
``trunk_commands(axial=True)``); this fits the two shortenings, the rest of the proxy held at
the contraction calibration's parameters.

Reference: the FEM Trunk (base fixed, no cube) through the calibration's phases
(TRUNK_PHASES) and then TRUNK_COCONTRACTION_PHASES (cables pulled together, 0.3 s each),
every 5th position optimised, the others validated (the calibration's split); the
TRUNK_OTHER_PHASES trajectory validates on other actions.

    python experiments/proxy/cocontraction_calibration.py [--trials 30]

Writes experiments/proxy/cocontraction/trunk-cocontraction_calibration.json: a calibration
report ("parameters": the contraction calibration's and the two fitted; proxy/rl.py
--parameters reads it), with the errors of the same proxy without axial commands.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from pliant.proxy.calibrate import calibrate, mean_distance
from pliant.proxy.references import (
    TRUNK_COCONTRACTION_PHASES,
    TRUNK_OTHER_PHASES,
    TRUNK_PHASES,
    Reference,
    setup,
)

BASE = Path("experiments/proxy/contraction/trunk_calibration.json")
OUT = Path("experiments/proxy/cocontraction")
SPACE = {"lower_cocontraction": (0.0, 0.8), "upper_cocontraction": (0.0, 0.8)}
#: what stands for "no axial command" where the reference has them: a shortening nothing sees
NONE = {"lower_cocontraction": 1e-9, "upper_cocontraction": 1e-9}


def reference(path: Path, phases) -> Reference:
    from pliant.proxy.references import trunk_reference

    if path.exists():
        return Reference.load(path)
    data = trunk_reference(phases=phases, axial=True)
    data.save(path)
    return data


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--trials", type=int, default=30)
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    fitted = reference(
        OUT / "trunk-cocontraction_reference.npz", TRUNK_PHASES + TRUNK_COCONTRACTION_PHASES
    )
    other = reference(OUT / "trunk-other_reference.npz", TRUNK_OTHER_PHASES)
    base = json.loads(BASE.read_text())["parameters"]
    trunk = setup("trunk")
    result = calibrate(
        trunk.simulate(fitted),
        fitted.points,
        SPACE,
        trials=args.trials,
        fixed=base,
        storage=f"sqlite:///{OUT / 'cocontraction.db'}",
        study_name="trunk-cocontraction",
    )
    steps = int(round(0.3 / fitted.dt)) * len(TRUNK_PHASES)  # where the common pulls begin

    def errors(parameters: dict) -> dict:
        points = trunk.simulate(fitted)(parameters)
        gap = np.linalg.norm(points - fitted.points, axis=-1)
        return {
            "all_positions_mm": float(gap.mean()),
            "calibration_phases_mm": float(gap[:steps].mean()),
            "cables_together_mm": float(gap[steps:].mean()),
            "other_actions_mm": mean_distance(other.points, trunk.simulate(other)(parameters)),
        }

    report = {
        "robot": "trunk-cocontraction",
        "command": "python experiments/proxy/cocontraction_calibration.py "
        + " ".join(sys.argv[1:]),
        "trials": result.trials,
        "optimisation_error_mm": result.optimisation_error,
        "validation_error_mm": result.validation_error,
        "parameters": {**base, **result.parameters},
        "fitted": {k: result.parameters[k] for k in SPACE},
        "space": SPACE,
        "base_calibration": str(BASE),
        "contact": "nodes",
        "reference": str(OUT / "trunk-cocontraction_reference.npz"),
        "without_axial_commands": errors({**base, **NONE}),
        "with_axial_commands": errors(result.parameters),
    }
    (OUT / "trunk-cocontraction_calibration.json").write_text(json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
