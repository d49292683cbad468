"""A trained network F made usable: the condensed problem of a robot from its actuator state.

The model answers the question the FEM answers in :meth:`StaticSolver.condense`: W and
delta_free at the configuration reached for (delta_a, delta_c) (Eq. 5.2), as a
:class:`~pliant.constraints.condensed.CondensedProblem` with the effectors at their training
goals (Eq. 5.6 moves them). It knows the constraint layout it learned and the region its data
cover, and says so when used outside them.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

import pliant
from pliant.condensed.dataset import CollectionPlan, Dataset, atomic_write
from pliant.condensed.layout import Layout
from pliant.condensed.networks import StandardisedMLP, numpy_activation
from pliant.condensed.sampling import Box
from pliant.constraints.condensed import CondensedProblem
from pliant.errors import LearnedModelError
from pliant.model import Model, State

FORMAT = "pliant-learned-condensed"
FORMAT_VERSION = 1


class OutOfBoundsWarning(UserWarning):
    """The learned model is evaluated outside the region its training data cover."""


def numpy_forward(network: StandardisedMLP) -> Callable[[np.ndarray], np.ndarray]:
    """network.predict for one sample as NumPy operations on a copy of the weights (float32),
    what a controller runs without torch, at a tenth of its call overhead at this size."""
    state = {k: v.detach().numpy().copy() for k, v in network.state_dict().items()}
    in_mean, in_scale = state["input_scale.mean"], state["input_scale.scale"]
    out_mean, out_scale = state["output_scale.mean"], state["output_scale.scale"]
    layers = [
        (m.weight.detach().numpy().T.copy(), m.bias.detach().numpy().copy())
        for m in network.net
        if isinstance(m, torch.nn.Linear)
    ]

    act, _ = numpy_activation(network.activation)

    def forward(x: np.ndarray) -> np.ndarray:
        h = ((x - in_mean) / in_scale).astype(np.float32)
        for k, (weight, bias) in enumerate(layers):
            h = h @ weight + bias
            if k < len(layers) - 1:
                h = act(h)
        return (h * out_scale + out_mean).astype(np.float64)

    return forward


class LearnedCondensedModel:
    """F with its layout, the data's region and the rest values of the training design.

    Args:
        network: F, raw (delta_a, delta_c, W0 triangle, delta0_free) -> (W triangle, delta_free).
        layout: the constraint rows it learned.
        plan: how its dataset was collected.
        input_box: region of (delta_a, delta_c) covered by the training data.
        rest: (W0 triangle, delta0_free) used when `predict` is not given others: those of the
            training design (datasets over designs give them with G or the FEM instead).
        training: what training reported (best epoch, losses), kept with the model.
    """

    def __init__(
        self,
        network: StandardisedMLP,
        layout: Layout,
        plan: CollectionPlan,
        input_box: Box,
        rest: tuple[np.ndarray, np.ndarray],
        training: dict | None = None,
    ) -> None:
        n_in = input_box.dim + layout.n_triangle + layout.n_rows
        n_out = layout.n_triangle + layout.n_rows
        if (network.n_inputs, network.n_outputs) != (n_in, n_out):
            raise LearnedModelError(
                f"the network maps {network.n_inputs} -> {network.n_outputs} values; the"
                f" layout needs {n_in} -> {n_out}"
            )
        check_finite(network, "F")
        self.network = network.eval()
        self.layout = layout
        self.plan = plan
        self.input_box = input_box
        self.rest = tuple(np.asarray(r, dtype=float) for r in rest)
        self.training = dict(training or {})
        self._triangle = layout.n_triangle
        self._forward = numpy_forward(network)
        # solver round-off at the box's faces is not extrapolation
        self._tolerance = 1e-9 * float(np.linalg.norm(input_box.high - input_box.low))

    @classmethod
    def from_dataset(
        cls, network: StandardisedMLP, dataset: Dataset, training: dict | None = None
    ) -> LearnedCondensedModel:
        train = dataset.train.converged_only()
        if len(train) == 0:
            raise LearnedModelError("the dataset has no converged training sample")
        active = np.hstack([train.delta_a, train.delta_c])
        return cls(
            network,
            dataset.layout,
            dataset.plan,
            Box(active.min(axis=0), active.max(axis=0)),
            (train.w0_triangle[0], train.free_distance0[0]),
            training,
        )

    def check(self, model: Model) -> None:
        """Raise LearnedModelError unless `model` has the constraint layout learned."""
        self.layout.check(model)

    def predict(
        self,
        delta_a: np.ndarray,
        delta_c: np.ndarray | None = None,
        rest: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> CondensedProblem:
        """W and delta_free (Eq. 5.2) at actuator (and contact) distances delta_a (delta_c),
        for the rest values `rest` (default: the training design's). Warns with
        OutOfBoundsWarning, giving the distance, outside the region of the training data."""
        try:
            active = np.concatenate(
                [np.ravel(delta_a), np.zeros(0) if delta_c is None else np.ravel(delta_c)]
            ).astype(float)
        except (TypeError, ValueError) as exc:
            raise LearnedModelError(f"the distances must be numbers: {exc}") from None
        if not np.all(np.isfinite(active)):
            raise LearnedModelError(f"the distances must be finite, got {active.tolist()}")
        if active.size != self.input_box.dim:
            raise LearnedModelError(
                f"the model takes {self.input_box.dim} actuator and contact distances, got"
                f" {active.size}"
            )
        distance = float(self.input_box.distance(active)[0])
        if distance > self._tolerance:
            warnings.warn(
                f"the learned condensed model is used {distance:.3g} outside the region of its"
                f" training data (delta = {np.round(active, 4).tolist()}, data in"
                f" [{self.input_box.low.tolist()}, {self.input_box.high.tolist()}]); its"
                " prediction is an extrapolation",
                OutOfBoundsWarning,
                stacklevel=2,
            )
        w0, free0 = self.rest if rest is None else rest
        y = self._forward(np.concatenate([active, w0, free0]))
        return self.layout.unpack(y[: self._triangle], y[self._triangle :])

    def problem(self, state: State) -> CondensedProblem:
        """The condensed problem at a simulated state, from its actuator distances (and, for a
        robot with held contact points, :class:`~pliant.condensed.contact.ContactRobot`, their
        distances, which follow the actuators')."""
        n_a = self.layout.counts["actuator"]
        return self.predict(state.displacement[:n_a], state.displacement[n_a:])

    def save(self, path: str | os.PathLike) -> Path:
        """Write the model atomically (LearnedModelError, nothing left behind, on failure)."""
        networks = {"network": self.network.config(), "state": self.network.state_dict()}
        rest = [r.tolist() for r in self.rest]
        return write_model_file(
            path, model_record(FORMAT, FORMAT_VERSION, self, networks, rest=rest)
        )

    @classmethod
    def load(cls, path: str | os.PathLike) -> LearnedCondensedModel:
        return load_model_file(path, FORMAT, FORMAT_VERSION, "learned condensed model", cls._of)

    @classmethod
    def _of(cls, data: dict) -> LearnedCondensedModel:
        network = StandardisedMLP.from_config(data["network"])
        network.load_state_dict(data["state"])
        return cls(
            network,
            Layout.from_dict(data["layout"]),
            CollectionPlan.from_dict(data["plan"]),
            Box(*data["input_box"]),
            tuple(np.array(r) for r in data["rest"]),
            data["training"],
        )


def check_finite(network: torch.nn.Module, name: str) -> None:
    """LearnedModelError if a weight of `network` is NaN or infinite (a diverged training):
    its predictions would be NaN, reported later as anything but their cause."""
    for key, value in network.state_dict().items():
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            raise LearnedModelError(
                f"{name} has non-finite weights ({key}): it comes from a diverged training;"
                " train it again (a lower learning rate, or check the dataset)"
            )


def write_model_file(path: str | os.PathLike, data: dict) -> Path:
    """torch.save `data` to `path` atomically; LearnedModelError if it cannot be written."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: torch.save(data, tmp))
    except (OSError, RuntimeError) as exc:  # torch reports a full disk as RuntimeError
        raise LearnedModelError(f"cannot write the model file {path}: {exc}") from exc
    return path


def model_record(fmt: str, version: int, model, networks: dict, **extra) -> dict:
    """What the file of a condensed `model` holds: its format and versions, `networks`, the
    model's layout, plan and input box, `extra`, and its training."""
    return {
        "format": fmt,
        "format_version": version,
        "software_version": pliant.__version__,
        **networks,
        "layout": model.layout.to_dict(),
        "plan": model.plan.to_dict(),
        "input_box": [model.input_box.low.tolist(), model.input_box.high.tolist()],
        **extra,
        "training": model.training,
    }


def load_model_file(path: str | os.PathLike, fmt: str, version: int, kind: str, build):
    """`build(data)` of the dictionary that :func:`read_model_file` reads; LearnedModelError
    where it lacks an entry or holds an inconsistent one."""
    path = Path(path)
    data = read_model_file(path, fmt, version, kind)
    try:
        return build(data)
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise LearnedModelError(f"{path} is incomplete or inconsistent: {exc}") from exc


def read_model_file(path: Path, fmt: str, version: int, kind: str) -> dict:
    """The saved dictionary of a model file, checked: it exists, torch reads it, and its
    format and version are `fmt` and `version` (LearnedModelError naming `kind` otherwise)."""
    if not path.is_file():
        raise LearnedModelError(f"no {kind} at {path}")
    try:
        data = torch.load(path, weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt or foreign file
        raise LearnedModelError(f"{path} is not a readable model file: {exc}") from exc
    if not isinstance(data, dict) or data.get("format") != fmt:
        raise LearnedModelError(f"{path} is not a Pliant {kind}")
    if data.get("format_version") != version:
        raise LearnedModelError(
            f"{path} has model format version {data.get('format_version')}; this Pliant"
            f" reads version {version}"
        )
    return data
