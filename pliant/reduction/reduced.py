"""A reduced model: basis, reduced integration domain and how they were made, saved together.

The file (.npz) holds the modes, the rest shape, the selected elements and weights, and JSON
metadata: the mesh's fingerprint (loading it for another mesh raises ReductionError), the
robot, the tolerances, the training errors and the sizes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pliant.errors import ReductionError
from pliant.files import atomic_path, read_checked
from pliant.model import Model
from pliant.reduction.basis import ReducedBasis, mesh_fingerprint
from pliant.reduction.ecsw import IntegrationDomain, Selection
from pliant.reduction.solver import ReducedImplicitEuler


@dataclass(frozen=True)
class ReducedModel:
    """Basis, integration domain and metadata (tolerances, errors, sizes)."""

    basis: ReducedBasis
    domain: IntegrationDomain
    metadata: dict = field(default_factory=dict)

    def solver(self, model: Model, dt: float = 0.01, *, tangent: str = "lagged"):
        """The :class:`ReducedImplicitEuler` of `model` (checked against the basis' mesh)."""
        return ReducedImplicitEuler(model, self.basis, self.domain, dt, tangent=tangent)

    def save(self, path: str | Path) -> Path:
        """Write the reduced model to `path` (.npz) atomically."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {
            "rest": self.basis.rest,
            "modes": self.basis.modes,
            "singular_values": self.basis.singular_values,
            "tet_elements": self.domain.tets.elements,
            "tet_weights": self.domain.tets.weights,
        }
        for k, s in enumerate(self.domain.membranes):
            arrays[f"membrane{k}_elements"] = s.elements
            arrays[f"membrane{k}_weights"] = s.weights
        header = {
            **self.metadata,
            "fingerprint": self.basis.fingerprint,
            "n_translation": self.basis.n_translation,
            "n_membranes": len(self.domain.membranes),
            "errors": [self.domain.tets.error, *(s.error for s in self.domain.membranes)],
        }
        with atomic_path(path if path.suffix == ".npz" else path.with_suffix(".npz")) as tmp:
            np.savez(tmp, metadata=np.array(json.dumps(header)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path, model: Model | None = None) -> ReducedModel:
        """Read a reduced model; with `model`, ReductionError unless it is of that mesh."""
        path = Path(path)
        if not path.is_file():
            raise ReductionError(f"cannot read a reduced model from {path}: no such file")
        # A damaged file (empty, cut short, overwritten) fails the members' CRC-32 or the
        # archive's structure here, named, rather than later in the solver.
        return read_checked(path, lambda p: cls._read(p, model), "a reduced model", ReductionError)

    @classmethod
    def _read(cls, path: Path, model: Model | None) -> ReducedModel:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["metadata"]))
            errors = meta.pop("errors")
            basis = ReducedBasis(
                data["rest"],
                data["modes"],
                int(meta.pop("n_translation")),
                data["singular_values"],
                meta.pop("fingerprint"),
            )
            membranes = tuple(
                Selection(
                    data[f"membrane{k}_elements"], data[f"membrane{k}_weights"], errors[k + 1]
                )
                for k in range(int(meta.pop("n_membranes")))
            )
            domain = IntegrationDomain(
                Selection(data["tet_elements"], data["tet_weights"], errors[0]), membranes
            )
        if model is not None and basis.fingerprint != mesh_fingerprint(model.body):
            raise ReductionError(
                f"{path} is a reduced model of another mesh than {model.name}'s (fingerprint"
                f" {basis.fingerprint} != {mesh_fingerprint(model.body)}): reduce this model"
                " with `pliant reduce`"
            )
        return cls(basis, domain, meta)
