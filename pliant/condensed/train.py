"""Training of F and G (thesis §5.1.2): the loss of Eq. 5.5 on standardised data (Eq. 5.4),
Adam with a learning rate reduced on plateaus, the best epoch kept.

The loss is Eq. 5.5 averaged over samples and output elements (a mean squared error), so that
its values compare across dataset sizes and robots, as the thesis' Tables 5.1-5.2 do. The best
epoch is the one with the lowest test loss, the network the thesis keeps; the learning-rate
schedule follows the training loss (and the best epoch too when there is no test sample). A
checkpoint written every few epochs lets an interrupted training go on where it stopped; a
loss that turns non-finite stops the run with a TrainingError naming the epoch, before the
diverged weights can be saved.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from torch import Tensor

from pliant.condensed.collect import held_out_split
from pliant.condensed.dataset import Dataset, Split, atomic_write
from pliant.condensed.learned import LearnedCondensedModel
from pliant.condensed.networks import ACTIVATIONS, StandardisedMLP
from pliant.errors import DatasetError, TrainingError

SCHEDULES = ("plateau", "cosine")


@dataclass
class TrainConfig:
    """Hyper-parameters and bookkeeping of a training run (thesis defaults: 3 x 450, 1e-4).

    Args:
        activation: hidden-layer activation (`pliant.condensed.networks.ACTIVATIONS`).
        schedule: "plateau", the rate times `lr_factor` when the training loss has not
            improved for `lr_patience` epochs (ReduceLROnPlateau); or "cosine", one cycle per
            run: a warm-up from a tenth of the rate over the first 5 % of the batches, then a
            cosine decay to 1e-4 of it by the last (OneCycleLR).
        weight_decay: AdamW's decoupled weight decay (0: Adam).
        lr_factor, lr_patience: ReduceLROnPlateau's factor and patience (epochs).
        log_dir: TensorBoard folder (None: no logs).
        checkpoint: file to save to every `checkpoint_every` epochs and to resume from.
    """

    epochs: int = 1000
    batch_size: int = 256
    learning_rate: float = 1e-4
    hidden: tuple[int, ...] = (450, 450, 450)
    dropout: float = 0.0
    activation: str = "relu"
    schedule: str = "plateau"
    weight_decay: float = 0.0
    lr_factor: float = 0.5
    lr_patience: int = 50
    seed: int = 0
    log_dir: Path | None = None
    checkpoint: Path | None = None
    checkpoint_every: int = 50
    progress: bool = True

    def __post_init__(self) -> None:
        counts = {
            "epochs": self.epochs,
            "batch_size": self.batch_size,
            "lr_patience": self.lr_patience + 1,
            "checkpoint_every": self.checkpoint_every,
        }
        for name, value in counts.items():
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise TrainingError(f"{name} must be an integer >= 1, got {getattr(self, name)!r}")
        if not self.hidden or not all(isinstance(h, int) and h >= 1 for h in self.hidden):
            raise TrainingError(f"hidden widths must be integers >= 1, got {self.hidden!r}")
        reals = {"learning_rate": self.learning_rate, "dropout": self.dropout}
        reals["lr_factor"] = self.lr_factor
        reals["weight_decay"] = self.weight_decay
        for name, value in reals.items():
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise TrainingError(f"{name} must be a real number, got {value!r}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise TrainingError(f"learning_rate must be finite and > 0, got {self.learning_rate}")
        if not (math.isfinite(self.dropout) and 0 <= self.dropout < 1):
            raise TrainingError(f"dropout must lie in [0, 1), got {self.dropout}")
        if not (math.isfinite(self.lr_factor) and 0 < self.lr_factor < 1):
            raise TrainingError(f"lr_factor must lie in (0, 1), got {self.lr_factor}")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise TrainingError(f"weight_decay must be finite and >= 0, got {self.weight_decay}")
        if self.activation not in ACTIVATIONS:
            raise TrainingError(
                f"activation must be one of {sorted(ACTIVATIONS)}, got {self.activation!r}"
            )
        if self.schedule not in SCHEDULES:
            raise TrainingError(f"schedule must be one of {SCHEDULES}, got {self.schedule!r}")


@dataclass
class FitResult:
    """The network at its best epoch, and the history of every epoch."""

    network: StandardisedMLP
    best_epoch: int
    best_test_loss: float
    history: list[dict] = field(default_factory=list)


def standardised_loss(network: StandardisedMLP, x: Tensor, y: Tensor) -> Tensor:
    """Eq. 5.5, mean over samples and elements, in the network's output standardisation."""
    return torch.mean((network(x) - network.output_scale(y)) ** 2)


def fit(
    network: StandardisedMLP,
    train: tuple[Tensor, Tensor],
    test: tuple[Tensor, Tensor],
    config: TrainConfig,
) -> FitResult:
    """Train `network` on (inputs, outputs) pairs; resume from config.checkpoint if present."""
    generator = torch.Generator().manual_seed(config.seed)
    optimiser = torch.optim.AdamW(
        network.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )
    x_train, y_train = train
    batches = math.ceil(len(x_train) / config.batch_size)
    if config.schedule == "cosine":
        per_batch = torch.optim.lr_scheduler.OneCycleLR(
            optimiser,
            max_lr=config.learning_rate,
            total_steps=config.epochs * batches,
            pct_start=0.05,
            div_factor=10.0,
            final_div_factor=1e3,
        )
        scheduler = per_batch
    else:
        per_batch = None
        scheduler = torch.optim.lr_scheduler.ReduceLROnPlateau(
            optimiser, factor=config.lr_factor, patience=config.lr_patience
        )
    best = {"epoch": 0, "loss": float("inf"), "state": _copy_state(network)}
    history: list[dict] = []
    first = 1
    if config.checkpoint is not None and Path(config.checkpoint).exists():
        first, best, history = _resume(config.checkpoint, network, optimiser, scheduler, generator)
    writer = _tensorboard(config.log_dir)
    with _progress(config.progress) as bar:
        task = bar.add_task("training", total=config.epochs, completed=first - 1, status="")
        for epoch in range(first, config.epochs + 1):
            network.train()
            total = 0.0
            for batch in torch.randperm(len(x_train), generator=generator).split(config.batch_size):
                optimiser.zero_grad()
                loss = standardised_loss(network, x_train[batch], y_train[batch])
                loss.backward()
                optimiser.step()
                if per_batch is not None:
                    per_batch.step()
                total += loss.item() * len(batch)
            train_loss = total / len(x_train)
            lr = optimiser.param_groups[0]["lr"]
            if not math.isfinite(train_loss):
                raise TrainingError(
                    f"epoch {epoch}: the training loss is {train_loss} (non-finite); likely"
                    " causes: values in the data too large for float32 once squared, or a"
                    f" learning rate ({lr:g}) too high. Nothing of this epoch was saved (a"
                    " checkpoint keeps the last one written before it)"
                )
            if per_batch is None:
                scheduler.step(train_loss)
            test_loss = evaluate_loss(network, *test)
            if len(test[0]) and not math.isfinite(test_loss):
                raise TrainingError(
                    f"epoch {epoch}: the test loss is {test_loss} (non-finite) while the"
                    f" training loss is {train_loss:.3g}: the test data hold values the"
                    " network maps out of float32's range (corrupt or extreme test samples?)"
                )
            # Without test samples the best epoch is the one of the lowest training loss.
            score = test_loss if len(test[0]) else train_loss
            history.append({"epoch": epoch, "train": train_loss, "test": test_loss, "lr": lr})
            if score < best["loss"]:
                best = {"epoch": epoch, "loss": score, "state": _copy_state(network)}
            if writer is not None:
                writer.add_scalars("loss", {"train": train_loss, "test": test_loss}, epoch)
                writer.add_scalar("learning_rate", lr, epoch)
            bar.update(
                task,
                advance=1,
                status=f"train {train_loss:.3g}  test {test_loss:.3g}  best {best['loss']:.3g}",
            )
            last = epoch == config.epochs
            if config.checkpoint is not None and (epoch % config.checkpoint_every == 0 or last):
                _save_checkpoint(
                    config.checkpoint,
                    epoch,
                    network,
                    optimiser,
                    scheduler,
                    generator,
                    best,
                    history,
                )
    if writer is not None:
        writer.close()
    network.load_state_dict(best["state"])
    network.eval()
    return FitResult(network, best["epoch"], best["loss"], history)


def evaluate_loss(network: StandardisedMLP, x: Tensor, y: Tensor) -> float:
    """The standardised loss (Eq. 5.5) of `network` on (x, y), in evaluation mode."""
    network.eval()
    with torch.no_grad():
        return float(standardised_loss(network, x, y)) if len(x) else float("nan")


def train_condensed(
    dataset: Dataset, config: TrainConfig | None = None
) -> tuple[LearnedCondensedModel, FitResult]:
    """Train F (Eq. 5.2) on the converged samples of `dataset`."""
    config = config or TrainConfig()
    train, test = dataset.train.converged_only(), dataset.test.converged_only()
    if len(train) < 2:
        raise DatasetError(f"F needs at least 2 converged training samples, got {len(train)}")
    x_train, y_train = _tensor(train.inputs()), _tensor(train.outputs())
    torch.manual_seed(config.seed)
    network = StandardisedMLP(
        x_train, y_train, hidden=config.hidden, dropout=config.dropout, activation=config.activation
    )
    result = fit(
        network, (x_train, y_train), (_tensor(test.inputs()), _tensor(test.outputs())), config
    )
    training = {"best_epoch": result.best_epoch, "test_loss": result.best_test_loss}
    return LearnedCondensedModel.from_dataset(result.network, dataset, training), result


def train_design(dataset: Dataset, config: TrainConfig | None = None) -> FitResult:
    """Train G (Eq. 5.7): design parameters -> (W0 triangle, delta0_free)."""
    config = config or TrainConfig()
    if not dataset.plan.design_names:
        raise DatasetError("the dataset has no design parameters: G has nothing to learn from")

    def pairs(split: Split) -> tuple[Tensor, Tensor]:
        good = split.converged_only()
        return _tensor(good.design), _tensor(np.hstack([good.w0_triangle, good.free_distance0]))

    train = pairs(dataset.train)
    torch.manual_seed(config.seed)
    network = StandardisedMLP(
        *train, hidden=config.hidden, dropout=config.dropout, activation=config.activation
    )
    return fit(network, train, pairs(dataset.test), config)


def evaluate(learned: LearnedCondensedModel, split: Split) -> dict[str, float]:
    """Standardised test loss of F on a split, beside the constant-rest baseline that predicts
    W = W0 and delta_free = delta0_free for every sample (in F's standardisation)."""
    good = split.converged_only()
    x, y = _tensor(good.inputs()), _tensor(good.outputs())
    baseline = _tensor(np.hstack([good.w0_triangle, good.free_distance0]))
    scale = learned.network.output_scale
    return {
        "loss": evaluate_loss(learned.network, x, y),
        "baseline_loss": float(torch.mean((scale(baseline) - scale(y)) ** 2)),
        "samples": len(good),
    }


def sample_losses(network: StandardisedMLP, split: Split) -> np.ndarray:
    """Eq. 5.5 per converged sample of `split` (mean over the outputs), in the network's
    standardisation: where a test loss comes from."""
    good = split.converged_only()
    x, y = _tensor(good.inputs()), _tensor(good.outputs())
    network.eval()
    with torch.no_grad():
        return ((network(x) - network.output_scale(y)) ** 2).mean(dim=1).numpy()


def loss_spread(network: StandardisedMLP, split: Split) -> dict[str, float]:
    """Eq. 5.5 on the converged samples of `split` (computed as every test loss is, by
    :func:`evaluate_loss`) and its spread over them: the median sample's loss and the worst
    sample's share of their sum (one outlier sample, or a loss spread over many)."""
    good = split.converged_only()
    per_sample = sample_losses(network, good)
    return {
        "loss": evaluate_loss(network, _tensor(good.inputs()), _tensor(good.outputs())),
        "median_sample_loss": float(np.median(per_sample)),
        "worst_sample_share": float(per_sample.max() / per_sample.sum()),
    }


def score_held_out(
    learned: LearnedCondensedModel, seed: int, *, workers: int | None = None
) -> dict[str, float]:
    """F's loss (Eq. 5.5) on a test set drawn after its training: the test stream of its plan
    under another `seed` (``held_out_split``; the plan's own test split chose the epoch, a
    validation set), with its spread over the samples (:func:`loss_spread`)."""
    test = held_out_split(learned.plan, seed, workers=workers)
    spread = loss_spread(learned.network, test)
    return {
        "seed": seed,
        "samples": len(test),
        "test_loss": spread.pop("loss"),
        **spread,
    }


def _tensor(array: np.ndarray) -> Tensor:
    return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32))


def _copy_state(network: StandardisedMLP) -> dict[str, Tensor]:
    return {k: v.detach().clone() for k, v in network.state_dict().items()}


def _progress(enabled: bool) -> Progress:
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} epochs"),
        TimeRemainingColumn(),
        TextColumn("{task.fields[status]}"),
        disable=not enabled,
    )


def _tensorboard(log_dir: Path | None):
    if log_dir is None:
        return None
    from torch.utils.tensorboard import SummaryWriter

    return SummaryWriter(log_dir=str(log_dir))


def _save_checkpoint(path, epoch, network, optimiser, scheduler, generator, best, history):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {
        "epoch": epoch,
        "network": network.state_dict(),
        "optimiser": optimiser.state_dict(),
        "scheduler": scheduler.state_dict(),
        "generator": generator.get_state(),
        "best": best,
        "history": history,
    }
    try:
        atomic_write(path, lambda tmp: torch.save(state, tmp))
    except (OSError, RuntimeError) as exc:  # torch reports a full disk as RuntimeError
        raise TrainingError(
            f"epoch {epoch}: cannot write the checkpoint {path}: {exc}; the previous checkpoint"
            " is kept: free space and rerun the same command to resume"
        ) from exc


def _resume(path, network, optimiser, scheduler, generator):
    """Load a checkpoint into the run's objects; refuse one made from other data."""
    try:
        state = torch.load(path, weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt file
        raise DatasetError(f"the checkpoint {path} is unreadable: {exc}; delete it") from exc
    saved = state["network"]
    for key in ("input_scale.mean", "input_scale.scale", "output_scale.mean"):
        mine = network.state_dict()[key]
        if saved[key].shape != mine.shape or not torch.allclose(saved[key], mine):
            raise DatasetError(
                f"the checkpoint {path} was trained on other data (its {key} differs); delete it"
                " or train on the same dataset"
            )
    network.load_state_dict(saved)
    optimiser.load_state_dict(state["optimiser"])
    scheduler.load_state_dict(state["scheduler"])
    generator.set_state(state["generator"])
    return state["epoch"] + 1, state["best"], state["history"]
