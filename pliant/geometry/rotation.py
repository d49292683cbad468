"""Rotations in 3D: the cross-product matrix, the exponential and logarithm maps of SO(3).

Rigid bodies store their orientation as a rotation matrix R (body -> world) and integrate a
world-frame angular velocity w with the exponential map, R_{n+1} = exp(h [w]x) R_n, which
keeps R exactly orthonormal (up to round-off) at any step size.
"""

from __future__ import annotations

import math

import numpy as np

from pliant.errors import ModelError


def skew(v: np.ndarray) -> np.ndarray:
    """The matrix [v]x with [v]x u = v x u."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def exp_map(rotation_vector: np.ndarray) -> np.ndarray:
    """exp([phi]x) by Rodrigues' formula: I + sin|phi| [u]x + (1 - cos|phi|) [u]x^2, u = phi/|phi|.

    Small angles use the Taylor series of sin(a)/a and (1 - cos a)/a^2 (no division by ~0).
    """
    phi = np.asarray(rotation_vector, dtype=float).reshape(3)
    angle = math.sqrt(float(phi @ phi))
    k = skew(phi)
    if angle < 1e-4:
        a2 = angle * angle
        s, c = 1.0 - a2 / 6.0 + a2 * a2 / 120.0, 0.5 - a2 / 24.0 + a2 * a2 / 720.0
    else:
        s, c = math.sin(angle) / angle, (1.0 - math.cos(angle)) / (angle * angle)
    return np.eye(3) + s * k + c * (k @ k)


def log_map(rotation: np.ndarray) -> np.ndarray:
    """The rotation vector phi with exp([phi]x) = R, |phi| <= pi."""
    r = np.asarray(rotation, dtype=float)
    cos_angle = min(1.0, max(-1.0, 0.5 * (np.trace(r) - 1.0)))
    angle = math.acos(cos_angle)
    axial = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-4:
        return axial * (1.0 + angle * angle / 6.0)  # axial = sin(a) u ~ (a - a^3/6) u
    if math.pi - angle > 1e-4:
        return axial * (angle / math.sin(angle))
    # Near pi the axial part vanishes: read the axis from R + I = 2 u u^T (+ O(pi - a)).
    b = r + np.eye(3)
    u = b[:, int(np.argmax(np.diag(b)))]
    u = u / np.linalg.norm(u)
    if axial @ u < 0.0:
        u = -u
    return angle * u


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """The rotation of `angle` radians about `axis` (any non-zero length)."""
    a = np.asarray(axis, dtype=float).reshape(3)
    norm = float(np.linalg.norm(a))
    if not (np.isfinite(norm) and norm > 0.0):
        raise ModelError(f"a rotation axis must be finite and non-zero, got {a.tolist()}")
    return exp_map(a * (float(angle) / norm))


def check_rotation(
    rotation: np.ndarray, *, name: str = "rotation", error: type[Exception] = ModelError
) -> np.ndarray:
    """R as a float (3, 3) array; raise `error` unless R^T R = I and det R = +1 (to 1e-9)."""
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise error(f"{name} must be a finite 3x3 matrix, got shape {r.shape}")
    deviation = float(np.abs(r.T @ r - np.eye(3)).max())
    if deviation > 1e-9 or np.linalg.det(r) < 0.0:
        raise error(
            f"{name} is not a proper rotation (|R^T R - I| = {deviation:.2e},"
            f" det = {np.linalg.det(r):.6f})"
        )
    return r.copy()
