"""Selector accuracy on CartStemContact states labelled by Eq. 4.7 (thesis §4.2.3 L855:
> 99.7 % on 50000 test samples, 20 % of the labelled data for validation).

    python experiments/graph/selector.py [--train 50000] [--test 50000] [--epochs 30]
        [--batch-size 64] [--schedule constant|cosine] [--lr 1e-3]

The states are drawn, not simulated: x_cart uniform on the cart's range (±0.45 beam lengths),
obstacles at random positions and sizes around the scene's (x_left ∈ [−0.35, −0.15],
x_right ∈ [0.15, 0.35], l_x ∈ [0.05, 0.15], l_z ∈ [0.1, 0.3]; the thesis randomises the contact
positions too), x_tip = x_cart + N(0, 0.1), x_goal uniform on ±0.35. The authors label 500000
random environment steps instead (D.2). Writes experiments/results/graph/selector.json and the
trained network, selector.pt (kept: 0.6 MB), beside it.

    python experiments/graph/selector.py --evaluate experiments/results/graph/selector.pt \
        --out OUT

re-evaluates a kept network on the test states it was tested on (the same draw: the file
records how many training states came first), without training, into OUT/selector.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from pliant import configure_threads
from pliant.learn.graph import Selector, cartstem_partition


def states(n: int, rng: np.random.Generator) -> np.ndarray:
    s = np.empty((n, 7))
    s[:, 0] = rng.uniform(-0.45, 0.45, n)
    s[:, 1] = s[:, 0] + rng.normal(0.0, 0.1, n)
    s[:, 2] = rng.uniform(-0.35, -0.15, n)
    s[:, 3] = rng.uniform(0.15, 0.35, n)
    s[:, 4] = rng.uniform(0.05, 0.15, n)
    s[:, 5] = rng.uniform(0.1, 0.3, n)
    s[:, 6] = rng.uniform(-0.35, 0.35, n)
    return s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--train", type=int, default=50_000)
    parser.add_argument("--test", type=int, default=50_000)
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--hidden", type=int, default=256)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--batch-size", type=int, default=64)
    parser.add_argument("--schedule", choices=["constant", "cosine"], default="constant")
    parser.add_argument("--out", type=Path, default=Path("experiments/results/graph"))
    parser.add_argument("--evaluate", type=Path, help="a kept network: test it, no training")
    args = parser.parse_args()
    configure_threads(torch_threads=1)
    torch.manual_seed(0)
    label = lambda s: np.array([cartstem_partition(x) for x in s])  # noqa: E731
    args.out.mkdir(parents=True, exist_ok=True)
    if args.evaluate is not None:
        evaluate(args.evaluate, args.test, args.out, label)
        return
    rng = np.random.default_rng(0)
    data, test = states(args.train, rng), states(args.test, rng)
    selector = Selector(7, 3, d=64, hidden=args.hidden)
    start = time.perf_counter()
    history = selector.fit(
        data, label(data), epochs=args.epochs, lr=args.lr, batch_size=args.batch_size,
        schedule=args.schedule, seed=0,
    )  # fmt: skip
    result = {
        "train_states": args.train,
        "validation_fraction": 0.2,
        "epochs": args.epochs,
        "hidden": args.hidden,
        "lr": args.lr,
        "batch_size": args.batch_size,
        "schedule": args.schedule,
        "best_validation_accuracy": max(history["val_accuracy"]),
        "test_states": args.test,
        "test_accuracy": selector.accuracy(test, label(test)),
        "class_counts_test": np.bincount(label(test), minlength=3).tolist(),
        "train_seconds": time.perf_counter() - start,
        "thesis": "> 99.7 % on 50000 test samples",
    }
    kept = {"network": selector.state_dict(), "hidden": args.hidden, "train_states": args.train}
    torch.save(kept, args.out / "selector.pt")
    (args.out / "selector.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


def evaluate(path: Path, n_test: int, out: Path, label) -> None:
    """The kept network of `path` on the test states of its training run (drawn after its
    training states, from the same seed), written into out/selector.json."""
    kept = torch.load(path, weights_only=True)
    selector = Selector(7, 3, d=64, hidden=kept["hidden"])
    selector.load_state_dict(kept["network"])
    rng = np.random.default_rng(0)
    states(kept["train_states"], rng)  # the training states, drawn first
    test = states(n_test, rng)
    result = {
        "evaluated": str(path),
        "train_states": kept["train_states"],
        "test_states": n_test,
        "test_accuracy": selector.accuracy(test, label(test)),
        "class_counts_test": np.bincount(label(test), minlength=3).tolist(),
    }
    (out / "selector.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
