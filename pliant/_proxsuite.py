"""ProxQP (proxsuite), loaded so that the same QP gives the same answer in every process.

proxsuite ships three builds of one solver and loads the most vectorised one the CPU runs
(AVX-512, else AVX2, else the baseline x86-64 build, SSE2). In the vectorised builds a dense
solve's reductions start where its data's memory alignment allows, and ProxQP's own workspace
moves from one process to the next, so the order of the additions, and the last bits of the
answer (1e-10 on Pliant's unit-scaled inverse QPs, within the solver's tolerance), change
between two runs of one program. A closed loop through contacts amplifies them: the transfer
loop's FEM Trunk, pushing its cube, ended 6 mm apart in three runs of one policy on one goal
(docs/proxy.md, "Evaluation noise"). The baseline build's 16-byte packets always find their
data aligned (every allocation is), and it gives one answer, bit for bit, in every process.

So Pliant loads the baseline build, unless proxsuite was imported before Pliant (it then keeps
the build loaded; :data:`BUILD` says which) or the environment sets PLIANT_PROXSUITE_SIMD=1.
The price is small where Pliant's QPs are, tens of unknowns
(experiments/constraints/qp_builds.py, random dense QPs with box constraints: 0.28 against
AVX-512's 0.37 ms for 20 unknowns, 3.2 against 2.7 ms for 60, 20 against 14 ms for 150, 286
against 150 ms for 400). proxsuite picks its build from
``proxsuite.instructionset``; a stand-in that reports no AVX is placed where its loader looks
for that module, for the time of the import only. If a later proxsuite loads its builds
otherwise, the stand-in is ignored and its choice stands; if it has no baseline build, it is
imported again as it would be (its vectorised build).
"""

from __future__ import annotations

import os
import sys
import types


def _load():
    if "proxsuite" not in sys.modules and os.environ.get("PLIANT_PROXSUITE_SIMD") != "1":
        baseline = types.ModuleType("proxsuite.instructionset")
        baseline.has_AVX512F = baseline.has_AVX2 = lambda: False
        sys.modules["proxsuite.instructionset"] = baseline
        try:
            import proxsuite
        finally:
            if sys.modules.get("proxsuite.instructionset") is baseline:
                del sys.modules["proxsuite.instructionset"]
            if getattr(sys.modules.get("proxsuite"), "instructionset", None) is baseline:
                del sys.modules["proxsuite"].instructionset
        try:
            return proxsuite.proxqp
        except AttributeError:  # a proxsuite without the baseline build: load it as it would
            for name in [m for m in sys.modules if m == "proxsuite" or m.startswith("proxsuite.")]:
                del sys.modules[name]
    import proxsuite

    return proxsuite.proxqp


proxqp = _load()
#: the proxsuite build in use: "proxsuite_pywrap" (the baseline, reproducible), or
#: "proxsuite_pywrap_avx2" / "proxsuite_pywrap_avx512"
BUILD = proxqp.__name__.split(".")[1]
