"""Calibrate the Multigait proxy again on the states its learned policy visits (issue 18: the
transfer of a policy learnt on the proxy loses ground on the FEM where the proxy gains on
actions the calibration did not hold).

    python experiments/proxy/iterate_calibration.py \
        --policy experiments/results/proxy/rl_multigait_travel \
        --out experiments/proxy/iterate

Writes OUT/multigait-iterate_reference.npz: the FEM Multigait under the joint calibration's
actions (hand gait, then the 16 patterns) followed by the policy's greedy episode on the proxy
(``learned_actions`` of its report.json), one trajectory of 0.6 s actions. Then, with the
proxy calibration's own command (a study resumed from OUT):

    pliant proxy calibrate multigait-joint \
        --reference experiments/proxy/iterate/multigait-iterate_reference.npz \
        --travel-weight 3 --friction 0.3,1.5 --trials 150 \
        --start experiments/proxy/travel/multigait-joint_calibration.json \
        --out experiments/proxy/iterate
    python experiments/proxy/rl.py multigait \
        --parameters experiments/proxy/iterate/multigait-joint_calibration.json --tag _iterate
    pliant proxy transfer multigait --policy experiments/results/proxy/rl_multigait_iterate \
        --steps 8 --feedforward 1 --out experiments/results/proxy/rl_multigait_iterate/feedforward
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from pliant.proxy.references import (
    MULTIGAIT_HAND_GAIT,
    MULTIGAIT_PATTERNS,
    multigait_reference,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--policy", type=Path, required=True, help="a proxy/rl.py result folder")
    parser.add_argument("--out", type=Path, default=Path("experiments/proxy/iterate"))
    args = parser.parse_args()
    report = json.loads((args.policy / "report.json").read_text())
    learned = [int(a) for a in report["evaluation"]["learned_actions"]]
    actions = MULTIGAIT_HAND_GAIT + MULTIGAIT_PATTERNS + tuple(learned)
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    reference = multigait_reference(actions=actions)
    path = args.out / "multigait-iterate_reference.npz"
    reference.save(path)
    meta = {
        "command": (
            "python experiments/proxy/iterate_calibration.py"
            f" --policy {args.policy} --out {args.out}"
        ),
        "policy": str(args.policy),
        "learned_actions": learned,
        "actions": list(actions),
        "steps": len(reference.commands),
        "fem_seconds": time.perf_counter() - start,
        "reference": str(path),
    }
    (args.out / "iterate.json").write_text(json.dumps(meta, indent=1))
    print(json.dumps(meta))


if __name__ == "__main__":
    main()
