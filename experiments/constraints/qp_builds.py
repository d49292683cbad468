"""ProxQP's builds on Pliant's QPs: time and reproducibility (docs/reliability.md, guarantee 8).

proxsuite loads its most vectorised build by itself (AVX-512 here); Pliant loads the baseline
x86-64 build (pliant/_proxsuite.py). For each build, in a fresh interpreter
(PLIANT_PROXSUITE_SIMD=1 gives proxsuite its own choice):

* time: random dense QPs with box constraints (n unknowns, n/3 equalities, n inequalities; the
  Hessian M M^T / n + 1e-3 I), solved by ``pliant.constraints.inverse._solve_qp`` as every
  inverse QP is, median of `--repeats` solves after one warm-up, for n = 20, 60, 150, 400;
* reproducibility: the same QP (n = 20 and 60) solved 32 times from copies of its data placed
  at every 8-byte offset from a 64-byte boundary, with other allocations between the solves,
  and the distinct solutions counted (bit patterns). One means the answer does not depend on
  where the data lie.

    python experiments/constraints/qp_builds.py [--repeats 7]

Writes experiments/results/qp_builds.json. Timings on a shared machine: compare the two builds
of one run, not runs of different days.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

OUT = Path("experiments/results/qp_builds.json")
SIZES = (20, 60, 150, 400)

MEASURE = """
import hashlib, json, time
import numpy as np
from pliant._proxsuite import BUILD
from pliant.constraints.inverse import _solve_qp

def problem(n, seed):
    rng = np.random.default_rng(seed)
    m = rng.standard_normal((n, n))
    hess = m @ m.T / n + 1e-3 * np.eye(n)
    eq = rng.standard_normal((n // 3, n))
    ineq = rng.standard_normal((n, n))
    return [hess, rng.standard_normal(n), eq, eq @ rng.standard_normal(n) * 0.1, ineq,
            -np.ones(n), np.ones(n), -3 * np.ones(n), 3 * np.ones(n)]

def shifted(x, offset):
    buf = np.empty(x.nbytes + 128, dtype=np.uint8)
    start = (-buf.ctypes.data) % 64 + offset
    out = buf[start:start + x.nbytes].view(x.dtype).reshape(x.shape)
    out[...] = x
    return out

out = {"build": BUILD, "median_ms": {}, "distinct_solutions": {}}
for n in SIZES:
    data = problem(n, n)
    _solve_qp(*data, 1e-9, 10000)
    times = []
    for _ in range(REPEATS):
        t = time.perf_counter()
        _solve_qp(*data, 1e-9, 10000)
        times.append(time.perf_counter() - t)
    out["median_ms"][str(n)] = 1e3 * float(np.median(times))
rng = np.random.default_rng(0)
for n in (20, 60):
    data, seen, keep = problem(n, 7 * n), set(), []
    for k in range(32):
        keep.append(np.empty(int(rng.integers(1, 5000))))
        x = _solve_qp(*[shifted(a, 8 * (k % 8)) for a in data], 1e-9, 10000).x
        seen.add(hashlib.sha256(x.tobytes()).hexdigest())
    out["distinct_solutions"][str(n)] = len(seen)
print(json.dumps(out))
"""


def measure(simd: bool, repeats: int) -> dict:
    code = MEASURE.replace("SIZES", repr(SIZES)).replace("REPEATS", str(repeats))
    env = {**os.environ, "PLIANT_PROXSUITE_SIMD": "1" if simd else "0"}
    output = subprocess.check_output(
        [sys.executable, "-c", textwrap.dedent(code)], env=env, text=True
    )
    return json.loads(output.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    rows = [measure(simd, args.repeats) for simd in (False, True)]
    for row in rows:
        print(row)
    report = {
        "command": "python experiments/constraints/qp_builds.py " + " ".join(sys.argv[1:]),
        "sizes": list(SIZES),
        "builds": rows,
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
