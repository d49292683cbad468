"""The prior's weight chosen on a validation case, the learned policy's transfer reported held
out (issue 61's protocol for the Multigait transfer, thesis §4.1.3).

experiments/proxy/prior.py swept the inverse QP's prior weight (0, i.e. none, 0.1, 1, 3, 10,
30) on the thesis' test sequence and on the learned policy (``rl_multigait_surface``), and the
registry's headline (1.8 %) took weight 10, the best on that very policy. Here the weight is
the one whose transfer of the test sequence (the validation case: no policy, the thesis' own
actions) differs least from its proxy, and the policy's transfer at that weight is the figure
(the held-out case). Both read from the committed transfers that prior.py summarised, so
nothing is re-run; the old figure is written beside the new one.

    python experiments/proxy/prior_selection.py [--summary FILE] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

SUMMARY = Path("experiments/results/proxy/prior_summary.json")
OUT = Path("experiments/results/proxy/prior_selection.json")
VALIDATION = "sequence"  # the thesis' test sequence: rows "sequence, prior W"
HELD_OUT = "policy"  # the learned policy: rows "policy, prior W"


def by_weight(rows: list[dict], case: str) -> dict[float, dict]:
    """The rows ``"CASE, prior W"`` by weight (W = 0 for no prior)."""
    out = {}
    for row in rows:
        name, _, prior = row["case"].partition(", prior ")
        if name == case and prior:
            out[float(prior)] = row
    if not out:
        raise SystemExit(f"no rows '{case}, prior W' in the summary")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--summary", type=Path, default=SUMMARY)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    rows = json.loads(args.summary.read_text())["rows"]
    validation, held_out = by_weight(rows, VALIDATION), by_weight(rows, HELD_OUT)
    weights = sorted(set(validation) & set(held_out))
    chosen = min(weights, key=lambda w: validation[w]["relative_difference"])
    old = min(weights, key=lambda w: held_out[w]["relative_difference"])

    def entry(row: dict) -> dict:
        keep = ("relative_difference", "fem_travel_mm", "proxy_travel_mm", "folder")
        return {k: row[k] for k in keep}

    report = {
        "command": "python experiments/proxy/prior_selection.py " + " ".join(sys.argv[1:]),
        "summary": str(args.summary),
        "weights": weights,
        "validation_case": VALIDATION,
        "held_out_case": HELD_OUT,
        "validation": {f"{w:g}": entry(validation[w]) for w in weights},
        "chosen_weight": chosen,
        "held_out": entry(held_out[chosen]),
        "chosen_on_the_held_out_case": {"weight": old, **entry(held_out[old])},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    print(json.dumps({k: report[k] for k in ("chosen_weight", "held_out")}, indent=1))


if __name__ == "__main__":
    main()
