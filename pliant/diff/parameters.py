"""Setting a model's differentiable material parameters in place (calibration loops)."""

from __future__ import annotations

import dataclasses

import numpy as np

from pliant.errors import MaterialError, ModelError
from pliant.model import Model


def element_young_poisson(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """Young's modulus and Poisson's ratio of every element (m,), from its Lamé parameters."""
    mu, lam = model.body.mu, model.body.lam
    return mu * (3.0 * lam + 2.0 * mu) / (lam + mu), lam / (2.0 * (lam + mu))


def region_sum(values: np.ndarray, regions: np.ndarray | None) -> float | np.ndarray:
    """Per-element values summed over the body (float) or per region (array)."""
    if regions is None:
        return float(np.sum(values))
    return np.bincount(regions, weights=values)


def check_regions(model: Model, regions) -> np.ndarray | None:
    if regions is None:
        return None
    out = np.asarray(regions)
    if out.shape != (model.body.n_elements,) or out.dtype.kind not in "iu" or out.min() < 0:
        raise ModelError(
            f"regions must give a region index >= 0 to each of the {model.body.n_elements}"
            f" elements, got an array of shape {out.shape} and dtype {out.dtype}"
        )
    return out


def set_parameters(
    model: Model,
    *,
    young_modulus: float | np.ndarray | None = None,
    poisson_ratio: float | np.ndarray | None = None,
    rayleigh_mass: float | None = None,
    rayleigh_stiffness: float | None = None,
    regions: np.ndarray | None = None,
) -> None:
    """Set E and nu (one value, or one per region of `regions`, an element -> region index
    array) and the Rayleigh coefficients of the model's body, in place; the body's revision
    goes up so that no solver reuses a linearisation made before.

    Raises MaterialError for a value out of range, ModelError for a wrong shape."""
    body = model.body
    regions = check_regions(model, regions)
    e, nu = element_young_poisson(model)
    for name, value, target in (
        ("young_modulus", young_modulus, e),
        ("poisson_ratio", poisson_ratio, nu),
    ):
        if value is None:
            continue
        values = np.atleast_1d(np.asarray(value, dtype=float))
        if regions is None:
            if values.size != 1:
                raise ModelError(f"{name}: one value without regions, got {values.size}")
            target[:] = values[0]
        else:
            if values.size != regions.max() + 1:
                raise ModelError(f"{name}: one value per region ({regions.max() + 1})")
            target[:] = values[regions]
    if np.any(~np.isfinite(e)) or np.any(e <= 0) or np.any(nu < 0) or np.any(nu >= 0.5):
        raise MaterialError(f"E must be > 0 and nu in [0, 0.5), got E {e.min()}.., nu {nu.max()}")
    body.mu[:] = e / (2.0 * (1.0 + nu))
    body.lam[:] = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    if np.all(e == e[0]) and np.all(nu == nu[0]):
        body.material = dataclasses.replace(
            body.material, young_modulus=float(e[0]), poisson_ratio=float(nu[0])
        )
    for name, value in (
        ("rayleigh_mass", rayleigh_mass),
        ("rayleigh_stiffness", rayleigh_stiffness),
    ):
        if value is not None:
            if not np.isfinite(value) or value < 0:
                raise MaterialError(f"{name} must be finite and >= 0, got {value!r}")
            body.uniform_rayleigh(f"set_parameters({name}=...)")
            setattr(body, name, float(value))
    body.changed()
