"""CHOLMOD with the symbolic analysis kept across numeric refactorisations.

The tangent of a tetrahedral body keeps its sparsity pattern for the whole simulation, so the
fill-reducing ordering and the supernodal structure (``cholmod_analyze``) are computed once and
every refactorisation is numeric only (``cholmod_factorize``). ``cholespy`` redoes the analysis at
every factorisation and scikit-sparse does not install from a wheel, so this module binds the
CHOLMOD library that cvxopt's wheels ship, through ctypes, to the five calls it needs.

Measured on this 2-core machine (A = M + h^2 K of the SoftRobots Diamond, 4710 DoFs, and of the
Trunk, 1869 DoFs): cholespy 21.6 / 4.5 ms per factorisation; here analysis 3.1 / 1.5 ms once,
then 2.3 / 0.8 ms per numeric refactorisation; solves with 9 right-hand sides 0.95 / 0.33 ms
(cholespy 0.86 / 0.28 ms).

Only the head of CHOLMOD's structs is used: ``cholmod_sparse`` and ``cholmod_dense`` (stable
since CHOLMOD 1.0), ``n`` and ``minor`` of ``cholmod_factor``, and the ``print`` option of
``cholmod_common``, written only after checking that the fields before it hold CHOLMOD's
documented defaults.
"""

from __future__ import annotations

import ctypes
import glob
import os
import weakref
from dataclasses import dataclass
from functools import cache

import numpy as np

from pliant.errors import SolverError

_REAL, _DOUBLE, _INT = 1, 0, 0  # CHOLMOD_REAL, CHOLMOD_DOUBLE, CHOLMOD_INT
_SOLVE_A = 0  # CHOLMOD_A: solve A x = b
_SIMPLICIAL, _SUPERNODAL = 0, 2  # CHOLMOD_SIMPLICIAL, CHOLMOD_SUPERNODAL
_COMMON_BYTES = 1 << 16
_FUNCTIONS = (
    "start",
    "finish",
    "analyze",
    "factorize",
    "solve2",
    "free_factor",
    "free_dense",
)  # sizeof(cholmod_common) is a few kB in every CHOLMOD release


class _Sparse(ctypes.Structure):
    _fields_ = [
        ("nrow", ctypes.c_size_t),
        ("ncol", ctypes.c_size_t),
        ("nzmax", ctypes.c_size_t),
        ("p", ctypes.c_void_p),
        ("i", ctypes.c_void_p),
        ("nz", ctypes.c_void_p),
        ("x", ctypes.c_void_p),
        ("z", ctypes.c_void_p),
        ("stype", ctypes.c_int),
        ("itype", ctypes.c_int),
        ("xtype", ctypes.c_int),
        ("dtype", ctypes.c_int),
        ("sorted", ctypes.c_int),
        ("packed", ctypes.c_int),
    ]


class _Dense(ctypes.Structure):
    _fields_ = [
        ("nrow", ctypes.c_size_t),
        ("ncol", ctypes.c_size_t),
        ("nzmax", ctypes.c_size_t),
        ("d", ctypes.c_size_t),
        ("x", ctypes.c_void_p),
        ("z", ctypes.c_void_p),
        ("xtype", ctypes.c_int),
        ("dtype", ctypes.c_int),
    ]


class _FactorHead(ctypes.Structure):
    _fields_ = [("n", ctypes.c_size_t), ("minor", ctypes.c_size_t)]


class _CommonHead(ctypes.Structure):
    """The first fields of cholmod_common, up to ``print``."""

    _fields_ = [
        ("dbound", ctypes.c_double),
        ("grow0", ctypes.c_double),
        ("grow1", ctypes.c_double),
        ("grow2", ctypes.c_size_t),
        ("maxrank", ctypes.c_size_t),
        ("supernodal_switch", ctypes.c_double),
        ("supernodal", ctypes.c_int),
        ("final_asis", ctypes.c_int),
        ("final_super", ctypes.c_int),
        ("final_ll", ctypes.c_int),
        ("final_pack", ctypes.c_int),
        ("final_monotonic", ctypes.c_int),
        ("final_resymbol", ctypes.c_int),
        ("zrelax", ctypes.c_double * 3),
        ("nrelax", ctypes.c_size_t * 3),
        ("prefer_zomplex", ctypes.c_int),
        ("prefer_upper", ctypes.c_int),
        ("quick_return_if_not_posdef", ctypes.c_int),
        ("prefer_binary", ctypes.c_int),
        ("print", ctypes.c_int),
    ]

    def has_defaults(self) -> bool:
        return (
            self.grow0 == 1.2
            and self.grow1 == 1.2
            and self.grow2 == 5
            and self.maxrank == 8
            and self.supernodal_switch == 40.0
            and self.final_asis == 1
            and tuple(self.zrelax) == (0.8, 0.1, 0.05)
            and tuple(self.nrelax) == (4, 16, 48)
        )


@dataclass(frozen=True)
class _Library:
    """A CHOLMOD build and the factorisation that is fastest with the BLAS it links to."""

    lib: ctypes.CDLL
    supernodal: int
    final_ll: int


def _library_candidates() -> list[tuple[str, int, int]]:
    """cvxopt's CHOLMOD (ATLAS BLAS: supernodal), then the CHOLMOD linked into cholespy's
    extension (reference BLAS: simplicial LL^T is faster there), as (path, supernodal, final_ll).
    """
    found = []
    try:
        import cvxopt
        import cvxopt.cholmod  # noqa: F401  (loads the SuiteSparse libraries CHOLMOD links to)

        root = os.path.dirname(cvxopt.__file__)
        for pattern in (
            os.path.join(os.path.dirname(root), "cvxopt.libs", "libcholmod*.so*"),
            os.path.join(root, ".dylibs", "libcholmod*.dylib"),
        ):
            found += [(path, _SUPERNODAL, 0) for path in sorted(glob.glob(pattern))]
    except ImportError:
        pass
    try:
        from cholespy import _cholespy_core

        found.append((_cholespy_core.__file__, _SIMPLICIAL, 1))
    except ImportError:
        pass
    return found


@cache
def _library() -> _Library | None:
    for path, supernodal, final_ll in _library_candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        if not all(hasattr(lib, f"cholmod_{name}") for name in _FUNCTIONS):
            continue
        p, vp = ctypes.POINTER, ctypes.c_void_p
        lib.cholmod_start.argtypes = [vp]
        lib.cholmod_finish.argtypes = [vp]
        lib.cholmod_analyze.argtypes = [p(_Sparse), vp]
        lib.cholmod_analyze.restype = vp
        lib.cholmod_factorize.argtypes = [p(_Sparse), vp, vp]
        lib.cholmod_solve2.argtypes = [
            ctypes.c_int,
            vp,
            p(_Dense),
            vp,
            p(p(_Dense)),
            vp,
            p(p(_Dense)),
            p(p(_Dense)),
            vp,
        ]
        lib.cholmod_free_factor.argtypes = [p(vp), vp]
        lib.cholmod_free_dense.argtypes = [p(p(_Dense)), vp]
        common = ctypes.create_string_buffer(_COMMON_BYTES)
        lib.cholmod_start(common)
        recognised = _CommonHead.from_buffer(common).has_defaults()
        lib.cholmod_finish(common)
        if recognised:
            return _Library(lib, supernodal, final_ll)
    return None


def available() -> bool:
    """Whether a CHOLMOD library was found (cvxopt installed)."""
    return _library() is not None


def _release(lib, common, factor, workspaces) -> None:
    for ws in workspaces:
        if ws:
            lib.cholmod_free_dense(ctypes.byref(ws), common)
    if factor.value:
        lib.cholmod_free_factor(ctypes.byref(factor), common)
    lib.cholmod_finish(common)


class CholmodCholesky:
    """Supernodal Cholesky of SPD matrices sharing one symmetric sparsity pattern.

    Args:
        indptr, indices: compressed pattern of the *full* symmetric matrix (CSR or CSC, which
            are the same for a symmetric pattern), indices sorted within each row.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray) -> None:
        library = _library()
        if library is None:
            raise SolverError("no usable CHOLMOD library was found (install cvxopt)")
        self._lib = lib = library.lib
        self.n = int(indptr.size - 1)
        if self.n == 0:
            raise SolverError("cannot factorise an empty system: every degree of freedom is fixed")
        self._indptr = np.ascontiguousarray(indptr, dtype=np.int32)
        self._indices = np.ascontiguousarray(indices, dtype=np.int32)
        self._data = np.zeros(self._indices.size)
        self._common = ctypes.create_string_buffer(_COMMON_BYTES)
        lib.cholmod_start(self._common)
        head = _CommonHead.from_buffer(self._common)
        head.print = 0  # errors are raised here, with context, rather than printed
        # An LL^T factorisation either way: LDL^T would not detect an indefinite matrix.
        head.supernodal = library.supernodal
        head.final_ll = library.final_ll
        # stype -1: symmetric, only the lower triangle is read (the pattern holds both).
        self._matrix = _Sparse(
            self.n,
            self.n,
            self._indices.size,
            self._indptr.ctypes.data,
            self._indices.ctypes.data,
            None,
            self._data.ctypes.data,
            None,
            -1,
            _INT,
            _REAL,
            _DOUBLE,
            1,
            1,
        )
        self._factor = ctypes.c_void_p(
            lib.cholmod_analyze(ctypes.byref(self._matrix), self._common)
        )
        p = ctypes.POINTER(_Dense)
        self._x, self._y, self._e = p(), p(), p()
        self._refs = tuple(ctypes.byref(w) for w in (self._x, self._y, self._e))
        # The solution's workspace, read as an array: (its address, columns, the array). CHOLMOD
        # keeps the workspace while the columns do not change, so the array is made once.
        self._solution: tuple[int, int, np.ndarray] | None = None
        self._finalizer = weakref.finalize(
            self, _release, lib, self._common, self._factor, (self._x, self._y, self._e)
        )
        self._matrix.x = None  # the analysis read the pattern only
        del self._data
        if not self._factor.value:
            raise SolverError("CHOLMOD's symbolic analysis failed (out of memory?)")
        self.factorised = False

    def factorize(self, data: np.ndarray) -> None:
        """Numeric factorisation of the matrix with values `data` on the pattern."""
        values = np.ascontiguousarray(data, dtype=np.float64)
        if values.shape != self._indices.shape:
            raise SolverError(f"expected {self._indices.size} values, got {values.shape}")
        if not np.all(np.isfinite(values)):
            raise SolverError("the system matrix has non-finite entries")
        self._matrix.x = values.ctypes.data
        self._lib.cholmod_factorize(ctypes.byref(self._matrix), self._factor, self._common)
        # The factor does not read A again: its values are not held (a kept factorisation,
        # pliant.diff's, would hold them for nothing), nor pointed to.
        self._matrix.x = None
        head = _FactorHead.from_address(self._factor.value)
        self.factorised = head.minor == head.n
        if not self.factorised:
            raise SolverError(
                f"Cholesky factorisation failed at column {head.minor} of {head.n}: the matrix is"
                " not positive definite: is the body held (fixed nodes) for a static solve, are"
                " elements inverted?"
            )

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x = A^-1 rhs for rhs (n,) or (n, k)."""
        if not self.factorised:
            raise SolverError("solve called before a successful factorisation")
        b = np.asfortranarray(rhs, dtype=np.float64)
        k = 1 if b.ndim == 1 else b.shape[1]
        dense = _Dense(self.n, k, self.n * k, self.n, b.ctypes.data, None, _REAL, _DOUBLE)
        x, y, e = self._refs
        ok = self._lib.cholmod_solve2(
            _SOLVE_A, self._factor, ctypes.byref(dense), None, x, None, y, e, self._common
        )
        if not ok:
            raise SolverError("CHOLMOD's solve failed")
        address = self._x.contents.x
        solution = self._solution
        if solution is None or solution[0] != address or solution[1] != k:
            buf = ctypes.cast(address, ctypes.POINTER(ctypes.c_double))
            solution = (address, k, np.ctypeslib.as_array(buf, shape=(k, self.n)))
            self._solution = solution
        if b.ndim == 1:
            return solution[2][0].copy()
        return solution[2].T.copy(order="F")
