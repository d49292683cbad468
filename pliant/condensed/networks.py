"""The networks of the learned condensed model (thesis §5.1.2, Fig. 5.3).

F maps (delta_a, delta_c, W0 triangle, delta0_free) to (W triangle, delta_free) (Eq. 5.2); G
maps design parameters P to (W0 triangle, delta0_free) (Eq. 5.7); F(delta_a, delta_c, G(P)) is
their composition (Eq. 5.8). Both are MLPs on element-wise standardised data (Eq. 5.4), the
standardisation stored inside the network so that a saved network is self-contained.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from scipy.special import expit
from torch import Tensor, nn


class Standardiser(nn.Module):
    """X -> (X - X_mean) / (X_std + eps), element-wise, statistics of the training set (Eq. 5.4).

    eps is relative to each element (eps = relative_eps * |X_mean| + tiny): the scaling does not
    depend on the scene's units, and an element constant in the training set (W0 of a single
    design) does not blow a new input's rounding differences up into large inputs.
    """

    def __init__(self, data: Tensor, *, relative_eps: float = 1e-3) -> None:
        super().__init__()
        mean = data.mean(dim=0)
        std = data.std(dim=0, correction=0) if data.shape[0] > 1 else torch.zeros_like(mean)
        eps = relative_eps * mean.abs() + torch.finfo(data.dtype).tiny
        self.register_buffer("mean", mean)
        self.register_buffer("scale", std + eps)

    def forward(self, x: Tensor) -> Tensor:
        return (x - self.mean) / self.scale

    def inverse(self, z: Tensor) -> Tensor:
        return z * self.scale + self.mean


# Hidden-layer activations by name. ReLU makes F piecewise linear; a smooth one (SiLU) fits the
# smooth maps from displacements to compliances more closely where samples are dense (Table
# 5.1's Diamond, 600 epochs: median test loss of a sample 6.5e-6 against 2.6e-5 with ReLU).
ACTIVATIONS = {"relu": nn.ReLU, "silu": nn.SiLU, "tanh": nn.Tanh}


def numpy_activation(name: str):
    """The hidden layers' activation `name` and its derivative as NumPy functions of the
    pre-activations h: (f(h), f'(h)), for the forward passes that run without torch."""
    if name == "relu":
        return (lambda h: h * (h > 0.0)), (lambda h: (h > 0.0).astype(h.dtype))
    if name == "silu":

        def silu(h):
            return h * expit(h)  # the logistic function without overflow for large |h|

        def silu_derivative(h):
            s = expit(h)
            return s * (1.0 + h * (1.0 - s))

        return silu, silu_derivative
    if name == "tanh":
        return np.tanh, (lambda h: 1.0 - np.tanh(h) ** 2)
    raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {name!r}")


def mlp(
    n_in: int,
    n_out: int,
    hidden: Sequence[int],
    dropout: float = 0.0,
    activation: str = "relu",
) -> nn.Sequential:
    """Fully connected network (`activation` after each hidden layer, one of ACTIVATIONS);
    dropout after each hidden layer when > 0."""
    layers: list[nn.Module] = []
    act = ACTIVATIONS[activation]
    for width in hidden:
        layers += [nn.Linear(n_in, width), act()]
        if dropout > 0:
            layers.append(nn.Dropout(dropout))
        n_in = width
    layers.append(nn.Linear(n_in, n_out))
    return nn.Sequential(*layers)


class StandardisedMLP(nn.Module):
    """An MLP between standardised inputs and outputs (Eq. 5.4).

    `forward` maps raw inputs to *standardised* outputs, what the loss of Eq. 5.5 compares;
    `predict` maps raw inputs to raw outputs.
    """

    def __init__(
        self,
        inputs: Tensor,
        outputs: Tensor,
        *,
        hidden: Sequence[int] = (450, 450, 450),
        dropout: float = 0.0,
        activation: str = "relu",
    ) -> None:
        super().__init__()
        if activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {activation!r}")
        self.hidden = tuple(int(h) for h in hidden)
        self.dropout = float(dropout)
        self.activation = activation
        self.input_scale = Standardiser(inputs)
        self.output_scale = Standardiser(outputs)
        self.net = mlp(inputs.shape[1], outputs.shape[1], self.hidden, self.dropout, activation)

    @property
    def n_inputs(self) -> int:
        return self.input_scale.mean.numel()

    @property
    def n_outputs(self) -> int:
        return self.output_scale.mean.numel()

    def forward(self, x: Tensor) -> Tensor:
        return self.net(self.input_scale(x))

    def predict(self, x: Tensor) -> Tensor:
        return self.output_scale.inverse(self(x))

    def config(self) -> dict:
        """What rebuilds this network's shape (with `from_config`), beside its state_dict."""
        return {
            "n_inputs": self.n_inputs,
            "n_outputs": self.n_outputs,
            "hidden": list(self.hidden),
            "dropout": self.dropout,
            "activation": self.activation,
        }

    @classmethod
    def from_config(cls, config: dict) -> StandardisedMLP:
        """An untrained network of this shape, to load a state_dict into."""
        return cls(
            torch.zeros(1, config["n_inputs"]),
            torch.zeros(1, config["n_outputs"]),
            hidden=config["hidden"],
            dropout=config["dropout"],
            activation=config.get("activation", "relu"),  # saved before the choice existed
        )


class ComposedNetwork(nn.Module):
    """F(delta_a, delta_c, G(P)) (Eq. 5.8): a differentiable map from design parameters and
    active-constraint displacements to (W triangle, delta_free), raw units."""

    def __init__(self, condensed: StandardisedMLP, design: StandardisedMLP) -> None:
        super().__init__()
        self.condensed = condensed
        self.design = design

    def forward(self, displacements: Tensor, design: Tensor) -> Tensor:
        """displacements: (n, delta_a + delta_c); design: (n, P) or (P,) for all rows."""
        rest = self.design.predict(design.expand(displacements.shape[0], -1))
        return self.condensed.predict(torch.cat([displacements, rest], dim=1))
